// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/slam_frontend.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <future>
#include <limits>
#include <map>
#include <numeric>
#include <set>
#include <utility>

#include <opencv2/calib3d.hpp>

#include "ds3d/errors.hpp"

namespace ds3d::slam {
namespace {

using Clock = std::chrono::steady_clock;
double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}
// CPU time of the calling thread [ms] (POSIX).
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

constexpr int kThHigh = 100;  // ORB-SLAM2's ORBmatcher::TH_HIGH
constexpr int kThLow = 50;    // ORB-SLAM2's ORBmatcher::TH_LOW
constexpr int kGridCols = 64;
constexpr int kGridRows = 48;

using Descriptor = std::array<std::uint8_t, 32>;

// Observations of a map point that choose its descriptor (update_point_descriptor).
constexpr std::size_t kDescriptorWindow = 32;

Descriptor row_descriptor(const cv::Mat& d, int i) {
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

}  // namespace

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
  DS3D_CHECK(refine_rounds >= 0, f, ": refine_rounds must be >= 0 (got ", refine_rounds, ")");
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

struct SlamFrontend::Impl {
  FrontendConfig cfg;
  OrbExtractor extractor;
  StereoIntrinsics k;
  std::vector<double> scale;       // per level
  std::vector<double> inv_sigma2;  // per level
  std::shared_ptr<DynamicObjectSource> source;
  std::shared_ptr<DynamicFeatureMasker> masker;

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
  Eigen::Isometry3d velocity = Eigen::Isometry3d::Identity();
  int ref_kf = -1;
  int last_kf_frame = 0;  // frame_counter at the last keyframe
  int lost_count = 0;
  bool just_relocalized = false;

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

  std::optional<BaJob> ba_job;
  std::size_t ba_count = 0;
  double ba_ms = 0;
  double refine_ms = 0;  // thread CPU of finish()'s refinement

  Impl(FrontendConfig c, std::shared_ptr<DynamicObjectSource> s,
       std::shared_ptr<DynamicFeatureMasker> m)
      : cfg(std::move(c)),
        extractor((cfg.validate(), cfg.orb)),
        source(std::move(s)),
        masker(std::move(m)) {
    if (!source) source = std::make_shared<NoDynamicObjects>();
    if (!masker) masker = std::make_shared<NoDynamicMasker>();
    k = {cfg.camera.fx, cfg.camera.fy, cfg.camera.cx, cfg.camera.cy, cfg.bf};
    for (int l = 0; l < cfg.orb.num_levels; ++l) {
      scale.push_back(extractor.level_scale(l));
      inv_sigma2.push_back(1.0 / (scale.back() * scale.back()));
    }
  }

  ~Impl() {
    if (ba_job && ba_job->result.valid()) ba_job->result.wait();
  }

  // ---- helpers -------------------------------------------------------------------------------
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
    return o;
  }

  [[nodiscard]] int predict_level(const MapPoint& p, double dist) const {
    if (dist <= 0) return 0;
    const int l =
        static_cast<int>(std::ceil(std::log(p.max_dist / dist) / std::log(cfg.orb.scale_factor)));
    return std::clamp(l, 0, cfg.orb.num_levels - 1);
  }

