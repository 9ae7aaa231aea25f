// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// Private to SlamFrontend: the map's types and SlamFrontend::Impl, shared by its sources.
#pragma once

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <future>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "ds3d/slam/dynamic/boxes.hpp"
#include "ds3d/slam/slam_frontend.hpp"

namespace ds3d::slam::detail {

using Clock = std::chrono::steady_clock;
inline double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
// CPU time of the calling thread [ms] (POSIX).
inline double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

inline constexpr int kThHigh = 100;  // ORB-SLAM2's ORBmatcher::TH_HIGH
inline constexpr int kThLow = 50;    // ORB-SLAM2's ORBmatcher::TH_LOW
inline constexpr int kGridCols = 64;
inline constexpr int kGridRows = 48;

using Descriptor = std::array<std::uint8_t, 32>;

// Observations of a map point that choose its descriptor (update_point_descriptor).
inline constexpr std::size_t kDescriptorWindow = 32;

inline Descriptor row_descriptor(const cv::Mat& d, int i) {
  Descriptor out{};
  std::memcpy(out.data(), d.ptr<std::uint8_t>(i), 32);
  return out;
}

// Features of a frame or keyframe bucketed on a coarse grid for radius queries.
class FeatureGrid {
 public:
  void build(const std::vector<Eigen::Vector2f>& uv, int width, int height) {
    width_ = width;
    height_ = height;
    cells_.assign(static_cast<std::size_t>(kGridCols * kGridRows), {});
    for (std::size_t i = 0; i < uv.size(); ++i) {
      const int c = cell_x(uv[i].x());
      const int r = cell_y(uv[i].y());
      cells_[static_cast<std::size_t>(r * kGridCols + c)].push_back(static_cast<int>(i));
    }
  }
  template <class F>
  void for_each_in(double u, double v, double radius, F&& f) const {
    const int c0 = cell_x(u - radius);
    const int c1 = cell_x(u + radius);
    const int r0 = cell_y(v - radius);
    const int r1 = cell_y(v + radius);
    for (int r = r0; r <= r1; ++r) {
      for (int c = c0; c <= c1; ++c) {
        for (const int i : cells_[static_cast<std::size_t>(r * kGridCols + c)]) f(i);
      }
    }
  }

 private:
  [[nodiscard]] int cell_x(double u) const {
    return std::clamp(static_cast<int>(std::floor(u * kGridCols / width_)), 0, kGridCols - 1);
  }
  [[nodiscard]] int cell_y(double v) const {
    return std::clamp(static_cast<int>(std::floor(v * kGridRows / height_)), 0, kGridRows - 1);
  }
  int width_ = 1;
  int height_ = 1;
  std::vector<std::vector<int>> cells_;
};

struct MapPoint {
  Eigen::Vector3d pos = Eigen::Vector3d::Zero();
  Descriptor desc{};
  std::vector<std::pair<int, int>> obs;  // (keyframe id, keypoint index)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  double max_dist = 0;
  double min_dist = 0;
  int ref_kf = -1;
  int first_kf = -1;
  int visible = 1;
  int found = 1;
  bool bad = false;
  std::size_t last_frame_seen = std::numeric_limits<std::size_t>::max();
  std::size_t local_stamp = std::numeric_limits<std::size_t>::max();
};

// Shared per-keypoint data of frames and keyframes.
struct FrameData {
  float close_depth = 3.0F;
  std::vector<Eigen::Vector2f> uv;
  std::vector<float> depth;
  std::vector<int> octave;
  std::vector<float> disp_inv_sigma2;  // FrontendConfig::disparity_sigma; empty when off
  cv::Mat desc;
  std::vector<int> points;  // map point id or -1
  FeatureGrid grid;
  [[nodiscard]] std::size_t size() const { return uv.size(); }
  [[nodiscard]] bool is_close(std::size_t i) const {
    return depth[i] > 0 && depth[i] <= close_depth;
  }
  [[nodiscard]] double u_right(std::size_t i, double bf) const {
    return depth[i] > 0 ? uv[i].x() - bf / depth[i] : -1.0;
  }
};

struct Keyframe {
  int id = 0;
  std::size_t frame_index = 0;
  double timestamp = 0;
  Eigen::Isometry3d T_cw = Eigen::Isometry3d::Identity();
  FrameData data;
  std::map<int, int> covis;  // keyframe id -> shared points
  bool bad = false;          // removed by keyframe culling (its data is released)
  [[nodiscard]] Eigen::Vector3d center() const { return T_cw.inverse().translation(); }
};

// A local BA launched at a keyframe: input snapshot and (future) result.
struct BaJob {
  std::size_t due_frame = 0;
  std::vector<int> kf_ids;
  std::vector<int> point_ids;
  std::vector<BaObservation> observations;
  std::future<std::pair<LocalBaResult, double>> result;
  int cull_kf = -1;  // local BA of this keyframe: keyframe culling runs after it is applied
};

}  // namespace ds3d::slam::detail

