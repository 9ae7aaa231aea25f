// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// finish(): re-anchored map segments moved back onto the earlier map (FrontendConfig::
// merge_segments), and lost frames given poses between the frames around them
// (FrontendConfig::interpolate_lost).
#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <vector>

#include <Eigen/Geometry>

#include "slam_frontend_impl.hpp"

namespace ds3d::slam {

using detail::FrameData;
using detail::Keyframe;

// Index of the map segment keyframe `kf` belongs to: 0 for the first map, s + 1 for the one that
// segment_starts[s] started.
int SlamFrontend::Impl::segment_of(int kf) const {
  return static_cast<int>(std::upper_bound(segment_starts.begin(), segment_starts.end(), kf) -
                          segment_starts.begin());
}

int SlamFrontend::Impl::group_of(int kf) const {
  return segment_group[static_cast<std::size_t>(segment_of(kf))];
}

// Relocalisation of keyframe K against the keyframes of the other segment groups, nearest in time
// first, up to relocalisation_candidates: descriptor matching against one keyframe, pose-only
// optimisation (PnP-RANSAC when needed), then that keyframe's local map; accepted with
// relocalisation's 50 inliers (or min_tracked_inliers if larger). T_cw: K's pose in that map.
// Returns the keyframe it was found against, -1 if none.
int SlamFrontend::Impl::localise_in_other_segments(const Keyframe& K, Eigen::Isometry3d& T_cw) {
  const int min_inliers = std::max(50, cfg.min_tracked_inliers);
  const int group = group_of(K.id);
  std::vector<int> cand;
  for (std::size_t id = 0; id < keyframes.size(); ++id) {
    if (!keyframes[id].bad && group_of(static_cast<int>(id)) != group)
      cand.push_back(static_cast<int>(id));
  }
  std::stable_sort(cand.begin(), cand.end(),
                   [&K](int a, int b) { return std::abs(a - K.id) < std::abs(b - K.id); });
  if (cand.size() > static_cast<std::size_t>(cfg.relocalisation_candidates))
    cand.resize(static_cast<std::size_t>(cfg.relocalisation_candidates));
  const int saved_ref = ref_kf;
  int found = -1;
  for (const int id : cand) {
    const Keyframe& other = keyframes[static_cast<std::size_t>(id)];
    FrameData f = K.data;
    std::fill(f.points.begin(), f.points.end(), -1);
    Eigen::Isometry3d T = other.T_cw;
    const bool ok = track_keyframe(other, f, T, min_inliers) &&
                    track_local_map(f, T) >= min_inliers && T.matrix().allFinite();
    clear_frame_marks();
    if (ok) {
      T_cw = T;
      found = id;
      break;
    }
  }
  ref_kf = saved_ref;
  return found;
}

// Every keyframe of segment group `group`, and every map point first made by one of them, moved by
// the world change W (the other world → this group's world): T_cw · W, W⁻¹ · p; the group then
// belongs to `into`.
void SlamFrontend::Impl::move_group(int group, const Eigen::Isometry3d& W, int into) {
  const Eigen::Isometry3d Winv = W.inverse();
  for (std::size_t id = 0; id < keyframes.size(); ++id) {
    if (group_of(static_cast<int>(id)) == group) keyframes[id].T_cw = keyframes[id].T_cw * W;
  }
  for (auto& p : points) {
    if (p.bad || p.first_kf < 0 || group_of(p.first_kf) != group) continue;
    p.pos = Winv * p.pos;
    p.normal = Winv.linear() * p.normal;
  }
  for (auto& g : segment_group) {
    if (g == group) g = into;
  }
}

// Each segment outside the first map's group, keyframe by keyframe in order, is localised against
// the other groups; on success its whole group moves onto that map. One pass is enough: a merge
// changes no segment's candidate keyframes (those outside its group) but moves them rigidly with
// their map, so a segment that found no match will not find one later.
void SlamFrontend::Impl::merge_segments() {
  segment_group.resize(segment_starts.size() + 1);
  for (std::size_t g = 0; g < segment_group.size(); ++g) segment_group[g] = static_cast<int>(g);
  if (!cfg.merge_segments) return;
  for (std::size_t s = 1; s < segment_group.size(); ++s) {
    if (segment_group[s] == segment_group[0]) continue;
    const int first = segment_starts[s - 1];
    const int end =
        s < segment_starts.size() ? segment_starts[s] : static_cast<int>(keyframes.size());
    for (int id = first; id < end; ++id) {
      const Keyframe& K = keyframes[static_cast<std::size_t>(id)];
      if (K.bad) continue;
      Eigen::Isometry3d T;
      const int other = localise_in_other_segments(K, T);
      if (other < 0) continue;
      move_group(segment_group[s], K.T_cw.inverse() * T, group_of(other));
      ++num_merged_segments;
      break;
    }
  }
}

// Records i .. b − 1 placed between records i − 1 and b: the camera centre linear in time, the
// rotation slerped.
void SlamFrontend::Impl::interpolate_records(std::size_t i, std::size_t b) {
  const FrameRecord& A = records[i - 1];
  const FrameRecord& B = records[b];
  const Eigen::Isometry3d Ta = record_pose(A).inverse();  // T_world_cam
  const Eigen::Isometry3d Tb = record_pose(B).inverse();
  const Eigen::Quaterniond qa(Ta.linear());
  const Eigen::Quaterniond qb(Tb.linear());
  for (std::size_t j = i; j < b; ++j) {
    FrameRecord& r = records[j];
    if (r.ref_kf < 0) continue;
    const double a =
        std::clamp((r.timestamp - A.timestamp) / (B.timestamp - A.timestamp), 0.0, 1.0);
    Eigen::Isometry3d Twc = Eigen::Isometry3d::Identity();
    Twc.linear() = qa.slerp(a, qb).toRotationMatrix();
    Twc.translation() = (1.0 - a) * Ta.translation() + a * Tb.translation();
    r.T_c_ref = Twc.inverse() * keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw.inverse();
    ++num_interpolated_frames;
  }
}

// A break in the map: after a record placed in group G, the records up to the next one placed in
// G are lost, or placed in groups that appear nowhere else (a segment that never merged, whose
// world is unknown). They are interpolated between the two records of G.
void SlamFrontend::Impl::interpolate_lost_frames() {
  const std::size_t n = records.size();
  std::vector<int> g(n, -1);  // group of each record placed in the map, -1 for lost ones
  std::vector<std::size_t> first_rec(segment_group.size(), n);
  std::vector<std::size_t> last_rec(segment_group.size(), 0);
  for (std::size_t j = 0; j < n; ++j) {
    const FrameRecord& r = records[j];
    if (r.ref_kf < 0 || !(r.tracked || r.keyframe)) continue;
    g[j] = group_of(r.ref_kf);
    const auto u = static_cast<std::size_t>(g[j]);
    first_rec[u] = std::min(first_rec[u], j);
    last_rec[u] = std::max(last_rec[u], j);
  }
  std::size_t i = 1;
  while (i < n) {
    if (g[i - 1] < 0 || g[i] == g[i - 1]) {
      ++i;
      continue;
    }
    std::size_t b = i;
    while (b < n && g[b] != g[i - 1]) ++b;
    bool confined = true;  // every group placed inside the break appears nowhere else
    for (std::size_t j = i; j < b; ++j) {
      if (g[j] < 0) continue;
      const auto u = static_cast<std::size_t>(g[j]);
      confined = confined && first_rec[u] >= i && last_rec[u] < b;
    }
    if (b < n && confined && records[b].timestamp > records[i - 1].timestamp) {
      interpolate_records(i, b);
      i = b;
    } else {
      ++i;
    }
  }
}

}  // namespace ds3d::slam
