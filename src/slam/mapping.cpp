// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SlamFrontend::Impl, the map: map-point geometry and descriptors, fusion, point culling, local BA.
#include <algorithm>
#include <array>
#include <cstring>
#include <future>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {

void SlamFrontend::Impl::update_point_geometry(MapPoint& p) {
  if (p.obs.empty()) return;
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  for (const auto& [kf, idx] : p.obs)
    n += (p.pos - keyframes[static_cast<std::size_t>(kf)].center()).normalized();
  p.normal = n.normalized();
  const auto ref =
      std::find_if(p.obs.begin(), p.obs.end(), [&](const auto& o) { return o.first == p.ref_kf; });
  const auto& [rkf, ridx] = ref != p.obs.end() ? *ref : p.obs.front();
  const Keyframe& kf = keyframes[static_cast<std::size_t>(rkf)];
  const double dist = (p.pos - kf.center()).norm();
  const int level = kf.data.octave[static_cast<std::size_t>(ridx)];
  p.max_dist = dist * scale[static_cast<std::size_t>(level)];
  p.min_dist = p.max_dist / scale.back();
}

// The observation descriptor with the least median distance to the others (ORB-SLAM2).
// ORB-SLAM2's ComputeDistinctiveDescriptors: the observed descriptor whose median Hamming
// distance to the others (its own zero included) is smallest; the first on ties. Only the
// newest kDescriptorWindow observations take part. The rule costs O(obs²) per update; without
// keyframe culling (FrontendConfig::cull_keyframes off), on a 1,500-frame sequence circling one
// room, points gathered hundreds of observations and this function took 8 % of the run's CPU,
// in bursts of > 100 ms inside the tracking thread at each keyframe (docs/slam.md, "Long
// sequences"). Points with at most kDescriptorWindow observations get exactly ORB-SLAM2's
// choice.
void SlamFrontend::Impl::update_point_descriptor(MapPoint& p) {
  const std::size_t total = p.obs.size();
  if (total <= 1) return;
  const std::size_t n = std::min(total, kDescriptorWindow);
  const std::size_t first = total - n;
  std::array<const std::uint8_t*, kDescriptorWindow> desc{};
  for (std::size_t i = 0; i < n; ++i) {
    const auto& [kf, idx] = p.obs[first + i];
    desc[i] = keyframes[static_cast<std::size_t>(kf)].data.desc.ptr<std::uint8_t>(idx);
  }
  std::array<std::array<int, kDescriptorWindow>, kDescriptorWindow> dist{};
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) {
      dist[i][j] = descriptor_distance(desc[i], desc[j]);
      dist[j][i] = dist[i][j];
    }
  }
  std::size_t best = 0;
  int best_median = std::numeric_limits<int>::max();
  std::array<int, kDescriptorWindow> row{};
  for (std::size_t i = 0; i < n; ++i) {
    std::copy_n(dist[i].begin(), n, row.begin());
    std::nth_element(row.begin(), row.begin() + static_cast<long>(n / 2),
                     row.begin() + static_cast<long>(n));
    const int med = row[n / 2];
    if (med < best_median) {
      best_median = med;
      best = i;
    }
  }
  std::memcpy(p.desc.data(), desc[best], p.desc.size());
}

// Merges map point `from` into `into` (ORB-SLAM2's MapPoint::Replace): every keyframe that saw
// `from` now sees `into` (or nothing, when it already sees `into` at another keypoint).
void SlamFrontend::Impl::replace_point(int from, int into) {
  if (from == into) return;
  MapPoint& a = points[static_cast<std::size_t>(from)];
  MapPoint& b = points[static_cast<std::size_t>(into)];
  for (const auto& [kf, idx] : a.obs) {
    auto& slot = keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(idx)];
    const bool seen =
        std::any_of(b.obs.begin(), b.obs.end(), [&](const auto& o) { return o.first == kf; });
    if (seen) {
      slot = -1;
    } else {
      slot = into;
      b.obs.emplace_back(kf, idx);
    }
  }
  b.visible += a.visible;
  b.found += a.found;
  a.obs.clear();
  a.bad = true;
  update_point_descriptor(b);
  update_point_geometry(b);
}

