// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// HtxSource and keep_anchored_foreground.
#include "ds3d/slam/dynamic/htx_source.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <sstream>
#include <utility>

#include "ds3d/detail/kdtree.hpp"
#include "ds3d/dynamic/dynamic_filter.hpp"
#include "ds3d/errors.hpp"
#include "dynamic_impl.hpp"

namespace ds3d::slam {

using impl::finite_rows_of;

void HtxSourceParams::validate() const {
  preprocess.validate();
  input.validate();
  DS3D_CHECK(std::isfinite(min_score) && min_score >= 0.0F && min_score <= 1.0F,
             "ds3d::slam::HtxSourceParams: min_score must be in [0, 1] (got ", min_score, ")");
  DS3D_CHECK(detect_every >= 1, "ds3d::slam::HtxSourceParams: detect_every must be >= 1 (got ",
             detect_every, ")");
  DS3D_CHECK(num_threads >= 0, "ds3d::slam::HtxSourceParams: num_threads must be >= 0 (got ",
             num_threads, ")");
  DS3D_CHECK(box_uncertainty >= 0.0F,
             "ds3d::slam::HtxSourceParams: box_uncertainty must be >= 0 or +inf (got ",
             box_uncertainty, ")");
  DS3D_CHECK(foreground_min_prob > 0.0F && foreground_min_prob < 1.0F,
             "ds3d::slam::HtxSourceParams: foreground_min_prob must be in (0, 1) (got ",
             foreground_min_prob, ")");
  DS3D_CHECK(std::isfinite(foreground_radius) && foreground_radius > 0.0F,
             "ds3d::slam::HtxSourceParams: foreground_radius must be finite and > 0 (got ",
             foreground_radius, ")");
  DS3D_CHECK(hold_frames >= 0, "ds3d::slam::HtxSourceParams: hold_frames must be >= 0 (got ",
             hold_frames, ")");
  DS3D_CHECK(hold_min_points >= 1,
             "ds3d::slam::HtxSourceParams: hold_min_points must be >= 1 (got ", hold_min_points,
             ")");
  DS3D_CHECK(segment_frames >= 0, "ds3d::slam::HtxSourceParams: segment_frames must be >= 0 (got ",
             segment_frames, ")");
  DS3D_CHECK(std::isfinite(hold_seconds) && hold_seconds >= 0.0,
             "ds3d::slam::HtxSourceParams: hold_seconds must be finite and >= 0 (got ",
             hold_seconds, ")");
}

namespace {

std::vector<std::int32_t> class_labels(const std::vector<std::string>& wanted,
                                       const std::vector<std::string>& known) {
  std::vector<std::int32_t> out;
  for (const std::string& w : wanted) {
    const auto it = std::find(known.begin(), known.end(), w);
    if (it == known.end()) {
      std::ostringstream names;
      for (std::size_t i = 0; i < known.size(); ++i) names << (i > 0 ? ", " : "") << known[i];
      throw InvalidArgument(
          detail::concat("ds3d::slam::HtxSource: class '", w,
                         "' is not a class of the detector (classes: ", names.str(), ")"));
    }
    out.push_back(static_cast<std::int32_t>(it - known.begin()));
  }
  return out;
}

double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Frame index mixed into the draw's seed (SplitMix64 finaliser), so consecutive frames get
// unrelated draws while the same frame always gets the same one.
std::uint64_t mix_seed(std::uint64_t seed, std::size_t index) {
  std::uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (static_cast<std::uint64_t>(index) + 1U);
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31U);
}

// Whether a box centred at `centre` continues `kept`, centred at `kept_centre` in the same frame:
// the centre lies within half kept's largest horizontal size (the detector reported the object
// again at about the same place; HtxSourceParams::hold_frames).
bool continues(const Box3& kept, const Eigen::Vector3f& kept_centre,
               const Eigen::Vector3f& centre) {
  return (centre - kept_centre).norm() < 0.5F * std::max(kept.size.x(), kept.size.y());
}

}  // namespace