namespace ds3d::slam {

/// Moves the spare candidates of `pf` that lie clearly off the dynamic regions (outside the
/// source's boxes and pixel mask, farther than a grid cell from each removed keypoint) into
/// pf.features as static keypoints, at most one per removed keypoint (static_refill.cpp).
void refill_static(PreparedFrame& pf, const PinholeCamera& camera, const OrbExtractor& extractor);

/// True if pixel `p` lies in one of `boxes` (edges included).
inline bool in_any_box(const std::vector<ImageBox>& boxes, const cv::Point2f& p) {
  return std::any_of(boxes.begin(), boxes.end(), [&](const ImageBox& b) {
    return p.x >= b.x_min && p.x <= b.x_max && p.y >= b.y_min && p.y <= b.y_max;
  });
}

/// True if pixel `p` (rounded, clamped to the image) is set in the CV_8UC1 mask `m`; false for
/// an empty mask or another type.
inline bool in_mask(const cv::Mat& m, const cv::Point2f& p) {
  if (m.empty() || m.type() != CV_8UC1) return false;
  const int x = std::clamp(static_cast<int>(std::lround(p.x)), 0, m.cols - 1);
  const int y = std::clamp(static_cast<int>(std::lround(p.y)), 0, m.rows - 1);
  return m.at<std::uint8_t>(y, x) != 0U;
}

/// PreparedFrame::dynamic value of a keypoint removed for lying on a depth edge (the dynamic
/// filter's flags are 1).
inline constexpr std::uint8_t kDepthEdgeFlag = 2;

/// Marks with kDepthEdgeFlag the keypoints of `pf` not already removed that touch a dynamic
/// region (one of 17 samples, the keypoint's pixel and 16 at 4 and 8 px × level scale, lies in
/// a source box's image rectangle or on its pixel mask) and whose samples span a depth step:
/// farthest valid depth > (1 + ratio) × nearest. Returns how many (depth_edges.cpp).
int mark_depth_edges(PreparedFrame& pf, const PinholeCamera& camera, const OrbExtractor& extractor,
                     double ratio);

/// Per feature of `pf`, the information 1/σ_d² [px⁻²] of its disparity bf/z: σ_d² =
/// cfg.disparity_sigma² + the largest disparity difference to the depth 2 px × level scale
/// around it (8 directions; the whole disparity when one of them has no depth). 0 for features
/// without depth, all 0 when cfg.disparity_sigma is 0 (disparity_sigma.cpp).
std::vector<float> disparity_inv_sigma2(const PreparedFrame& pf, const FrontendConfig& cfg,
                                        const OrbExtractor& extractor);

// The front-end's sources use the short names.
using detail::BaJob;
using detail::Clock;
using detail::Descriptor;
using detail::FeatureGrid;
using detail::FrameData;
using detail::kDescriptorWindow;
using detail::Keyframe;
using detail::kThHigh;
using detail::kThLow;
using detail::MapPoint;
using detail::ms_since;
using detail::row_descriptor;
using detail::thread_cpu_ms;

struct SlamFrontend::Impl {
  FrontendConfig cfg;
  OrbExtractor extractor;
  StereoIntrinsics k;
  std::vector<double> scale;       // per level
  std::vector<double> inv_sigma2;  // per level
  std::shared_ptr<DynamicObjectSource> source;
  std::shared_ptr<DynamicFeatureMasker> masker;
  bool confirm_far = false;   // cfg.confirm_far_points and a source other than "none"
  bool motion_prior = false;  // cfg.prior_acceleration > 0 and a source other than "none"

  std::vector<Keyframe> keyframes;  // indexed by id; culled ones stay (bad = true)
  std::size_t live_keyframes = 0;
  std::vector<CulledKeyframe> culled;
  std::vector<MapPoint> points;
  std::vector<int> recent_points;

