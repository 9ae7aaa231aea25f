// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/slam_frontend.hpp"

#include "ds3d/slam/pose_smoothing.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <memory>
#include <utility>
#include <vector>

#include "ds3d/errors.hpp"
#include "slam_frontend_impl.hpp"

namespace ds3d::slam {

const char* to_string(TrackState s) noexcept {
  switch (s) {
    case TrackState::kNotInitialized:
      return "not_initialized";
    case TrackState::kInitialized:
      return "initialized";
    case TrackState::kTracking:
      return "tracking";
    case TrackState::kRelocalized:
      return "relocalized";
    case TrackState::kLost:
      return "lost";
    case TrackState::kReanchored:
      return "reanchored";
  }
  return "unknown";
}

void FrontendConfig::validate() const {
  constexpr const char* f = "ds3d::slam::FrontendConfig";
  camera.validate(f);
  orb.validate();
  pose.validate();
  local_ba.validate();
  DS3D_CHECK(std::isfinite(bf) && bf > 0, f, ": bf must be > 0 (got ", bf, ")");
  DS3D_CHECK(min_init_points >= 10, f, ": min_init_points must be >= 10 (got ", min_init_points,
             ")");
  DS3D_CHECK(min_tracked_inliers >= 10, f, ": min_tracked_inliers must be >= 10 (got ",
             min_tracked_inliers, ")");
  DS3D_CHECK(keyframe_max_gap >= 1, f, ": keyframe_max_gap must be >= 1 (got ", keyframe_max_gap,
             ")");
  DS3D_CHECK(local_window >= 2, f, ": local_window must be >= 2 (got ", local_window, ")");
  DS3D_CHECK(max_fixed_keyframes >= 1, f, ": max_fixed_keyframes must be >= 1 (got ",
             max_fixed_keyframes, ")");
  DS3D_CHECK(ba_apply_lag >= 0, f, ": ba_apply_lag must be >= 0 (got ", ba_apply_lag, ")");
  DS3D_CHECK(relocalisation_candidates >= 1, f, ": relocalisation_candidates must be >= 1 (got ",
             relocalisation_candidates, ")");
  DS3D_CHECK(reanchor_after_lost >= 0, f, ": reanchor_after_lost must be >= 0 (got ",
             reanchor_after_lost, ")");
  DS3D_CHECK(spare_features >= 0, f, ": spare_features must be >= 0 (got ", spare_features, ")");
  DS3D_CHECK(std::isfinite(disparity_sigma) && disparity_sigma >= 0, f,
             ": disparity_sigma must be finite and >= 0 (got ", disparity_sigma, ")");
  DS3D_CHECK(std::isfinite(max_acceleration) && max_acceleration >= 0, f,
             ": max_acceleration must be finite and >= 0 (got ", max_acceleration, ")");
  DS3D_CHECK(std::isfinite(max_angular_acceleration) && max_angular_acceleration >= 0, f,
             ": max_angular_acceleration must be finite and >= 0 (got ", max_angular_acceleration,
             ")");
  DS3D_CHECK(std::isfinite(prior_acceleration) && prior_acceleration >= 0, f,
             ": prior_acceleration must be finite and >= 0 (got ", prior_acceleration, ")");
  DS3D_CHECK(std::isfinite(depth_edge_ratio) && depth_edge_ratio >= 0, f,
             ": depth_edge_ratio must be finite and >= 0 (got ", depth_edge_ratio, ")");
  DS3D_CHECK(refine_rounds >= 0, f, ": refine_rounds must be >= 0 (got ", refine_rounds, ")");
  DS3D_CHECK(std::isfinite(source_motion_gate) && source_motion_gate >= 0, f,
             ": source_motion_gate must be finite and >= 0 (got ", source_motion_gate, ")");
  DS3D_CHECK(retrack_first_frames >= 0, f, ": retrack_first_frames must be >= 0 (got ",
             retrack_first_frames, ")");
  DS3D_CHECK(std::isfinite(smooth_acceleration) && smooth_acceleration >= 0, f,
             ": smooth_acceleration must be >= 0 (got ", smooth_acceleration, ")");
  DS3D_CHECK(std::isfinite(keyframe_ref_ratio) && keyframe_ref_ratio > 0 && keyframe_ref_ratio <= 1,
             f, ": keyframe_ref_ratio must be in (0, 1] (got ", keyframe_ref_ratio, ")");
  DS3D_CHECK(std::isfinite(keyframe_redundancy_ratio) && keyframe_redundancy_ratio > 0 &&
                 keyframe_redundancy_ratio <= 1,
             f, ": keyframe_redundancy_ratio must be in (0, 1] (got ", keyframe_redundancy_ratio,
             ")");
  DS3D_CHECK(keyframe_redundant_observers >= 1, f,
             ": keyframe_redundant_observers must be >= 1 (got ", keyframe_redundant_observers,
             ")");
}

void PipelineOptions::validate() const {
  DS3D_CHECK(queue_capacity >= 1, "ds3d::slam::PipelineOptions: queue_capacity must be >= 1 (got ",
             queue_capacity, ")");
}

SlamFrontend::Impl::Impl(FrontendConfig c, std::shared_ptr<DynamicObjectSource> s,
                         std::shared_ptr<DynamicFeatureMasker> m)
    : cfg(std::move(c)),
      extractor((cfg.validate(), cfg.orb)),
      source(std::move(s)),
      masker(std::move(m)) {
  if (!source) source = std::make_shared<NoDynamicObjects>();
  confirm_far =
      cfg.confirm_far_points && dynamic_cast<const NoDynamicObjects*>(source.get()) == nullptr;
  motion_prior =
      cfg.prior_acceleration > 0 && dynamic_cast<const NoDynamicObjects*>(source.get()) == nullptr;
  if (!masker) masker = std::make_shared<NoDynamicMasker>();
  k = {cfg.camera.fx, cfg.camera.fy, cfg.camera.cx, cfg.camera.cy, cfg.bf};
  for (int l = 0; l < cfg.orb.num_levels; ++l) {
    scale.push_back(extractor.level_scale(l));
    inv_sigma2.push_back(1.0 / (scale.back() * scale.back()));
  }
}

SlamFrontend::Impl::~Impl() {
  if (ba_job && ba_job->result.valid()) ba_job->result.wait();
}

// Re-optimises each tracked non-keyframe pose against the final map points it was matched to
// (pose-only, as in tracking), starting from its pose relative to its reference keyframe. A
// frame keeps its old pose when too few matches survive.
void SlamFrontend::Impl::refine_frame_poses(const PoseOptimizerParams& params) {
  for (auto& r : records) {
    if (!r.tracked || r.keyframe || r.ref_kf < 0 || r.matches.empty()) continue;
    std::vector<Eigen::Vector3d> pw;
    std::vector<Observation> obs;
    for (const auto& [pid, o] : r.matches) {
      const MapPoint& p = points[static_cast<std::size_t>(pid)];
      if (p.bad) continue;
      pw.push_back(p.pos);
      obs.push_back(o);
    }
    if (static_cast<int>(pw.size()) < cfg.min_tracked_inliers) continue;
    const Eigen::Isometry3d& T_rw = keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw;
    const auto opt = optimize_pose(k, r.T_c_ref * T_rw, pw, obs, params);
    if (opt.num_inliers >= cfg.min_tracked_inliers && opt.T_cam_world.matrix().allFinite()) {
      r.T_c_ref = opt.T_cam_world * T_rw.inverse();
    }
  }
}

// FrontendConfig::retrack_first_frames: the first frames matched again against the final map,
// backwards, each from the new pose of the frame after it. Their online poses may have followed
// people that the first map held and the final map no longer does.
void SlamFrontend::Impl::retrack_first_frames() {
  if (first_frames.empty()) return;
  std::size_t next = first_frames.back().first + 1;
  while (next < records.size() && !(records[next].tracked && records[next].ref_kf >= 0)) ++next;
  if (next >= records.size()) {
    first_frames.clear();
    return;
  }
  prior.sigma = 0;  // no motion prior: the neighbour's pose only starts the search
  Eigen::Isometry3d T_next = record_pose(records[next]);
  std::vector<int> cand;
  for (std::size_t j = 0; j < points.size(); ++j) {
    if (!points[j].bad) cand.push_back(static_cast<int>(j));
  }
  std::size_t stamp = frame_counter;  // marks of searches after the last frame
  for (auto it = first_frames.rbegin(); it != first_frames.rend(); ++it) {
    FrameRecord& r = records[it->first];
    if (!r.tracked || r.ref_kf < 0) continue;
    FrameData& f = it->second;
    Eigen::Isometry3d T = T_next;
    search_by_projection(f, T, cand, 15.0, false, stamp++);
    if (optimize_frame(f, T) < cfg.min_tracked_inliers) continue;
    r.T_c_ref = T * keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw.inverse();
    if (cfg.refine_frame_poses && !r.keyframe) {  // what refine_frame_poses() starts from
      r.matches.clear();
      for (std::size_t j = 0; j < f.size(); ++j) {
        if (f.points[j] >= 0) r.matches.emplace_back(f.points[j], observation(f, j));
      }
    }
    T_next = T;
  }
  for (auto& p : points) {  // clear the searches' marks (unmarked is max())
    if (p.last_frame_seen >= frame_counter)
      p.last_frame_seen = std::numeric_limits<std::size_t>::max();
  }
  first_frames.clear();
  first_frames.shrink_to_fit();
}

// A record's pose in the world: relative to its reference keyframe where it has one.
Eigen::Isometry3d SlamFrontend::Impl::record_pose(const FrameRecord& r) const {
  return r.ref_kf >= 0
             ? Eigen::Isometry3d(r.T_c_ref * keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw)
             : r.T_cw_online;
}

// FrontendConfig::smooth_acceleration: every tracked frame, keyframes included, smoothed against
// the final map points it was matched to (the matches that pass the χ² test at its refined pose).
// Only the frame trajectory moves: the keyframes' own poses (keyframe_trajectory()) stay as BA
// left them.
void SlamFrontend::Impl::smooth_frame_poses() {
  std::vector<SmoothingFrame> frames;
  frames.reserve(records.size());
  std::vector<std::size_t> rec;
  for (std::size_t i = 0; i < records.size(); ++i) {
    const FrameRecord& r = records[i];
    SmoothingFrame s;
    s.timestamp = r.timestamp;
    s.valid = r.tracked && r.ref_kf >= 0;
    if (s.valid) s.T_cam_world = record_pose(r);
    if (!frames.empty() && !(s.timestamp > frames.back().timestamp)) continue;
    const auto add = [&](int pid, const Observation& o) {
      const MapPoint& p = points[static_cast<std::size_t>(pid)];
      if (p.bad) return;
      bool front = false;
      const double chi2 = reprojection_chi2(k, s.T_cam_world, p.pos, o, &front);
      if (!front || chi2 > (o.stereo() ? cfg.pose.chi2_stereo : cfg.pose.chi2_mono)) return;
      s.points.push_back(p.pos);
      s.observations.push_back(o);
    };
    if (s.valid && r.keyframe) {
      // A live keyframe's own frame (its ref_kf is itself): the keyframe's observations.
      const FrameData& d = keyframes[static_cast<std::size_t>(r.ref_kf)].data;
      for (std::size_t j = 0; j < d.size(); ++j) {
        if (d.points[j] >= 0) add(d.points[j], observation(d, j));
      }
    } else if (s.valid) {
      for (const auto& [pid, o] : r.matches) add(pid, o);
    }
    frames.push_back(std::move(s));
    rec.push_back(i);
  }
  PoseSmoothingParams params;
  params.acceleration_sigma = cfg.smooth_acceleration;
  params.chi2_mono = cfg.pose.chi2_mono;
  params.chi2_stereo = cfg.pose.chi2_stereo;
  const std::vector<Eigen::Isometry3d> T = smooth_poses(k, frames, params);
  for (std::size_t j = 0; j < frames.size(); ++j) {
    FrameRecord& r = records[rec[j]];
    if (!frames[j].valid) continue;
    r.T_c_ref = T[j] * keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw.inverse();
  }
}

// Structure-only step over every map point with all its observations, the keyframes' and the
// (refined) frames', every pose fixed: a few Gauss-Newton iterations on the 3-D position with
// Huber weights, then a χ² test; a point keeps its position unless at least two observations
// pass and the solution is finite. Points are independent, so this is O(observations).
void SlamFrontend::Impl::refine_points_from_frames() {
  struct Obs {
    Eigen::Isometry3d T_cw;
    Observation o;
  };
  std::vector<std::vector<Obs>> per_point(points.size());
  for (std::size_t j = 0; j < points.size(); ++j) {
    const MapPoint& p = points[j];
    if (p.bad) continue;
    for (const auto& [kf, idx] : p.obs) {
      const Keyframe& K = keyframes[static_cast<std::size_t>(kf)];
      per_point[j].push_back({K.T_cw, observation(K.data, static_cast<std::size_t>(idx))});
    }
  }
  for (const auto& r : records) {
    if (!r.tracked || r.keyframe || r.ref_kf < 0) continue;
    const Eigen::Isometry3d T_cw = record_pose(r);
    for (const auto& [pid, o] : r.matches) {
      if (!points[static_cast<std::size_t>(pid)].bad)
        per_point[static_cast<std::size_t>(pid)].push_back({T_cw, o});
    }
  }
  for (std::size_t j = 0; j < points.size(); ++j) {
    MapPoint& p = points[j];
    const auto& obs = per_point[j];
    if (p.bad || obs.size() < 2) continue;
    Eigen::Vector3d x = p.pos;
    for (int it = 0; it < 5; ++it) {
      Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
      Eigen::Vector3d b = Eigen::Vector3d::Zero();
      for (const auto& ob : obs) {
        double res[3];
        double jp[9];
        const int d = reprojection_residual(k, ob.T_cw, x, ob.o, res, nullptr, jp);
        if (d == 0) continue;
        const Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>> J(jp, d,
                                                                                            3);
        const Eigen::Map<const Eigen::VectorXd> e(res, d);
        const double chi2 = e.squaredNorm();
        const double th = d == 3 ? cfg.local_ba.chi2_stereo : cfg.local_ba.chi2_mono;
        const double w = chi2 <= th ? 1.0 : std::sqrt(th / chi2);  // Huber, δ² = χ² threshold
        H += w * J.transpose() * J;
        b += w * J.transpose() * e;
      }
      const Eigen::Vector3d dx = H.ldlt().solve(-b);
      if (!dx.allFinite()) break;
      x += dx;
      if (dx.norm() < 1e-7) break;
    }
    int inliers = 0;
    for (const auto& ob : obs) {
      bool front = false;
      const double chi2 = reprojection_chi2(k, ob.T_cw, x, ob.o, &front);
      if (!front) continue;
      inliers +=
          chi2 <= (ob.o.stereo() ? cfg.local_ba.chi2_stereo : cfg.local_ba.chi2_mono) ? 1 : 0;
    }
    if (inliers >= 2 && x.allFinite()) p.pos = x;
  }
}

SlamFrontend::SlamFrontend(FrontendConfig config, std::shared_ptr<DynamicObjectSource> source,
                           std::shared_ptr<DynamicFeatureMasker> masker)
    : impl_(std::make_unique<Impl>(std::move(config), std::move(source), std::move(masker))) {}
SlamFrontend::~SlamFrontend() = default;
SlamFrontend::SlamFrontend(SlamFrontend&&) noexcept = default;
SlamFrontend& SlamFrontend::operator=(SlamFrontend&&) noexcept = default;

PreparedFrame SlamFrontend::extract(FrameInput frame) const {
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_ms();
  PreparedFrame pf;
  // With spare_features = 0 the spare list stays empty and the features are extract()'s.
  if (impl_->source->uses_orb_corners()) {
    auto corners = std::make_shared<OrbCorners>();
    pf.features = impl_->extractor.extract(frame.rgb, frame.depth, impl_->cfg.camera, pf.spare,
                                           impl_->cfg.spare_features, *corners);
    frame.orb_corners = std::move(corners);
  } else {
    pf.features = impl_->extractor.extract(frame.rgb, frame.depth, impl_->cfg.camera, pf.spare,
                                           impl_->cfg.spare_features);
  }
  pf.input = std::move(frame);
  pf.times.extract_ms = ms_since(t0);
  pf.times.extract_cpu_ms = thread_cpu_ms() - c0;
  return pf;
}

void SlamFrontend::prepare_dynamic(PreparedFrame& frame) const {
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_ms();
  frame.detection = impl_->source->prepare(frame.input, impl_->cfg.camera);
  frame.times.prepare_ms = ms_since(t0);
  frame.times.prepare_cpu_ms = thread_cpu_ms() - c0;
}

void SlamFrontend::detect_dynamic(PreparedFrame& frame) {
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_ms();
  frame.objects =
      impl_->source->detect_prepared(frame.input, impl_->cfg.camera, frame.detection.get());
  frame.detection.reset();
  frame.input.orb_corners.reset();
  frame.times.detect_ms = frame.times.prepare_ms + ms_since(t0);
  frame.times.detect_cpu_ms = frame.times.prepare_cpu_ms + thread_cpu_ms() - c0;
}

void SlamFrontend::filter_dynamic(PreparedFrame& frame) {
  const auto t0 = Clock::now();
  frame.dynamic =
      impl_->masker->mask(frame.input, impl_->cfg.camera, frame.features, frame.objects);
  DS3D_CHECK(frame.dynamic.size() == frame.features.size(),
             "ds3d::slam::SlamFrontend: dynamic filter '", impl_->masker->name(), "' returned ",
             frame.dynamic.size(), " flags for ", frame.features.size(), " keypoints");
  for (auto& d : frame.dynamic) d = d != 0 ? 1 : 0;
  mark_depth_edges(frame, impl_->cfg.camera, impl_->extractor, impl_->cfg.depth_edge_ratio);
  refill_static(frame, impl_->cfg.camera, impl_->extractor);
  frame.times.filter_ms = ms_since(t0);
}

TrackResult SlamFrontend::track_prepared(PreparedFrame frame) {
  return impl_->track(std::move(frame));
}

TrackResult SlamFrontend::track(const cv::Mat& rgb, const cv::Mat& depth, double timestamp) {
  FrameInput in;
  in.index = impl_->frame_counter;
  in.timestamp = timestamp;
  in.rgb = rgb;
  in.depth = depth;
  PreparedFrame pf = extract(std::move(in));
  detect_dynamic(pf);
  filter_dynamic(pf);
  return track_prepared(std::move(pf));
}

TrackResult SlamFrontend::track(const RgbdFrame& frame) {
  PreparedFrame pf = extract(to_frame_input(frame));
  detect_dynamic(pf);
  filter_dynamic(pf);
  return track_prepared(std::move(pf));
}

Trajectory to_trajectory(const std::vector<FramePose>& poses) {
  Trajectory out;
  out.reserve(poses.size());
  for (const auto& p : poses) {
    TimedPose t;
    t.timestamp = p.timestamp;
    t.T_world_cam = p.T_world_cam;
    out.push_back(t);
  }
  return out;
}

void SlamFrontend::finish() {
  impl_->apply_ba_if_due(true);
  impl_->merge_segments();
  if (impl_->cfg.final_global_ba && impl_->live_keyframes >= 2) {
    // Global BA over every keyframe and point, first keyframe fixed (the world frame).
    std::vector<int> local;
    for (std::size_t i = 1; i < impl_->keyframes.size(); ++i) {
      if (!impl_->keyframes[i].bad) local.push_back(static_cast<int>(i));
    }
    std::vector<int> pts;
    for (std::size_t j = 0; j < impl_->points.size(); ++j) {
      if (!impl_->points[j].bad) pts.push_back(static_cast<int>(j));
    }
    LocalBaParams params = impl_->cfg.local_ba;
    params.iterations_first = std::max(params.iterations_first, 10);
    params.iterations_second = std::max(params.iterations_second, 10);
    impl_->launch_ba(local, {0}, pts, false, params);
    impl_->apply_ba_if_due(true);
  }
  impl_->retrack_first_frames();
  if (impl_->cfg.refine_frame_poses) {
    const double c0 = thread_cpu_ms();
    impl_->refine_frame_poses(impl_->cfg.pose);
    // After the first pass each frame starts next to its optimum: one robust round to re-classify
    // outliers and the final plain one are enough.
    PoseOptimizerParams again = impl_->cfg.pose;
    again.rounds = std::min(again.rounds, 2);
    for (int round = 0; round < impl_->cfg.refine_rounds; ++round) {
      impl_->refine_points_from_frames();
      impl_->refine_frame_poses(again);
    }
    if (impl_->cfg.smooth_acceleration > 0) impl_->smooth_frame_poses();
    for (auto& r : impl_->records) {
      r.matches.clear();
      r.matches.shrink_to_fit();
    }
    impl_->refine_ms += thread_cpu_ms() - c0;
  }
  if (impl_->cfg.interpolate_lost) impl_->interpolate_lost_frames();
}

std::vector<FramePose> SlamFrontend::trajectory() const {
  std::vector<FramePose> out;
  out.reserve(impl_->records.size());
  for (const auto& r : impl_->records) {
    FramePose p;
    p.index = r.index;
    p.timestamp = r.timestamp;
    p.tracked = r.tracked;
    p.T_world_cam = impl_->record_pose(r).inverse();
    out.push_back(p);
  }
  return out;
}

std::vector<FramePose> SlamFrontend::keyframe_trajectory() const {
  std::vector<FramePose> out;
  for (const auto& kf : impl_->keyframes) {
    if (!kf.bad) out.push_back({kf.frame_index, kf.timestamp, kf.T_cw.inverse(), true});
  }
  return out;
}

Points3f SlamFrontend::map_points() const {
  std::vector<const MapPoint*> good;
  for (const auto& p : impl_->points) {
    if (!p.bad && p.pos.allFinite()) good.push_back(&p);
  }
  Points3f out(static_cast<Eigen::Index>(good.size()), 3);
  for (std::size_t i = 0; i < good.size(); ++i)
    out.row(static_cast<Eigen::Index>(i)) = good[i]->pos.cast<float>().transpose();
  return out;
}

void SlamFrontend::write_map_ply(const std::filesystem::path& path) const {
  const Points3f pts = map_points();
  std::ofstream out(path);
  DS3D_CHECK_AS(IoError, out.good(), "ds3d::slam::SlamFrontend::write_map_ply: cannot open '",
                path.string(), "'");
  out << "ply\nformat ascii 1.0\nelement vertex " << pts.rows()
      << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  for (Eigen::Index i = 0; i < pts.rows(); ++i)
    out << pts(i, 0) << ' ' << pts(i, 1) << ' ' << pts(i, 2) << '\n';
  DS3D_CHECK_AS(IoError, out.good(), "ds3d::slam::SlamFrontend::write_map_ply: write failed for '",
                path.string(), "'");
}

const FrontendConfig& SlamFrontend::config() const noexcept { return impl_->cfg; }
std::size_t SlamFrontend::num_keyframes() const noexcept { return impl_->live_keyframes; }
int SlamFrontend::merged_segments() const noexcept { return impl_->num_merged_segments; }

int SlamFrontend::interpolated_frames() const noexcept { return impl_->num_interpolated_frames; }

const std::vector<CulledKeyframe>& SlamFrontend::culled_keyframes() const noexcept {
  return impl_->culled;
}
std::size_t SlamFrontend::num_local_ba() const noexcept { return impl_->ba_count; }
double SlamFrontend::local_ba_ms() const noexcept { return impl_->ba_ms; }
double SlamFrontend::refine_ms() const noexcept { return impl_->refine_ms; }
const DynamicObjectSource& SlamFrontend::dynamic_source() const noexcept { return *impl_->source; }
const DynamicFeatureMasker& SlamFrontend::dynamic_masker() const noexcept { return *impl_->masker; }

}  // namespace ds3d::slam