// Projects `cands` into keyframe `kf_id` and merges each with the keypoint it matches
// (ORB-SLAM2's ORBmatcher::Fuse, radius 3 × scale, χ² test of the stereo or mono residual,
// Hamming <= TH_LOW): an unmatched keypoint gains the observation; a keypoint that already has
// a map point keeps whichever of the two is observed more. Returns the number of fusions.
int SlamFrontend::Impl::fuse_into(int kf_id, std::vector<int> cands) {
  Keyframe& K = keyframes[static_cast<std::size_t>(kf_id)];
  FrameData& f = K.data;
  const Eigen::Vector3d Ow = K.center();
  int fused = 0;
  for (const int pid : cands) {
    if (pid < 0) continue;
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    if (p.bad ||
        std::any_of(p.obs.begin(), p.obs.end(), [&](const auto& o) { return o.first == kf_id; }))
      continue;
    const Eigen::Vector3d pc = K.T_cw * p.pos;
    if (pc.z() <= 1e-3) continue;
    const double u = k.fx * pc.x() / pc.z() + k.cx;
    const double v = k.fy * pc.y() / pc.z() + k.cy;
    if (!cfg.camera.in_image(u, v)) continue;
    const double ur = u - k.bf / pc.z();
    const Eigen::Vector3d po = p.pos - Ow;
    const double dist = po.norm();
    if (dist < 0.8 * p.min_dist || dist > 1.2 * p.max_dist) continue;
    if (po.dot(p.normal) < 0.5 * dist) continue;
    const int level = predict_level(p, dist);
    const double radius = 3.0 * scale[static_cast<std::size_t>(level)];
    int best = 256;
    int best_idx = -1;
    f.grid.for_each_in(u, v, radius, [&](int i) {
      const auto si = static_cast<std::size_t>(i);
      const int lv = f.octave[si];
      if (lv < level - 1 || lv > level) return;
      const double eu = u - f.uv[si].x();
      const double ev = v - f.uv[si].y();
      const double w = inv_sigma2[static_cast<std::size_t>(lv)];
      if (f.depth[si] > 0) {
        const double er = ur - f.u_right(si, k.bf);
        if ((eu * eu + ev * ev + er * er) * w > cfg.local_ba.chi2_stereo) return;
      } else if ((eu * eu + ev * ev) * w > cfg.local_ba.chi2_mono) {
        return;
      }
      const int d = descriptor_distance(p.desc.data(), f.desc.ptr<std::uint8_t>(i));
      if (d < best) {
        best = d;
        best_idx = i;
      }
    });
    if (best_idx < 0 || best > kThLow) continue;
    const int other = f.points[static_cast<std::size_t>(best_idx)];
    if (other >= 0 && !points[static_cast<std::size_t>(other)].bad) {
      if (other == pid) continue;
      if (points[static_cast<std::size_t>(other)].obs.size() > p.obs.size()) {
        replace_point(pid, other);
      } else {
        replace_point(other, pid);
      }
    } else {
      f.points[static_cast<std::size_t>(best_idx)] = pid;
      p.obs.emplace_back(kf_id, best_idx);
      update_point_descriptor(p);
      update_point_geometry(p);
    }
    ++fused;
  }
  return fused;
}

// ORB-SLAM2's SearchInNeighbors: fuses the new keyframe's points into its covisible neighbours
// (10 best + 5 best of each) and their points into it, then refreshes its connections.
void SlamFrontend::Impl::search_in_neighbors(int kf_id) {
  std::vector<int> targets;
  std::set<int> seen{kf_id};
  for (const int id : best_covisible(kf_id, 10)) {
    if (seen.insert(id).second) targets.push_back(id);
  }
  const std::size_t first = targets.size();
  for (std::size_t i = 0; i < first; ++i) {
    for (const int id : best_covisible(targets[i], 5)) {
      if (seen.insert(id).second) targets.push_back(id);
    }
  }
  for (const int id : targets)
    fuse_into(id, keyframes[static_cast<std::size_t>(kf_id)].data.points);
  fuse_into(kf_id, keyframe_points(targets));
  update_connections(keyframes[static_cast<std::size_t>(kf_id)]);
}

// ORB-SLAM2's MapPointCulling: recent points must be found in >= 25 % of the frames that
// should have seen them, and have an observation weight > 3 (two keyframes with depth) once
// two keyframes have passed.
void SlamFrontend::Impl::cull_recent_points(int current_kf) {
  std::vector<int> keep;
  for (const int pid : recent_points) {
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    if (p.bad) continue;
    const int age = current_kf - p.first_kf;
    if (static_cast<double>(p.found) / p.visible < 0.25 || (age >= 2 && obs_weight(p) <= 3)) {
      erase_point(pid);
    } else if (age < 3) {
      keep.push_back(pid);
    }
  }
  recent_points = std::move(keep);
}

void SlamFrontend::Impl::erase_point(int pid) {
  MapPoint& p = points[static_cast<std::size_t>(pid)];
  p.bad = true;
  for (const auto& [kf, idx] : p.obs)
    keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(idx)] = -1;
  p.obs.clear();
}