  void update_point_geometry(MapPoint& p) {
    if (p.obs.empty()) return;
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    for (const auto& [kf, idx] : p.obs)
      n += (p.pos - keyframes[static_cast<std::size_t>(kf)].center()).normalized();
    p.normal = n.normalized();
    const auto ref = std::find_if(p.obs.begin(), p.obs.end(),
                                  [&](const auto& o) { return o.first == p.ref_kf; });
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
  void update_point_descriptor(MapPoint& p) {
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

  FrameData make_frame_data(const PreparedFrame& pf) const {
    FrameData f;
    const auto& feat = pf.features;
    f.close_depth = feat.close_depth;
    for (std::size_t i = 0; i < feat.size(); ++i) {
      if (!pf.dynamic.empty() && pf.dynamic[i] != 0) continue;
      f.uv.push_back(feat.undistorted[i]);
      f.depth.push_back(feat.depth[i]);
      f.octave.push_back(feat.keypoints[i].octave);
    }
    f.desc.create(static_cast<int>(f.uv.size()), 32, CV_8U);
    int r = 0;
    for (std::size_t i = 0; i < feat.size(); ++i) {
      if (!pf.dynamic.empty() && pf.dynamic[i] != 0) continue;
      feat.descriptors.row(static_cast<int>(i)).copyTo(f.desc.row(r++));
    }
    f.points.assign(f.uv.size(), -1);
    f.grid.build(f.uv, cfg.camera.width, cfg.camera.height);
    return f;
  }

  // ---- matching ------------------------------------------------------------------------------
  // Projects `candidates` into frame `f` at pose T_cw and assigns each to the best unmatched
  // keypoint within `radius_px` × level scale (ORB-SLAM2's SearchByProjection). Returns matches.
  int search_by_projection(FrameData& f, const Eigen::Isometry3d& T_cw,
                           const std::vector<int>& candidates, double th, bool local_map,
                           std::size_t stamp) {
    const Eigen::Vector3d Ow = T_cw.inverse().translation();
    int matches = 0;
    for (const int pid : candidates) {
      MapPoint& p = points[static_cast<std::size_t>(pid)];
      if (p.bad || p.last_frame_seen == stamp) continue;
      const Eigen::Vector3d pc = T_cw * p.pos;
      if (pc.z() <= 1e-3) continue;
      const double u = k.fx * pc.x() / pc.z() + k.cx;
      const double v = k.fy * pc.y() / pc.z() + k.cy;
      if (!cfg.camera.in_image(u, v)) continue;
      const Eigen::Vector3d po = p.pos - Ow;
      const double dist = po.norm();
      double radius = th;
      int level;
      if (local_map) {
        if (dist < 0.8 * p.min_dist || dist > 1.2 * p.max_dist) continue;
        const double view_cos = po.dot(p.normal) / dist;
        if (view_cos < 0.5) continue;
        level = predict_level(p, dist);
        radius *= (view_cos > 0.998 ? 2.5 : 4.0);
        ++p.visible;
      } else {
        level = predict_level(p, dist);
      }
      radius *= scale[static_cast<std::size_t>(level)];
      const double ur = u - k.bf / pc.z();
      int best = 256;
      int second = 256;
      int best_idx = -1;
      int best_level = -1;
      int second_level = -1;
      f.grid.for_each_in(u, v, radius, [&](int i) {
        const auto si = static_cast<std::size_t>(i);
        if (f.points[si] >= 0) return;
        const int lv = f.octave[si];
        if (lv < level - 1 || lv > level + 1) return;
        const double du = f.uv[si].x() - u;
        const double dv = f.uv[si].y() - v;
        if (du * du + dv * dv > radius * radius) return;
        if (f.depth[si] > 0 && std::abs(f.u_right(si, k.bf) - ur) > radius) return;
        const int d = descriptor_distance(p.desc.data(), f.desc.ptr<std::uint8_t>(i));
        if (d < best) {
          second = best;
          second_level = best_level;
          best = d;
          best_idx = i;
          best_level = lv;
        } else if (d < second) {
          second = d;
          second_level = lv;
        }
      });
      if (best_idx < 0 || best > kThHigh) continue;
      if (local_map && best_level == second_level && best > 0.8 * second) continue;
      f.points[static_cast<std::size_t>(best_idx)] = pid;
      p.last_frame_seen = stamp;
      ++matches;
    }
    return matches;
  }

  // Brute-force descriptor matching of keyframe points against frame features (ratio 0.7),
  // one-to-one. Used for the reference-keyframe fallback and relocalisation.
  int match_keyframe(const Keyframe& kf, FrameData& f) const {
    std::vector<int> best_for_kp(f.size(), -1);
    std::vector<int> best_dist(f.size(), 256);
    for (std::size_t j = 0; j < kf.data.size(); ++j) {
      const int pid = kf.data.points[j];
      if (pid < 0 || points[static_cast<std::size_t>(pid)].bad) continue;
      const std::uint8_t* dj = kf.data.desc.ptr<std::uint8_t>(static_cast<int>(j));
      int b1 = 256;
      int b2 = 256;
      int bi = -1;
      for (std::size_t i = 0; i < f.size(); ++i) {
        const int d = descriptor_distance(dj, f.desc.ptr<std::uint8_t>(static_cast<int>(i)));
        if (d < b1) {
          b2 = b1;
          b1 = d;
          bi = static_cast<int>(i);
        } else if (d < b2) {
          b2 = d;
        }
      }
      if (bi < 0 || b1 > kThLow || b1 >= 0.7 * b2) continue;
      const auto ui = static_cast<std::size_t>(bi);
      if (b1 < best_dist[ui]) {
        best_dist[ui] = b1;
        best_for_kp[ui] = pid;
      }
    }
    int n = 0;
    std::fill(f.points.begin(), f.points.end(), -1);
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (best_for_kp[i] >= 0) {
        f.points[i] = best_for_kp[i];
        ++n;
      }
    }
    return n;
  }

  // Pose-only optimisation over the frame's current matches; drops outlier matches.
  int optimize_frame(FrameData& f, Eigen::Isometry3d& T_cw) const {
    std::vector<Eigen::Vector3d> pw;
    std::vector<Observation> obs;
    std::vector<std::size_t> idx;
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (f.points[i] < 0) continue;
      pw.push_back(points[static_cast<std::size_t>(f.points[i])].pos);
      obs.push_back(observation(f, i));
      idx.push_back(i);
    }
    if (pw.size() < 3) return 0;
    const auto r = optimize_pose(k, T_cw, pw, obs, cfg.pose);
    T_cw = r.T_cam_world;
    for (std::size_t j = 0; j < idx.size(); ++j) {
      if (r.inlier[j] == 0) f.points[idx[j]] = -1;
    }
    return r.num_inliers;
  }