std::size_t keep_anchored_foreground(DynamicObjects& objects, float margin) {
  constexpr const char* kFn = "ds3d::slam::keep_anchored_foreground";
  DS3D_CHECK(margin >= 0.0F, kFn, ": margin must be >= 0 or +inf (got ", margin, ")");
  Segmentation& seg = objects.segmentation;
  DS3D_CHECK(std::isfinite(seg.foreground_radius) && seg.foreground_radius > 0.0F, kFn,
             ": objects.foreground_radius must be finite and > 0 (got ", seg.foreground_radius,
             ")");
  Points3f& fg = seg.foreground_points;
  const std::vector<std::uint32_t> rows = finite_rows_of(fg);  // tree index -> row
  if (rows.empty()) return 0;
  // Seeds: the points inside a box's solid grown by the margin (tree indices).
  std::vector<std::uint8_t> anchored(rows.size(), 0);
  std::vector<std::uint32_t> queue;
  for (const Eigen::Matrix<float, 8, 3>& corners : objects.boxes_3d) {
    const std::optional<SolidBox> solid =
        solid_from_corners(corners, std::isfinite(margin) ? margin : 0.0F);
    if (!solid) continue;
    for (std::uint32_t t = 0; t < rows.size(); ++t) {
      const Eigen::Vector3f p = fg.row(rows[t]).transpose();
      if (anchored[t] != 0U || !(p.z() > 0.0F)) continue;
      if (solid->contains(p, p / p.z(), 0.0F)) {
        anchored[t] = 1;
        queue.push_back(t);
      }
    }
  }
  if (queue.size() < rows.size() && !queue.empty()) {
    // Breadth-first along the foreground: every point within the radius of an anchored one.
    const detail::KdTreeCloudAdaptor<Points3f> adaptor{fg, &rows};
    detail::KdTree3f<Points3f> tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree.buildIndex();
    const double r2 = static_cast<double>(seg.foreground_radius) * seg.foreground_radius;
    const auto reach = [&](std::uint32_t t) {  // never counted: the search visits them all
      if (anchored[t] == 0U) {
        anchored[t] = 1;
        queue.push_back(t);
      }
      return false;
    };
    for (std::size_t head = 0; head < queue.size(); ++head) {
      const Eigen::Vector3f q = fg.row(rows[queue[head]]).transpose();
      detail::CountingRadiusResultSet<decltype(reach)> rs(r2, 1, reach);
      tree.findNeighbors(rs, q.data(), nanoflann::SearchParams());
    }
  }
  const std::size_t moved = rows.size() - queue.size();
  if (moved == 0) return 0;
  // Row order kept on both sides; non-finite rows stay with the foreground (ignored there).
  std::vector<std::uint8_t> stays(static_cast<std::size_t>(fg.rows()), 1);
  for (std::uint32_t t = 0; t < rows.size(); ++t) stays[rows[t]] = anchored[t];
  Points3f kept(fg.rows() - static_cast<Eigen::Index>(moved), 3);
  Points3f& bg = seg.background_points;
  Eigen::Index b = bg.rows();
  bg.conservativeResize(b + static_cast<Eigen::Index>(moved), 3);
  Eigen::Index a = 0;
  for (Eigen::Index r = 0; r < fg.rows(); ++r) {
    (stays[static_cast<std::size_t>(r)] != 0U ? kept.row(a++) : bg.row(b++)) = fg.row(r);
  }
  fg = std::move(kept);
  return moved;
}

HtxSource::HtxSource(std::shared_ptr<const SparseDetector> detector, HtxSourceParams params)
    : params_(std::move(params)), R_up_cam_(upright_rotation(Eigen::Vector3d(0.0, -1.0, 0.0))) {
  DS3D_CHECK(detector != nullptr, "ds3d::slam::HtxSource: detector must not be null");
  params_.validate();
  labels_ = class_labels(params_.classes, detector->config().class_names);
  const int threads = params_.num_threads;
  run_ = [detector, threads](Eigen::Ref<const Points3f> xyz) {
    DetectOptions opt;
    opt.num_threads = threads;
    opt.part_logits = true;
    return detector->run(xyz, opt);
  };
  detect_ = [detector = std::move(detector), threads](Eigen::Ref<const Points3f> xyz) {
    return detector->detect(xyz, threads);
  };
}