  // Tracking state.
  std::size_t frame_counter = 0;  // frames processed by track_prepared
  bool initialized = false;
  bool have_last = false;
  double last_timestamp = -std::numeric_limits<double>::infinity();
  FrameData last;
  Eigen::Isometry3d last_T_cw = Eigen::Isometry3d::Identity();
  bool last_tracked = false;
  bool velocity_valid = false;
  bool velocity_trusted = false;  // velocity from two frames tracked normally (the motion gate)
  bool last_normal = false;       // the last frame was tracked, not relocalised or re-anchored
  Eigen::Isometry3d velocity = Eigen::Isometry3d::Identity();
  CentrePrior prior;  // FrontendConfig::prior_acceleration for this frame (sigma 0 = none)
  int ref_kf = -1;
  int last_kf_frame = 0;  // frame_counter at the last keyframe
  int lost_count = 0;
  std::vector<int> segment_starts;  // first keyframe of each segment a re-anchoring started
  std::vector<int> segment_group;   // finish(): per segment, the segment whose world it is in
  int num_merged_segments = 0;
  int num_interpolated_frames = 0;
  bool just_relocalized = false;
  // Map points whose MapPoint::visible / found this frame's tracking raised, one entry per
  // raise, so that a hypothesis not kept can take its raises back (settle_retry).
  std::vector<int> raised_visible;
  std::vector<int> raised_found;
  // Where a retry of the pose started: the raises so far and the reference keyframe.
  struct RetryMark {
    std::size_t visible;
    std::size_t found;
    int ref_kf;
  };

  // Trajectory: per frame, pose relative to its reference keyframe.
  struct FrameRecord {
    std::size_t index;
    double timestamp;
    int ref_kf;
    Eigen::Isometry3d T_c_ref;
    Eigen::Isometry3d T_cw_online;
    bool tracked;
    bool keyframe = false;
    std::vector<std::pair<int, Observation>> matches;  // kept only for refine_frame_poses
  };
  std::vector<FrameRecord> records;
  // FrontendConfig::retrack_first_frames: (record index, features) of the first frames.
  std::vector<std::pair<std::size_t, FrameData>> first_frames;

  std::optional<BaJob> ba_job;
  std::size_t ba_count = 0;
  double ba_ms = 0;
  double refine_ms = 0;  // thread CPU of finish()'s refinement

  Impl(FrontendConfig c, std::shared_ptr<DynamicObjectSource> s,
       std::shared_ptr<DynamicFeatureMasker> m);
  ~Impl();

  // ---- helpers (inline: the matching and mapping loops of several files call them) --------
  // ORB-SLAM2 counts an observation with depth twice (it constrains like a stereo pair).
  [[nodiscard]] int obs_weight(const MapPoint& p) const {
    int n = 0;
    for (const auto& [kf, idx] : p.obs) {
      n += keyframes[static_cast<std::size_t>(kf)].data.depth[static_cast<std::size_t>(idx)] > 0
               ? 2
               : 1;
    }
    return n;
  }

  [[nodiscard]] Observation observation(const FrameData& f, std::size_t i) const {
    Observation o;
    o.pixel = f.uv[i].cast<double>();
    o.u_right = f.u_right(i, k.bf);
    o.has_depth = f.depth[i] > 0;
    o.inv_sigma2 = inv_sigma2[static_cast<std::size_t>(f.octave[i])];
    if (!f.disp_inv_sigma2.empty()) o.disparity_inv_sigma2 = f.disp_inv_sigma2[i];
    return o;
  }

  [[nodiscard]] int predict_level(const MapPoint& p, double dist) const {
    if (dist <= 0) return 0;
    const int l =
        static_cast<int>(std::ceil(std::log(p.max_dist / dist) / std::log(cfg.orb.scale_factor)));
    return std::clamp(l, 0, cfg.orb.num_levels - 1);
  }