void SlamFrontend::Impl::schedule_local_ba(int kf_id) {
  if (!cfg.enable_local_ba) return;
  // A keyframe inserted before the previous BA was due (gap or weak-tracking criterion) must not
  // discard that BA: apply it now (waits for the mapping thread; still deterministic).
  apply_ba_if_due(true);
  std::vector<int> local{kf_id};
  for (const int id : best_covisible(kf_id, cfg.local_window - 1)) local.push_back(id);
  std::set<int> local_set(local.begin(), local.end());
  const std::vector<int> pts = keyframe_points(local);
  // Fixed keyframes: others observing the local points, most-sharing first.
  std::map<int, int> others;
  for (const int pid : pts) {
    for (const auto& [kf, idx] : points[static_cast<std::size_t>(pid)].obs) {
      if (local_set.count(kf) == 0) ++others[kf];
    }
  }
  std::vector<std::pair<int, int>> fixed_sorted(others.begin(), others.end());
  std::stable_sort(fixed_sorted.begin(), fixed_sorted.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  if (static_cast<int>(fixed_sorted.size()) > cfg.max_fixed_keyframes)
    fixed_sorted.resize(static_cast<std::size_t>(cfg.max_fixed_keyframes));
  std::vector<int> fixed_ids;
  for (const auto& [id, c] : fixed_sorted) fixed_ids.push_back(id);
  launch_ba(local, fixed_ids, pts, cfg.mapping_thread, cfg.local_ba);
  if (ba_job) ba_job->cull_kf = kf_id;
}

// Starts a BA over `local` (optimised) and `fixed_ids` (constant) keyframes and `pts`, on the
// mapping thread or deferred; its result is applied ba_apply_lag frames later (or by finish()).
void SlamFrontend::Impl::launch_ba(const std::vector<int>& local, const std::vector<int>& fixed_ids,
                                   const std::vector<int>& pts, bool async,
                                   const LocalBaParams& params) {
  BaJob job;
  job.kf_ids = local;
  std::vector<std::uint8_t> fixed(local.size(), 0);
  for (const int id : fixed_ids) {
    job.kf_ids.push_back(id);
    fixed.push_back(1);
  }
  // The first keyframe anchors the world frame; with no other fixed keyframe, fix the oldest.
  std::map<int, int> slot;
  for (std::size_t i = 0; i < job.kf_ids.size(); ++i) {
    slot[job.kf_ids[i]] = static_cast<int>(i);
    if (job.kf_ids[i] == 0) fixed[i] = 1;
  }
  if (std::none_of(fixed.begin(), fixed.end(), [](std::uint8_t v) { return v != 0; })) {
    const auto oldest = std::min_element(job.kf_ids.begin(), job.kf_ids.end()) - job.kf_ids.begin();
    fixed[static_cast<std::size_t>(oldest)] = 1;
  }
  if (job.kf_ids.size() < 2) return;
  std::vector<Eigen::Isometry3d> poses;
  for (const int id : job.kf_ids) poses.push_back(keyframes[static_cast<std::size_t>(id)].T_cw);
  std::vector<Eigen::Vector3d> pos;
  for (std::size_t j = 0; j < pts.size(); ++j) {
    const MapPoint& p = points[static_cast<std::size_t>(pts[j])];
    pos.push_back(p.pos);
    for (const auto& [kf, idx] : p.obs) {
      const auto it = slot.find(kf);
      if (it == slot.end()) continue;
      BaObservation o;
      o.keyframe = it->second;
      o.point = static_cast<int>(j);
      o.obs =
          observation(keyframes[static_cast<std::size_t>(kf)].data, static_cast<std::size_t>(idx));
      job.observations.push_back(o);
    }
  }
  job.point_ids = pts;
  job.due_frame = frame_counter + static_cast<std::size_t>(cfg.ba_apply_lag);
  auto work = [k = k, poses = std::move(poses), fixed = std::move(fixed), pos = std::move(pos),
               obs = job.observations, params]() {
    const double c0 = thread_cpu_ms();
    auto r = local_bundle_adjustment(k, poses, fixed, pos, obs, params);
    return std::make_pair(std::move(r), thread_cpu_ms() - c0);
  };
  if (async) {
    job.result = std::async(std::launch::async, std::move(work));
  } else {
    job.result = std::async(std::launch::deferred, std::move(work));
  }
  ba_job = std::move(job);
}

void SlamFrontend::Impl::apply_ba_if_due(bool force) {
  if (!ba_job || (!force && frame_counter < ba_job->due_frame)) return;
  auto [r, ms] = ba_job->result.get();
  ++ba_count;
  ba_ms += ms;
  const BaJob& job = *ba_job;
  for (std::size_t i = 0; i < job.kf_ids.size(); ++i)
    keyframes[static_cast<std::size_t>(job.kf_ids[i])].T_cw = r.poses[i];
  for (std::size_t i = 0; i < job.observations.size(); ++i) {
    if (r.outlier[i] == 0) continue;
    const int pid = job.point_ids[static_cast<std::size_t>(job.observations[i].point)];
    const int kf = job.kf_ids[static_cast<std::size_t>(job.observations[i].keyframe)];
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    const auto it =
        std::find_if(p.obs.begin(), p.obs.end(), [&](const auto& o) { return o.first == kf; });
    if (it == p.obs.end()) continue;
    keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(it->second)] = -1;
    p.obs.erase(it);
    if (p.obs.empty()) p.bad = true;
  }
  for (std::size_t j = 0; j < job.point_ids.size(); ++j) {
    MapPoint& p = points[static_cast<std::size_t>(job.point_ids[j])];
    if (p.bad) continue;
    p.pos = r.points[j];
    if (std::none_of(p.obs.begin(), p.obs.end(),
                     [&](const auto& o) { return o.first == p.ref_kf; }))
      p.ref_kf = p.obs.front().first;
    update_point_geometry(p);
  }
  const int cull_kf = job.cull_kf;
  ba_job.reset();
  if (cull_kf >= 0 && cfg.cull_keyframes) cull_keyframes(cull_kf);
}

}  // namespace ds3d::slam