HtxSource::HtxSource(DetectFn detect, std::vector<std::string> class_names, HtxSourceParams params)
    : detect_(std::move(detect)),
      params_(std::move(params)),
      R_up_cam_(upright_rotation(Eigen::Vector3d(0.0, -1.0, 0.0))) {
  DS3D_CHECK(static_cast<bool>(detect_), "ds3d::slam::HtxSource: detect must not be empty");
  params_.validate();
  labels_ = class_labels(params_.classes, class_names);
}

namespace {

// The preprocess stage of HtxSource::detect: the frame's depth image as a cloud (camera frame).
PreprocessResult preprocess_depth(const FrameInput& frame, const PinholeCamera& camera,
                                  const HtxSourceParams& params, PixelRayCache& rays) {
  PreprocessParams pp = params.preprocess;
  pp.num_threads = params.num_threads;
  return impl::preprocess_depth(frame, camera, pp, rays);
}

// Whether the frame's depth image is one HtxSource can read: CV_16UC1 of the camera's size.
bool depth_fits(const FrameInput& frame, const PinholeCamera& camera) {
  return frame.depth.type() == CV_16UC1 && frame.depth.cols == camera.width &&
         frame.depth.rows == camera.height;
}

// The gravity-alignment stage: with this frame's floor, R_up_cam from its normal, and the floor
// as the objects' segment_plane (`segment`) and support_plane (report_floor). Returns whether
// the floor was used.
bool align_with_floor(const PreprocessResult& pre, const HtxSourceParams& params, bool segment,
                      Eigen::Matrix3f& R_up_cam, DynamicObjects& objects) {
  const std::optional<Eigen::Vector3d> up = impl::usable_floor(pre);
  if (!up) return false;
  R_up_cam = upright_rotation(*up);
  const Eigen::Vector4f ground = impl::floor_plane(pre, *up);
  // The floor preprocess removed (camera frame): the segmentation gives it no label.
  if (segment) objects.segmentation.segment_plane = ground;
  // This frame's floor: the masker keeps the keypoints on it static.
  if (params.report_floor) objects.support_plane = ground;
  return true;
}

}  // namespace

struct HtxSource::Network {
  DetectorInput in;
  DetectorOutput out;     // boxes, and part logits when segmenting
  double input_ms = 0;    // make_detector_input
  double network_ms = 0;  // the forward pass
};

struct HtxSource::Prepared final : PreparedDetection {
  std::size_t index = 0;  // the frame's
  double timestamp = 0;
  PreprocessResult pre;
  double preprocess_ms = 0;
  std::optional<Network> net;  // when pre's floor fixed the upright frame
};

HtxSource::Prepared HtxSource::preprocess_frame(const FrameInput& frame,
                                                const PinholeCamera& camera,
                                                PixelRayCache& rays) const {
  const auto t0 = std::chrono::steady_clock::now();
  Prepared p;
  p.index = frame.index;
  p.timestamp = frame.timestamp;
  p.pre = preprocess_depth(frame, camera, params_, rays);
  p.preprocess_ms = ms_since(t0);
  return p;
}

HtxSource::Network HtxSource::run_network(const PreprocessResult& pre,
                                          const Eigen::Matrix3f& R_up_cam,
                                          std::size_t index) const {
  const auto t0 = std::chrono::steady_clock::now();
  Network net;
  DetectorInputParams ip = params_.input;
  ip.seed = mix_seed(params_.input.seed, index);
  net.in = make_detector_input(pre.points, R_up_cam, ip);
  net.input_ms = ms_since(t0);
  if (net.in.points.rows() == 0) return net;
  const auto t1 = std::chrono::steady_clock::now();
  if (params_.segment && run_) {
    net.out = run_(net.in.points);
  } else {
    net.out.boxes = detect_(net.in.points);
  }
  net.network_ms = ms_since(t1);
  return net;
}

