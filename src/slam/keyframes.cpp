// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SlamFrontend::Impl, keyframes: when to insert one, insertion, covisibility and culling.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {

bool SlamFrontend::Impl::need_keyframe(const FrameData& f, int inliers) const {
  // Keyframes of the current map segment: after a re-anchoring the new segment starts like a
  // new map (ORB-SLAM2's thresholds for a map of one or two keyframes), else its first
  // keyframe's points, seen once, never count and no keyframe would follow it.
  const int segment_first_kf = segment_starts.empty() ? 0 : segment_starts.back();
  const int n_kf = std::min(static_cast<int>(live_keyframes),
                            static_cast<int>(keyframes.size()) - segment_first_kf);
  const int min_obs = n_kf <= 2 ? 2 : 3;
  int ref_matches = 0;
  for (const int pid : keyframes[static_cast<std::size_t>(ref_kf)].data.points) {
    if (pid >= 0 && !points[static_cast<std::size_t>(pid)].bad &&
        obs_weight(points[static_cast<std::size_t>(pid)]) >= min_obs) {
      ++ref_matches;
    }
  }
  int tracked_close = 0;
  int untracked_close = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (!f.is_close(i)) continue;
    if (f.points[i] >= 0) {
      ++tracked_close;
    } else {
      ++untracked_close;
    }
  }
  const bool need_close = tracked_close < 100 && untracked_close > 70;
  const double ratio = n_kf < 2 ? 0.4 : cfg.keyframe_ref_ratio;
  const int gap = static_cast<int>(frame_counter) - last_kf_frame;
  const bool mapping_idle = !ba_job.has_value();
  const bool c1a = gap >= cfg.keyframe_max_gap;
  const bool c1b = mapping_idle;
  const bool c1c = inliers < 0.25 * ref_matches || need_close;
  const bool c2 = (inliers < ratio * ref_matches || need_close) && inliers > 15;
  return (c1a || c1b || c1c) && c2;
}

namespace {

// Keypoint i of `d` with its depth, in the camera frame [m].
Eigen::Vector3d back_project(const StereoIntrinsics& k, const FrameData& d, std::size_t i) {
  const double z = d.depth[i];
  return {(d.uv[i].x() - k.cx) / k.fx * z, (d.uv[i].y() - k.cy) / k.fy * z, z};
}

}  // namespace