  // ---- tracking.cpp: frame preparation, matching, pose optimisation, tracking, relocalisation
  FrameData make_frame_data(const PreparedFrame& pf) const;
  int search_by_projection(FrameData& f, const Eigen::Isometry3d& T_cw,
                           const std::vector<int>& candidates, double th, bool local_map,
                           std::size_t stamp);
  int match_keyframe(const Keyframe& kf, FrameData& f) const;
  int optimize_frame(FrameData& f, Eigen::Isometry3d& T_cw) const;
  void set_prior(double dt);
  bool pnp_ransac(const FrameData& f, Eigen::Isometry3d& T_cw) const;
  void forget_seen(const std::vector<int>& cand);
  void clear_frame_marks();
  int search_widening(FrameData& f, const Eigen::Isometry3d& T_cw, const std::vector<int>& cand);
  bool track_motion_model(FrameData& f, Eigen::Isometry3d& T_cw);
  bool track_keyframe(const Keyframe& kf, FrameData& f, Eigen::Isometry3d& T_cw, int min_inliers);
  bool relocalize(FrameData& f, Eigen::Isometry3d& T_cw);
  bool recover_by_projection(FrameData& f, Eigen::Isometry3d& T_cw);
  bool track_last_frame(FrameData& f, Eigen::Isometry3d& T_cw);  // odometry.cpp
  std::vector<int> local_keyframes(const FrameData& f);
  int track_local_map(FrameData& f, Eigen::Isometry3d& T_cw);
  bool gate_by_source_motion(const EgoMotion& em, double timestamp, double dt, FrameData& f,
                             Eigen::Isometry3d& T_cw, int& inliers, bool implausible);
  int keep_agreeing(FrameData& f, const Eigen::Isometry3d& T_cw) const;
  bool plausible(const Eigen::Isometry3d& T_cw, const Eigen::Isometry3d& pred, double dt) const;
  bool track_from_prediction(FrameData& f, Eigen::Isometry3d& T_cw, const Eigen::Isometry3d& pred,
                             double dt, int& inliers);
  [[nodiscard]] RetryMark retry_mark() const {
    return {raised_visible.size(), raised_found.size(), ref_kf};
  }
  void settle_retry(const RetryMark& m, bool kept);
  bool retry_pose(FrameData& f, Eigen::Isometry3d& T_cw, int& inliers,
                  const Eigen::Isometry3d& pred, double dt, double within);
  TrackResult track(PreparedFrame pf);

  // ---- mapping.cpp: map points, fusion, local BA scheduling and applying
  void update_point_geometry(MapPoint& p);
  void update_point_descriptor(MapPoint& p);
  void replace_point(int from, int into);
  int fuse_into(int kf_id, std::vector<int> cands);  // by value: fusion edits the source lists
  void search_in_neighbors(int kf_id);
  void cull_recent_points(int current_kf);
  void erase_point(int pid);
  void schedule_local_ba(int kf_id);
  void launch_ba(const std::vector<int>& local, const std::vector<int>& fixed_ids,
                 const std::vector<int>& pts, bool async, const LocalBaParams& params);
  void apply_ba_if_due(bool force);

  // ---- keyframes.cpp: keyframe decision, insertion, covisibility, culling
  bool need_keyframe(const FrameData& f, int inliers) const;
  int add_keyframe(const FrameData& f, const Eigen::Isometry3d& T_cw, const FrameInput& in);
  int confirm_far_points(Keyframe& K);
  [[nodiscard]] int match_far_point(const Keyframe& K, const Eigen::Vector3d& x_k, int level,
                                    const std::uint8_t* desc) const;
  void update_connections(Keyframe& K);
  [[nodiscard]] std::vector<int> best_covisible(int kf_id, int n) const;
  [[nodiscard]] std::vector<int> keyframe_points(const std::vector<int>& kf_ids) const;
  [[nodiscard]] std::pair<int, int> redundancy(int id) const;
  void cull_keyframes(int current);
  void remove_keyframe(int id, int close, int redundant);

  // ---- segments.cpp: finish()'s merging of re-anchored segments and lost frames' poses
  [[nodiscard]] int segment_of(int kf) const;
  [[nodiscard]] int group_of(int kf) const;
  int localise_in_other_segments(const Keyframe& K, Eigen::Isometry3d& T_cw);
  void move_group(int group, const Eigen::Isometry3d& W, int into);
  void merge_segments();
  void interpolate_records(std::size_t i, std::size_t b);
  void interpolate_lost_frames();

  // ---- slam_frontend.cpp: finish()'s refinement, and each frame's pose in the world
  [[nodiscard]] Eigen::Isometry3d record_pose(const FrameRecord& r) const;
  void refine_frame_poses(const PoseOptimizerParams& params);
  void retrack_first_frames();
  void refine_points_from_frames();
  void smooth_frame_poses();
};

}  // namespace ds3d::slam