std::shared_ptr<const PreparedDetection> HtxSource::prepare(const FrameInput& frame,
                                                            const PinholeCamera& camera) const {
  if (params_.detect_every != 1 || !run_ || frame.depth.empty() || !depth_fits(frame, camera)) {
    return nullptr;
  }
  const std::lock_guard<std::mutex> lock(prepare_mutex_);
  auto p = std::make_shared<Prepared>(preprocess_frame(frame, camera, prepare_rays_));
  if (const std::optional<Eigen::Vector3d> up = impl::usable_floor(p->pre)) {
    p->net = run_network(p->pre, upright_rotation(*up), frame.index);
  }
  return p;
}

DynamicObjects HtxSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  return detect_prepared(frame, camera, nullptr);
}

DynamicObjects HtxSource::detect_prepared(const FrameInput& frame, const PinholeCamera& camera,
                                          const PreparedDetection* prepared) {
  const bool run_now = frame_count_ % static_cast<std::size_t>(params_.detect_every) == 0;
  ++frame_count_;
  stats_ = HtxFrameStats{};
  if (!run_now) return last_objects_;  // carried: the last detection's camera-frame boxes
  last_objects_ = DynamicObjects{};
  boxes_.clear();
  if (frame.depth.empty()) return last_objects_;
  DS3D_CHECK(depth_fits(frame, camera), "ds3d::slam::HtxSource::detect: depth must be CV_16UC1 of ",
             camera.width, "x", camera.height, " (got type ", frame.depth.type(), ", ",
             frame.depth.cols, "x", frame.depth.rows, ")");
  const auto* given = dynamic_cast<const Prepared*>(prepared);
  if (given != nullptr && (given->index != frame.index || given->timestamp != frame.timestamp)) {
    given = nullptr;  // prepared for another frame
  }
  std::optional<Prepared> local;
  if (given == nullptr) local = preprocess_frame(frame, camera, rays_);
  const Prepared& p = given != nullptr ? *given : *local;
  const bool segment = params_.segment && static_cast<bool>(run_);
  const PreprocessResult& pre = p.pre;
  stats_.num_points = static_cast<std::size_t>(pre.points.rows());
  stats_.ground_found = align_with_floor(pre, params_, segment, R_up_cam_, last_objects_);
  std::optional<Network> computed;
  if (!p.net) computed = run_network(pre, R_up_cam_, frame.index);
  const Network& net = p.net ? *p.net : *computed;
  const DetectorInput& in = net.in;
  stats_.preprocess_ms = p.preprocess_ms + net.input_ms;
  if (in.points.rows() == 0) return last_objects_;
  const auto t1 = std::chrono::steady_clock::now();
  const std::vector<Box3> boxes =
      segment ? segment_frame(pre, in, net.out, frame.timestamp) : net.out.boxes;
  stats_.detect_ms = net.network_ms + ms_since(t1);
  stats_.detected = true;
  const auto report = [&](const Box3& b, const Eigen::Matrix3f& R_up_cam) {
    const Eigen::Matrix3d R_cam_up = R_up_cam.cast<double>().transpose();
    Eigen::Matrix<float, 8, 3> corners;
    const auto up_corners = box::corners(b);
    for (int k = 0; k < 8; ++k) {
      corners.row(k) =
          (R_cam_up * up_corners[static_cast<std::size_t>(k)]).cast<float>().transpose();
    }
    last_objects_.boxes_3d.push_back(corners);
    last_objects_.boxes_3d_margin.push_back(params_.box_uncertainty);
    if (segment) last_objects_.segmentation.boxes_3d_segmented.push_back(1);
  };
  for (const Box3& b : boxes) {
    if (!(b.score >= params_.min_score)) continue;  // also drops a NaN score
    if (!labels_.empty() && std::find(labels_.begin(), labels_.end(), b.label) == labels_.end()) {
      continue;
    }
    if (!b.centre.allFinite() || !b.size.allFinite() || !std::isfinite(b.yaw)) continue;
    report(b, R_up_cam_);
    boxes_.push_back(b);
  }
  stats_.num_boxes = boxes_.size();
  // Whole-frame segmentation: only the foreground connected to a reported box is trusted.
  const auto finish = [&]() -> const DynamicObjects& {
    if (segment && params_.segment_outside_boxes) {
      stats_.num_unanchored = keep_anchored_foreground(last_objects_, params_.box_uncertainty);
      stats_.num_foreground -= stats_.num_unanchored;
    }
    return last_objects_;
  };
  if (!segment || params_.hold_frames == 0) return finish();
  // Carry the held boxes that no box of this frame continues while the segmentation still sees
  // foreground in them; then hold this frame's boxes.
  const Points3f& fg = last_objects_.segmentation.foreground_points;
  std::vector<HeldBox> held;
  for (const Box3& b : boxes_) {
    // A box without foreground support is not held (nothing to follow it by).
    const auto [centroid, count] = foreground_in(b, R_up_cam_, fg);
    if (count >= params_.hold_min_points) {
      held.push_back({b, R_up_cam_, centroid, frame.timestamp, 0});
    }
  }
  for (HeldBox h : held_) {
    const double dt = frame.timestamp - h.timestamp;
    if (h.age >= params_.hold_frames || !(dt >= 0.0 && dt <= params_.hold_seconds)) continue;
    // Continued: a box of this frame has its centre within half this box's largest horizontal
    // size (the detector reported the object again at about the same place). Other held boxes
    // are not merged: the boxes of a person from consecutive frames often each cover only a part
    // of them, and their union gates more of the person (the segmentation decides inside).
    const Eigen::Vector3f c_cam = h.R_up_cam.transpose() * h.box.centre;
    const bool continued = std::any_of(boxes_.begin(), boxes_.end(), [&](const Box3& b) {
      return continues(h.box, c_cam, R_up_cam_.transpose() * b.centre);
    });
    if (continued) continue;
    const auto [centroid, count] = foreground_in(h.box, h.R_up_cam, fg);
    if (count < params_.hold_min_points) continue;
    h.box.centre += h.R_up_cam * (centroid - h.fg_centroid);
    h.fg_centroid = centroid;
    ++h.age;
    report(h.box, h.R_up_cam);
    ++stats_.num_carried;
    held.push_back(h);
  }
  held_ = std::move(held);
  stats_.num_boxes += stats_.num_carried;
  return finish();
}