int SlamFrontend::Impl::add_keyframe(const FrameData& f, const Eigen::Isometry3d& T_cw,
                                     const FrameInput& in) {
  Keyframe kf;
  kf.id = static_cast<int>(keyframes.size());
  kf.frame_index = in.index;
  kf.timestamp = in.timestamp;
  kf.T_cw = T_cw;
  kf.data = f;
  keyframes.push_back(std::move(kf));
  ++live_keyframes;
  Keyframe& K = keyframes.back();
  const Eigen::Isometry3d T_wc = T_cw.inverse();
  for (std::size_t i = 0; i < K.data.size(); ++i) {
    const int pid = K.data.points[i];
    if (pid < 0) continue;
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    p.obs.emplace_back(K.id, static_cast<int>(i));
    update_point_geometry(p);
    update_point_descriptor(p);
  }
  // New points from depth (ORB-SLAM2's CreateNewKeyFrame): by increasing depth, every close
  // keypoint, and far ones until 100 keypoints have points. The first keyframe uses them all.
  std::vector<std::pair<float, std::size_t>> by_depth;
  for (std::size_t i = 0; i < K.data.size(); ++i) {
    if (K.data.depth[i] > 0) by_depth.emplace_back(K.data.depth[i], i);
  }
  std::stable_sort(by_depth.begin(), by_depth.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  int n_points = 0;
  for (const auto& [depth_i, i] : by_depth) {
    if (K.id > 0 && depth_i > K.data.close_depth && n_points > 100) break;
    ++n_points;
    if (K.data.points[i] >= 0) continue;
    int pid = -1;
    MapPoint p;
    p.pos = T_wc * back_project(k, K.data, i);
    p.desc = row_descriptor(K.data.desc, static_cast<int>(i));
    p.obs.emplace_back(K.id, static_cast<int>(i));
    p.ref_kf = K.id;
    p.first_kf = K.id;
    pid = static_cast<int>(points.size());
    points.push_back(p);
    update_point_geometry(points.back());
    K.data.points[i] = pid;
    recent_points.push_back(pid);
  }
  if (confirm_far && K.id > 0) confirm_far_points(K);
  update_connections(K);
  if (cfg.fuse_neighbors) search_in_neighbors(K.id);
  cull_recent_points(K.id);
  last_kf_frame = static_cast<int>(frame_counter);
  ref_kf = K.id;
  return K.id;
}

// The keypoint of K without a map point that best matches a far point at x_k (K's camera frame),
// seen at `level` with descriptor `desc`: within 3 px × level scale of its projection, level
// ± 1, depth within 5 %, distance <= kThLow and < 0.8 × the second best. -1 if none.
int SlamFrontend::Impl::match_far_point(const Keyframe& K, const Eigen::Vector3d& x_k, int level,
                                        const std::uint8_t* desc) const {
  if (x_k.z() <= 0.1) return -1;
  const double u = k.fx * x_k.x() / x_k.z() + k.cx;
  const double v = k.fy * x_k.y() / x_k.z() + k.cy;
  if (!cfg.camera.in_image(u, v)) return -1;
  const double radius = 3.0 * scale[static_cast<std::size_t>(level)];
  int best = 256;
  int second = 256;
  int best_i = -1;
  K.data.grid.for_each_in(u, v, radius, [&](int i) {
    const auto si = static_cast<std::size_t>(i);
    if (K.data.points[si] >= 0 || K.data.depth[si] <= 0) return;
    if (std::abs(K.data.octave[si] - level) > 1) return;
    if (std::abs(K.data.depth[si] - x_k.z()) > 0.05 * x_k.z()) return;
    const int d = descriptor_distance(desc, K.data.desc.ptr<std::uint8_t>(i));
    if (d < best) {
      second = best;
      best = d;
      best_i = i;
    } else if (d < second) {
      second = d;
    }
  });
  if (best_i < 0 || best > kThLow || best > 0.8 * second) return -1;
  return best_i;
}

// FrontendConfig::confirm_far_points: far keypoints of the previous live keyframe that K sees
// again become map points of both, at the mean of the two back-projections. Returns how many.
int SlamFrontend::Impl::confirm_far_points(Keyframe& K) {
  int pi = K.id - 1;
  while (pi >= 0 && keyframes[static_cast<std::size_t>(pi)].bad) --pi;
  if (pi < 0) return 0;
  Keyframe& P = keyframes[static_cast<std::size_t>(pi)];
  const Eigen::Isometry3d P_wc = P.T_cw.inverse();
  const Eigen::Isometry3d K_wc = K.T_cw.inverse();
  int made = 0;
  for (std::size_t j = 0; j < P.data.size(); ++j) {
    if (P.data.points[j] >= 0 || P.data.depth[j] <= P.data.close_depth) continue;
    const Eigen::Vector3d x_w = P_wc * back_project(k, P.data, j);
    const int i = match_far_point(K, K.T_cw * x_w, P.data.octave[j],
                                  P.data.desc.ptr<std::uint8_t>(static_cast<int>(j)));
    if (i < 0) continue;
    const auto si = static_cast<std::size_t>(i);
    MapPoint p;
    p.pos = 0.5 * (x_w + K_wc * back_project(k, K.data, si));
    p.desc = row_descriptor(K.data.desc, i);
    p.obs = {{P.id, static_cast<int>(j)}, {K.id, i}};
    p.ref_kf = K.id;
    p.first_kf = K.id;
    const int pid = static_cast<int>(points.size());
    points.push_back(p);
    update_point_geometry(points.back());
    P.data.points[j] = pid;
    K.data.points[si] = pid;
    recent_points.push_back(pid);
    ++made;
  }
  return made;
}

// Covisibility edges of keyframe K from its current points (ORB-SLAM2's UpdateConnections:
// weight = shared points, kept when >= 15, or the best one). Stale edges of K are replaced.
void SlamFrontend::Impl::update_connections(Keyframe& K) {
  std::map<int, int> shared;
  for (const int pid : K.data.points) {
    if (pid < 0 || points[static_cast<std::size_t>(pid)].bad) continue;
    for (const auto& [other, idx] : points[static_cast<std::size_t>(pid)].obs) {
      if (other != K.id) ++shared[other];
    }
  }
  for (const auto& [other, w] : K.covis)
    keyframes[static_cast<std::size_t>(other)].covis.erase(K.id);
  K.covis.clear();
  int best = -1;
  int best_w = 0;
  for (const auto& [other, w] : shared) {
    if (w > best_w) {
      best_w = w;
      best = other;
    }
    if (w >= 15) {
      K.covis[other] = w;
      keyframes[static_cast<std::size_t>(other)].covis[K.id] = w;
    }
  }
  if (K.covis.empty() && best >= 0) {
    K.covis[best] = best_w;
    keyframes[static_cast<std::size_t>(best)].covis[K.id] = best_w;
  }
}

// Best covisible keyframes of `kf_id`, most-sharing first (ties: lower id).
std::vector<int> SlamFrontend::Impl::best_covisible(int kf_id, int n) const {
  const auto& cov = keyframes[static_cast<std::size_t>(kf_id)].covis;
  std::vector<std::pair<int, int>> nb(cov.begin(), cov.end());
  std::stable_sort(nb.begin(), nb.end(),
                   [](const auto& a, const auto& b) { return a.second > b.second; });
  std::vector<int> out;
  for (const auto& [id, w] : nb) {
    if (static_cast<int>(out.size()) >= n) break;
    out.push_back(id);
  }
  return out;
}

// The map points of the keyframes `kf_ids`, each once, in order of first sighting; bad ones left
// out.
std::vector<int> SlamFrontend::Impl::keyframe_points(const std::vector<int>& kf_ids) const {
  std::vector<int> out;
  std::set<int> seen;
  for (const int id : kf_ids) {
    for (const int pid : keyframes[static_cast<std::size_t>(id)].data.points) {
      if (pid >= 0 && !points[static_cast<std::size_t>(pid)].bad && seen.insert(pid).second)
        out.push_back(pid);
    }
  }
  return out;
}

// Keyframe culling (ORB-SLAM §VI-E, Mur-Artal et al. 2015; ORB-SLAM2's KeyFrameCulling).
// Close map points of keyframe `id` (depth in (0, ThDepth]) and how many of them are seen by
// >= keyframe_redundant_observers other keyframes at the same or a finer scale (octave <= its
// octave + 1). Like ORB-SLAM2, only points whose observation weight (depth counts twice)
// exceeds the observer count are tested.
std::pair<int, int> SlamFrontend::Impl::redundancy(int id) const {
  const Keyframe& K = keyframes[static_cast<std::size_t>(id)];
  const int th = cfg.keyframe_redundant_observers;
  int close = 0;
  int redundant = 0;
  for (std::size_t i = 0; i < K.data.size(); ++i) {
    const int pid = K.data.points[i];
    if (pid < 0 || !K.data.is_close(i)) continue;
    const MapPoint& p = points[static_cast<std::size_t>(pid)];
    if (p.bad) continue;
    ++close;
    if (obs_weight(p) <= th) continue;
    const int level = K.data.octave[i];
    int n = 0;
    for (const auto& [kf, idx] : p.obs) {
      if (kf == id) continue;
      if (keyframes[static_cast<std::size_t>(kf)].data.octave[static_cast<std::size_t>(idx)] <=
              level + 1 &&
          ++n >= th)
        break;
    }
    redundant += n >= th ? 1 : 0;
  }
  return {close, redundant};
}

// Tests the covisible keyframes of `current` (most-sharing first, as ORB-SLAM2) and removes
// the redundant ones. Never keyframe 0, the tracking reference, keyframes newer than `current`
// (not yet mapped in ORB-SLAM2's order) or keyframes in a pending BA snapshot.
void SlamFrontend::Impl::cull_keyframes(int current) {
  if (keyframes[static_cast<std::size_t>(current)].bad) return;
  for (const int id : best_covisible(current, std::numeric_limits<int>::max())) {
    const Keyframe& K = keyframes[static_cast<std::size_t>(id)];
    if (id == 0 || id > current || id == ref_kf || K.bad) continue;
    if (ba_job &&
        std::find(ba_job->kf_ids.begin(), ba_job->kf_ids.end(), id) != ba_job->kf_ids.end())
      continue;
    const auto [close, redundant] = redundancy(id);
    if (redundant > cfg.keyframe_redundancy_ratio * close) remove_keyframe(id, close, redundant);
  }
}

// ORB-SLAM2's KeyFrame::SetBadFlag: the keyframe's frames (its own and those tracked against
// it) are re-parented to its most covisible keyframe with the relative transform of now (as
// ORB-SLAM2's spanning-tree parent + Tcp); its observations leave its map points (a point
// left with observation weight <= 2 is culled) and its covisibility edges are erased.
void SlamFrontend::Impl::remove_keyframe(int id, int close, int redundant) {
  Keyframe& K = keyframes[static_cast<std::size_t>(id)];
  int parent = -1;
  int parent_w = 0;
  for (const auto& [other, w] : K.covis) {
    if (w > parent_w && !keyframes[static_cast<std::size_t>(other)].bad) {
      parent_w = w;
      parent = other;
    }
  }
  if (parent < 0) return;
  const Eigen::Isometry3d T_k_p =
      K.T_cw * keyframes[static_cast<std::size_t>(parent)].T_cw.inverse();
  for (auto& r : records) {
    if (r.ref_kf != id) continue;
    if (r.keyframe) {
      // The keyframe's own frame becomes an ordinary frame: it keeps its map-point
      // observations as matches so that finish() refines it like the others.
      r.keyframe = false;
      if (cfg.refine_frame_poses && r.tracked) {
        for (std::size_t i = 0; i < K.data.size(); ++i) {
          const int pid = K.data.points[i];
          if (pid >= 0 && !points[static_cast<std::size_t>(pid)].bad)
            r.matches.emplace_back(pid, observation(K.data, i));
        }
      }
    }
    r.T_c_ref = r.T_c_ref * T_k_p;
    r.ref_kf = parent;
  }
  for (std::size_t i = 0; i < K.data.size(); ++i) {
    const int pid = K.data.points[i];
    if (pid < 0) continue;
    K.data.points[i] = -1;
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    if (p.bad) continue;
    const auto it =
        std::find_if(p.obs.begin(), p.obs.end(), [&](const auto& o) { return o.first == id; });
    if (it != p.obs.end()) p.obs.erase(it);
    if (p.obs.empty() || obs_weight(p) <= 2) {
      erase_point(pid);
    } else if (p.ref_kf == id) {
      p.ref_kf = p.obs.front().first;
      update_point_geometry(p);
    }
  }
  for (const auto& [other, w] : K.covis) keyframes[static_cast<std::size_t>(other)].covis.erase(id);
  K.covis.clear();
  K.bad = true;
  K.data = FrameData{};  // bounded memory: nothing reads a culled keyframe's features
  --live_keyframes;
  culled.push_back({K.frame_index, K.timestamp, frame_counter, close, redundant});
}

}  // namespace ds3d::slam