  // PnP-RANSAC on the current 3-D/2-D matches (pixels are undistorted, so no distortion).
  bool pnp_ransac(const FrameData& f, Eigen::Isometry3d& T_cw) const {
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    for (std::size_t i = 0; i < f.size(); ++i) {
      if (f.points[i] < 0) continue;
      const Eigen::Vector3d& p = points[static_cast<std::size_t>(f.points[i])].pos;
      obj.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                       static_cast<float>(p.z()));
      img.emplace_back(f.uv[i].x(), f.uv[i].y());
    }
    if (obj.size() < 15) return false;
    const cv::Matx33d K(k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1);
    cv::Mat rvec;
    cv::Mat tvec;
    std::vector<int> inliers;
    // Fixed RNG seed inside OpenCV's RANSAC (cv::theRNG is per thread): seed it for determinism.
    cv::theRNG().state = 0x9E3779B97F4A7C15ULL;
    const bool ok = cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false, 200, 4.0F,
                                       0.99, inliers, cv::SOLVEPNP_EPNP);
    if (!ok || inliers.size() < 15) return false;
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) T.linear()(r, c) = R.at<double>(r, c);
      T.translation()(r) = tvec.at<double>(r);
    }
    if (!T.matrix().allFinite()) return false;
    T_cw = T;
    return true;
  }

  // ---- tracking steps ------------------------------------------------------------------------
  bool track_motion_model(FrameData& f, Eigen::Isometry3d& T_cw) {
    std::vector<int> cand;
    for (std::size_t i = 0; i < last.size(); ++i) {
      if (last.points[i] >= 0) cand.push_back(last.points[i]);
    }
    const Eigen::Isometry3d pred = velocity * last_T_cw;
    T_cw = pred;
    std::fill(f.points.begin(), f.points.end(), -1);
    // ORB-SLAM2 uses a 15-pixel window for monocular and RGB-D input.
    int n = search_by_projection(f, T_cw, cand, 15.0, false, frame_counter);
    if (n < 20) {
      std::fill(f.points.begin(), f.points.end(), -1);
      for (const int pid : cand)
        points[static_cast<std::size_t>(pid)].last_frame_seen =
            std::numeric_limits<std::size_t>::max();
      n = search_by_projection(f, T_cw, cand, 30.0, false, frame_counter);
    }
    if (n < 20) return false;
    return optimize_frame(f, T_cw) >= 10;
  }

  bool track_keyframe(const Keyframe& kf, FrameData& f, Eigen::Isometry3d& T_cw, int min_inliers) {
    if (match_keyframe(kf, f) < 15) return false;
    Eigen::Isometry3d T = T_cw;
    const FrameData saved = f;
    if (optimize_frame(f, T) >= min_inliers) {
      T_cw = T;
      return true;
    }
    f = saved;
    if (!pnp_ransac(f, T)) return false;
    if (optimize_frame(f, T) < min_inliers) return false;
    T_cw = T;
    return true;
  }

  bool relocalize(FrameData& f, Eigen::Isometry3d& T_cw) {
    int tried = 0;
    for (int id = static_cast<int>(keyframes.size()) - 1;
         id >= 0 && tried < cfg.relocalisation_candidates; --id) {
      if (keyframes[static_cast<std::size_t>(id)].bad) continue;
      ++tried;
      Eigen::Isometry3d T = keyframes[static_cast<std::size_t>(id)].T_cw;
      if (track_keyframe(keyframes[static_cast<std::size_t>(id)], f, T, 50)) {
        T_cw = T;
        ref_kf = id;
        return true;
      }
      std::fill(f.points.begin(), f.points.end(), -1);
    }
    return false;
  }

  // Local map: keyframes sharing points with the frame plus their best covisible neighbours.
  std::vector<int> local_keyframes(const FrameData& f) {
    std::map<int, int> counter;
    for (const int pid : f.points) {
      if (pid < 0) continue;
      for (const auto& [kf, idx] : points[static_cast<std::size_t>(pid)].obs) ++counter[kf];
    }
    if (counter.empty()) return {};
    std::vector<std::pair<int, int>> sorted(counter.begin(), counter.end());
    std::stable_sort(sorted.begin(), sorted.end(),
                     [](const auto& a, const auto& b) { return a.second > b.second; });
    ref_kf = sorted.front().first;
    std::vector<int> out;
    std::set<int> in;
    for (const auto& [kf, c] : sorted) {
      if (out.size() >= 80) break;
      out.push_back(kf);
      in.insert(kf);
    }
    const std::size_t direct = out.size();
    for (std::size_t i = 0; i < direct && out.size() < 80; ++i) {
      const auto& cov = keyframes[static_cast<std::size_t>(out[i])].covis;
      std::vector<std::pair<int, int>> nb(cov.begin(), cov.end());
      std::stable_sort(nb.begin(), nb.end(),
                       [](const auto& a, const auto& b) { return a.second > b.second; });
      int added = 0;
      for (const auto& [id, w] : nb) {
        if (added >= 10 || out.size() >= 80) break;
        if (in.insert(id).second) {
          out.push_back(id);
          ++added;
        }
      }
    }
    return out;
  }

  int track_local_map(FrameData& f, Eigen::Isometry3d& T_cw) {
    const auto kfs = local_keyframes(f);
    const std::size_t stamp = frame_counter;
    std::vector<int> cand;
    for (const int pid : f.points) {
      if (pid >= 0) points[static_cast<std::size_t>(pid)].last_frame_seen = stamp;
    }
    for (const int kf : kfs) {
      for (const int pid : keyframes[static_cast<std::size_t>(kf)].data.points) {
        if (pid < 0) continue;
        MapPoint& p = points[static_cast<std::size_t>(pid)];
        if (p.bad || p.local_stamp == stamp) continue;
        p.local_stamp = stamp;
        cand.push_back(pid);
      }
    }
    // ORB-SLAM2's RGB-D search radius factor: 3, or 5 right after relocalisation.
    search_by_projection(f, T_cw, cand, just_relocalized ? 5.0 : 3.0, true, stamp);
    const int inliers = optimize_frame(f, T_cw);
    for (const int pid : f.points) {
      if (pid >= 0) ++points[static_cast<std::size_t>(pid)].found;
    }
    return inliers;
  }

  // ---- mapping -------------------------------------------------------------------------------
  bool need_keyframe(const FrameData& f, int inliers) const {
    const int n_kf = static_cast<int>(live_keyframes);
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

  int add_keyframe(const FrameData& f, const Eigen::Isometry3d& T_cw, const FrameInput& in) {
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
      const double z = K.data.depth[i];
      const Eigen::Vector3d pc((K.data.uv[i].x() - k.cx) / k.fx * z,
                               (K.data.uv[i].y() - k.cy) / k.fy * z, z);
      p.pos = T_wc * pc;
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
    update_connections(K);
    if (cfg.fuse_neighbors) search_in_neighbors(K.id);
    cull_recent_points(K.id);
    last_kf_frame = static_cast<int>(frame_counter);
    ref_kf = K.id;
    return K.id;
  }

  // Covisibility edges of keyframe K from its current points (ORB-SLAM2's UpdateConnections:
  // weight = shared points, kept when >= 15, or the best one). Stale edges of K are replaced.
  void update_connections(Keyframe& K) {
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
  [[nodiscard]] std::vector<int> best_covisible(int kf_id, int n) const {
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

  // Merges map point `from` into `into` (ORB-SLAM2's MapPoint::Replace): every keyframe that saw
  // `from` now sees `into` (or nothing, when it already sees `into` at another keypoint).
  void replace_point(int from, int into) {
    if (from == into) return;
    MapPoint& a = points[static_cast<std::size_t>(from)];
    MapPoint& b = points[static_cast<std::size_t>(into)];
    for (const auto& [kf, idx] : a.obs) {
      auto& slot =
          keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(idx)];
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
  int fuse_into(int kf_id, std::vector<int> cands) {  // by value: fusion edits the source lists
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
  void search_in_neighbors(int kf_id) {
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
    std::vector<int> cands;
    std::set<int> cand_set;
    for (const int id : targets) {
      for (const int pid : keyframes[static_cast<std::size_t>(id)].data.points) {
        if (pid >= 0 && !points[static_cast<std::size_t>(pid)].bad && cand_set.insert(pid).second)
          cands.push_back(pid);
      }
    }
    fuse_into(kf_id, cands);
    update_connections(keyframes[static_cast<std::size_t>(kf_id)]);
  }

  // ORB-SLAM2's MapPointCulling: recent points must be found in >= 25 % of the frames that
  // should have seen them, and have an observation weight > 3 (two keyframes with depth) once
  // two keyframes have passed.
  void cull_recent_points(int current_kf) {
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

  void erase_point(int pid) {
    MapPoint& p = points[static_cast<std::size_t>(pid)];
    p.bad = true;
    for (const auto& [kf, idx] : p.obs)
      keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(idx)] = -1;
    p.obs.clear();
  }

  void schedule_local_ba(int kf_id) {
    if (!cfg.enable_local_ba) return;
    // A keyframe inserted before the previous BA was due (gap or weak-tracking criterion) must not
    // discard that BA: apply it now (waits for the mapping thread; still deterministic).
    apply_ba_if_due(true);
    const Keyframe& K = keyframes[static_cast<std::size_t>(kf_id)];
    std::vector<std::pair<int, int>> nb(K.covis.begin(), K.covis.end());
    std::stable_sort(nb.begin(), nb.end(),
                     [](const auto& a, const auto& b) { return a.second > b.second; });
    std::vector<int> local{kf_id};
    for (const auto& [id, w] : nb) {
      if (static_cast<int>(local.size()) >= cfg.local_window) break;
      local.push_back(id);
    }
    std::set<int> local_set(local.begin(), local.end());
    std::vector<int> pts;
    std::set<int> pts_set;
    for (const int id : local) {
      for (const int pid : keyframes[static_cast<std::size_t>(id)].data.points) {
        if (pid >= 0 && !points[static_cast<std::size_t>(pid)].bad && pts_set.insert(pid).second)
          pts.push_back(pid);
      }
    }
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
  void launch_ba(const std::vector<int>& local, const std::vector<int>& fixed_ids,
                 const std::vector<int>& pts, bool async, const LocalBaParams& params) {
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
      const auto oldest =
          std::min_element(job.kf_ids.begin(), job.kf_ids.end()) - job.kf_ids.begin();
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
        o.obs = observation(keyframes[static_cast<std::size_t>(kf)].data,
                            static_cast<std::size_t>(idx));
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

  void apply_ba_if_due(bool force) {
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
      keyframes[static_cast<std::size_t>(kf)].data.points[static_cast<std::size_t>(it->second)] =
          -1;
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

  // ---- keyframe culling (ORB-SLAM §VI-E, Mur-Artal et al. 2015; ORB-SLAM2's KeyFrameCulling) --
  // Close map points of keyframe `id` (depth in (0, ThDepth]) and how many of them are seen by
  // >= keyframe_redundant_observers other keyframes at the same or a finer scale (octave <= its
  // octave + 1). Like ORB-SLAM2, only points whose observation weight (depth counts twice)
  // exceeds the observer count are tested.
  [[nodiscard]] std::pair<int, int> redundancy(int id) const {
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
  void cull_keyframes(int current) {
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
  void remove_keyframe(int id, int close, int redundant) {
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
    for (const auto& [other, w] : K.covis)
      keyframes[static_cast<std::size_t>(other)].covis.erase(id);
    K.covis.clear();
    K.bad = true;
    K.data = FrameData{};  // bounded memory: nothing reads a culled keyframe's features
    --live_keyframes;
    culled.push_back({K.frame_index, K.timestamp, frame_counter, close, redundant});
  }

  // Re-optimises each tracked non-keyframe pose against the final map points it was matched to
  // (pose-only, as in tracking), starting from its pose relative to its reference keyframe. A
  // frame keeps its old pose when too few matches survive.
  void refine_frame_poses(const PoseOptimizerParams& params) {
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

  // Structure-only step over every map point with all its observations, the keyframes' and the
  // (refined) frames', every pose fixed: a few Gauss-Newton iterations on the 3-D position with
  // Huber weights, then a χ² test; a point keeps its position unless at least two observations
  // pass and the solution is finite. Points are independent, so this is O(observations).
  void refine_points_from_frames() {
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
      const Eigen::Isometry3d T_cw = r.T_c_ref * keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw;
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
        double res[3];
        const int d = reprojection_residual(k, ob.T_cw, x, ob.o, res, nullptr, nullptr);
        if (d == 0) continue;
        const double chi2 = Eigen::Map<const Eigen::VectorXd>(res, d).squaredNorm();
        inliers += chi2 <= (d == 3 ? cfg.local_ba.chi2_stereo : cfg.local_ba.chi2_mono) ? 1 : 0;
      }
      if (inliers >= 2 && x.allFinite()) p.pos = x;
    }
  }

  // ---- per frame -----------------------------------------------------------------------------
  TrackResult track(PreparedFrame pf) {
    const auto t0 = Clock::now();
    const double c0 = thread_cpu_ms();
    const FrameInput& in = pf.input;
    DS3D_CHECK(std::isfinite(in.timestamp),
               "ds3d::slam::SlamFrontend::track: timestamp must be finite (got ", in.timestamp,
               ")");
    DS3D_CHECK(in.timestamp >= last_timestamp,
               "ds3d::slam::SlamFrontend::track: time went backwards: frame ", in.index,
               " has timestamp ", in.timestamp, " < previous ", last_timestamp);
    last_timestamp = in.timestamp;
    apply_ba_if_due(false);

    TrackResult res;
    res.index = in.index;
    res.timestamp = in.timestamp;
    res.num_features = static_cast<int>(pf.features.size());
    res.keypoints.reserve(pf.features.size());
    for (const auto& kp : pf.features.keypoints) res.keypoints.push_back(kp.pt);
    res.keypoint_status.assign(pf.features.size(), KeypointStatus::kUnmatched);
    std::vector<std::size_t> kept;  // feature index of each FrameData entry
    for (std::size_t i = 0; i < pf.features.size(); ++i) {
      if (!pf.dynamic.empty() && pf.dynamic[i] != 0) {
        res.keypoint_status[i] = KeypointStatus::kDynamic;
        ++res.num_dynamic;
      } else {
        kept.push_back(i);
      }
    }
    FrameData f = make_frame_data(pf);
    int n_depth = 0;
    for (const float d : f.depth) n_depth += d > 0 ? 1 : 0;

    Eigen::Isometry3d T_cw = last_T_cw;
    bool ok = false;
    int inliers = 0;
    bool new_kf = false;
    if (!initialized) {
      if (n_depth >= cfg.min_init_points) {
        initialized = true;
        T_cw = Eigen::Isometry3d::Identity();
        add_keyframe(f, T_cw, in);
        f = keyframes.back().data;
        res.state = TrackState::kInitialized;
        ok = true;
        new_kf = true;
        for (const int pid : f.points) inliers += pid >= 0 ? 1 : 0;
      } else {
        res.state = TrackState::kNotInitialized;
      }
    } else {
      bool relocalized = false;
      if (last_tracked && velocity_valid) ok = track_motion_model(f, T_cw);
      if (!ok && last_tracked) {
        T_cw = last_T_cw;
        ok = track_keyframe(keyframes[static_cast<std::size_t>(ref_kf)], f, T_cw, 10);
      }
      if (!ok) {
        std::fill(f.points.begin(), f.points.end(), -1);
        ok = relocalize(f, T_cw);
        relocalized = ok;
      }
      if (ok) {
        just_relocalized = relocalized;
        inliers = track_local_map(f, T_cw);
        ok = inliers >=
             (relocalized ? std::max(50, cfg.min_tracked_inliers) : cfg.min_tracked_inliers);
      }
      if (ok) {
        res.state = relocalized ? TrackState::kRelocalized : TrackState::kTracking;
        lost_count = 0;
        velocity = T_cw * last_T_cw.inverse();
        velocity_valid = last_tracked;
        if (need_keyframe(f, inliers)) {
          const int id = add_keyframe(f, T_cw, in);
          f = keyframes[static_cast<std::size_t>(id)].data;
          schedule_local_ba(id);
          if (!cfg.enable_local_ba && cfg.cull_keyframes) cull_keyframes(id);
          new_kf = true;
        }
      } else {
        ++lost_count;
        T_cw = last_T_cw;
        velocity_valid = false;
        res.state = TrackState::kLost;
        std::fill(f.points.begin(), f.points.end(), -1);
        if (cfg.reanchor_after_lost > 0 && lost_count >= cfg.reanchor_after_lost &&
            n_depth >= cfg.min_init_points) {
          // A new map segment at the last known pose: keeps a trajectory going (with a jump
          // bounded by the motion during the outage) instead of staying lost for ever.
          const int id = add_keyframe(f, T_cw, in);
          f = keyframes[static_cast<std::size_t>(id)].data;
          res.state = TrackState::kReanchored;
          lost_count = 0;
          new_kf = true;
          ok = true;
        }
      }
    }
    res.tracked = res.state == TrackState::kInitialized || res.state == TrackState::kTracking ||
                  res.state == TrackState::kRelocalized;
    res.keyframe = new_kf;
    res.num_inliers = inliers;
    for (std::size_t j = 0; j < f.size(); ++j) {
      if (f.points[j] >= 0) res.keypoint_status[kept[j]] = KeypointStatus::kTracked;
    }
    res.T_world_cam = T_cw.inverse();

    FrameRecord rec{in.index, in.timestamp, ref_kf, Eigen::Isometry3d::Identity(),
                    T_cw,     res.tracked,  false,  {}};
    if (ref_kf >= 0)
      rec.T_c_ref = T_cw * keyframes[static_cast<std::size_t>(ref_kf)].T_cw.inverse();
    records.push_back(rec);

    if (cfg.refine_frame_poses && res.tracked && !new_kf) {
      auto& m = records.back().matches;
      for (std::size_t j = 0; j < f.size(); ++j) {
        if (f.points[j] >= 0) m.emplace_back(f.points[j], observation(f, j));
      }
    }
    records.back().keyframe = new_kf;
    last = std::move(f);
    last_T_cw = T_cw;
    last_tracked = ok;
    have_last = true;
    ++frame_counter;
    res.times = pf.times;
    res.times.track_ms = ms_since(t0);
    res.times.track_cpu_ms = thread_cpu_ms() - c0;
    return res;
  }
};

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
  pf.features = impl_->extractor.extract(frame.rgb, frame.depth, impl_->cfg.camera);
  pf.input = std::move(frame);
  pf.times.extract_ms = ms_since(t0);
  pf.times.extract_cpu_ms = thread_cpu_ms() - c0;
  return pf;
}

void SlamFrontend::detect_dynamic(PreparedFrame& frame) {
  const auto t0 = Clock::now();
  frame.objects = impl_->source->detect(frame.input, impl_->cfg.camera);
  frame.times.detect_ms = ms_since(t0);
}

void SlamFrontend::filter_dynamic(PreparedFrame& frame) {
  const auto t0 = Clock::now();
  frame.dynamic =
      impl_->masker->mask(frame.input, impl_->cfg.camera, frame.features, frame.objects);
  DS3D_CHECK(frame.dynamic.size() == frame.features.size(),
             "ds3d::slam::SlamFrontend: dynamic filter '", impl_->masker->name(), "' returned ",
             frame.dynamic.size(), " flags for ", frame.features.size(), " keypoints");
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
  FrameInput in;
  in.index = frame.index;
  in.timestamp = frame.timestamp;
  in.rgb = frame.rgb;
  in.depth = frame.depth;
  PreparedFrame pf = extract(std::move(in));
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
    for (auto& r : impl_->records) {
      r.matches.clear();
      r.matches.shrink_to_fit();
    }
    impl_->refine_ms += thread_cpu_ms() - c0;
  }
}

std::vector<FramePose> SlamFrontend::trajectory() const {
  std::vector<FramePose> out;
  out.reserve(impl_->records.size());
  for (const auto& r : impl_->records) {
    FramePose p;
    p.index = r.index;
    p.timestamp = r.timestamp;
    p.tracked = r.tracked;
    const Eigen::Isometry3d T_cw =
        r.ref_kf >= 0 ? Eigen::Isometry3d(r.T_c_ref *
                                          impl_->keyframes[static_cast<std::size_t>(r.ref_kf)].T_cw)
                      : r.T_cw_online;
    p.T_world_cam = T_cw.inverse();
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
const std::vector<CulledKeyframe>& SlamFrontend::culled_keyframes() const noexcept {
  return impl_->culled;
}
std::size_t SlamFrontend::num_local_ba() const noexcept { return impl_->ba_count; }
double SlamFrontend::local_ba_ms() const noexcept { return impl_->ba_ms; }
double SlamFrontend::refine_ms() const noexcept { return impl_->refine_ms; }
const DynamicObjectSource& SlamFrontend::dynamic_source() const noexcept { return *impl_->source; }
const DynamicFeatureMasker& SlamFrontend::dynamic_masker() const noexcept { return *impl_->masker; }

}  // namespace ds3d::slam