std::vector<Box3> HtxSource::segment_frame(const PreprocessResult& pre, const DetectorInput& in,
                                           const DetectorOutput& o, double timestamp) {
  // The part logits averaged per preprocessed point (a point drawn twice counts twice).
  const Eigen::Index n = pre.points.rows();
  std::vector<float> sum(static_cast<std::size_t>(n), 0.0F);
  std::vector<int> count(static_cast<std::size_t>(n), 0);
  for (Eigen::Index k = 0; k < o.part_logits.rows(); ++k) {
    const std::uint32_t row = in.rows[static_cast<std::size_t>(k)];
    sum[row] += o.part_logits(k, 0);
    ++count[row];
  }
  std::vector<float> logit(static_cast<std::size_t>(n), 0.0F);
  for (std::size_t k = 0; k < logit.size(); ++k) {
    if (count[k] > 0) logit[k] = sum[k] / static_cast<float>(count[k]);
  }
  smooth_over_frames(pre.points, count, timestamp, logit);
  // Foreground: sigmoid(logit) > p  <=>  logit > log(p / (1 - p)). The drawn points in the
  // draw's order (a point drawn twice is kept twice: harmless); points not drawn are left out.
  const double p = params_.foreground_min_prob;
  const auto min_logit = static_cast<float>(std::log(p / (1.0 - p)));
  std::vector<Eigen::Index> fg;
  std::vector<Eigen::Index> bg;
  const auto label = [&](Eigen::Index row) {
    (logit[static_cast<std::size_t>(row)] > min_logit ? fg : bg).push_back(row);
  };
  for (const std::uint32_t row : in.rows) label(row);
  const auto gather = [&](const std::vector<Eigen::Index>& rows, Points3f& to) {
    to.resize(static_cast<Eigen::Index>(rows.size()), 3);
    for (std::size_t k = 0; k < rows.size(); ++k) {
      to.row(static_cast<Eigen::Index>(k)) = pre.points.row(rows[k]);
    }
  };
  Segmentation& seg = last_objects_.segmentation;
  gather(fg, seg.foreground_points);
  gather(bg, seg.background_points);
  seg.foreground_radius = params_.foreground_radius;
  seg.segment_outside_boxes = params_.segment_outside_boxes;
  stats_.num_foreground = fg.size();
  return o.boxes;
}

struct HtxSource::PastSegmentation {
  explicit PastSegmentation(Points3f pts, std::vector<float> lg, double t)
      : points(std::move(pts)),
        logit(std::move(lg)),
        timestamp(t),
        adaptor{points, nullptr},
        tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {}
  Points3f points;                               // camera frame [m], finite
  std::vector<float> logit;                      // per row of points
  double timestamp = 0;                          // [s]
  detail::KdTreeCloudAdaptor<Points3f> adaptor;  // the tree keeps a reference to it
  detail::KdTree3f<Points3f> tree;
};

double HtxSource::largest_leaf_edge() const {
  const auto& leaf = params_.preprocess.voxel.leaf_size;
  return std::max({leaf.dx, leaf.dy, leaf.dz});
}

void HtxSource::smooth_over_frames(const Points3f& points, const std::vector<int>& count,
                                   double timestamp, std::vector<float>& logit) {
  if (params_.segment_frames == 0) return;
  // Frames too old (or a timestamp going back: another sequence) leave the window.
  while (!past_.empty() && !(timestamp - past_.front()->timestamp >= 0.0 &&
                             timestamp - past_.front()->timestamp <= params_.hold_seconds)) {
    past_.pop_front();
  }
  const double r2 = std::pow(largest_leaf_edge(), 2);
  std::vector<std::uint32_t> rows;
  for (Eigen::Index r = 0; r < points.rows(); ++r) {
    if (count[static_cast<std::size_t>(r)] > 0 && points.row(r).allFinite()) {
      rows.push_back(static_cast<std::uint32_t>(r));
    }
  }
  Points3f kept(static_cast<Eigen::Index>(rows.size()), 3);
  std::vector<float> kept_logit(rows.size());
  std::vector<float> mean = logit;
  for (std::size_t k = 0; k < rows.size(); ++k) {
    const std::uint32_t r = rows[k];
    kept.row(static_cast<Eigen::Index>(k)) = points.row(r);
    kept_logit[k] = logit[r];
    float s = logit[r];
    int m = 1;
    const Eigen::Vector3f q = points.row(r).transpose();
    for (const auto& f : past_) {
      detail::NearestWithinResultSet nearest(r2);
      f->tree.findNeighbors(nearest, q.data(), nanoflann::SearchParams());
      if (nearest.found()) {
        s += f->logit[nearest.index()];
        ++m;
      }
    }
    mean[r] = s / static_cast<float>(m);
  }
  logit = std::move(mean);
  past_.push_back(
      std::make_shared<const PastSegmentation>(std::move(kept), std::move(kept_logit), timestamp));
  while (past_.size() > static_cast<std::size_t>(params_.segment_frames)) past_.pop_front();
}

std::pair<Eigen::Vector3f, int> HtxSource::foreground_in(const Box3& b, const Eigen::Matrix3f& R,
                                                         const Points3f& fg) const {
  const double grow = std::isfinite(params_.box_uncertainty) ? 2.0 * params_.box_uncertainty : 0.0;
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (Eigen::Index k = 0; k < fg.rows(); ++k) {
    const Eigen::Vector3f p = fg.row(k).transpose();
    if (!p.allFinite()) continue;
    if (box::contains(b, (R * p).cast<double>(), grow)) {
      sum += p.cast<double>();
      ++n;
    }
  }
  if (n == 0) return {Eigen::Vector3f::Zero(), 0};
  return {(sum / n).cast<float>(), n};
}

}  // namespace ds3d::slam
