// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/geometric_motion.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/errors.hpp"
#include "ds3d/hdbscan.hpp"

namespace ds3d::slam {

void GeometricMotionParams::validate() const {
  constexpr const char* f = "ds3d::slam::GeometricMotionParams";
  DS3D_CHECK(num_features > 0, f, ": num_features must be > 0 (got ", num_features, ")");
  DS3D_CHECK(reference_gap >= 1, f, ": reference_gap must be >= 1 (got ", reference_gap, ")");
  DS3D_CHECK(max_match_distance >= 1 && max_match_distance <= 256, f,
             ": max_match_distance must be in [1, 256] (got ", max_match_distance, ")");
  DS3D_CHECK(ransac_iterations >= 1, f, ": ransac_iterations must be >= 1 (got ", ransac_iterations,
             ")");
  DS3D_CHECK(std::isfinite(chi2_2dof) && chi2_2dof > 0, f, ": chi2_2dof must be > 0 (got ",
             chi2_2dof, ")");
  DS3D_CHECK(std::isfinite(moving_chi2_factor) && moving_chi2_factor >= 1, f,
             ": moving_chi2_factor must be >= 1 (got ", moving_chi2_factor, ")");
  DS3D_CHECK(std::isfinite(depth_noise) && depth_noise >= 0, f, ": depth_noise must be >= 0 (got ",
             depth_noise, ")");
  DS3D_CHECK(std::isfinite(min_depth_residual) && min_depth_residual > 0, f,
             ": min_depth_residual must be > 0 (got ", min_depth_residual, ")");
  DS3D_CHECK(warp_stride >= 1, f, ": warp_stride must be >= 1 (got ", warp_stride, ")");
  DS3D_CHECK(warp_window >= 0, f, ": warp_window must be >= 0 (got ", warp_window, ")");
  DS3D_CHECK(std::isfinite(max_depth) && max_depth > 0, f, ": max_depth must be > 0 (got ",
             max_depth, ")");
  DS3D_CHECK(min_cluster_size >= 2, f, ": min_cluster_size must be >= 2 (got ", min_cluster_size,
             ")");
  DS3D_CHECK(min_samples >= 1, f, ": min_samples must be >= 1 (got ", min_samples, ")");
  DS3D_CHECK(std::isfinite(box_margin) && box_margin >= 0, f, ": box_margin must be >= 0 (got ",
             box_margin, ")");
  DS3D_CHECK(std::isfinite(dense_factor) && dense_factor > 0, f, ": dense_factor must be > 0 (got ",
             dense_factor, ")");
  DS3D_CHECK(std::isfinite(max_object_size) && max_object_size > 0, f,
             ": max_object_size must be > 0 (got ", max_object_size, ")");
  DS3D_CHECK(hold_frames >= 0, f, ": hold_frames must be >= 0 (got ", hold_frames, ")");
  DS3D_CHECK(min_pose_inliers >= 6, f, ": min_pose_inliers must be >= 6 (got ", min_pose_inliers,
             ")");
}

namespace {

OrbParams orb_params(const GeometricMotionParams& p) {
  OrbParams o;
  o.num_features = p.num_features;
  o.max_depth = p.max_depth;
  return o;
}

Eigen::Vector3d back_project_pinhole(const PinholeCamera& c, double u, double v, double z) {
  return {(u - c.cx) / c.fx * z, (v - c.cy) / c.fy * z, z};
}

}  // namespace

GeometricMotionSource::GeometricMotionSource(const GeometricMotionParams& params)
    : params_((params.validate(), params)), extractor_(orb_params(params)) {}

DynamicObjects GeometricMotionSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  stats_ = {};
  const std::size_t now = frame_count_++;
  DynamicObjects out;
  if (frame.depth.empty() || frame.depth.type() != CV_16UC1 || frame.rgb.empty()) return out;

  Past cur;
  cur.features = extractor_.extract(frame.rgb, frame.depth, camera);
  cur.depth = frame.depth.clone();
  {
    cv::Mat d = frame.depth.clone();
    d.setTo(65535, d == 0);
    const int k = 2 * params_.warp_window + 1;
    cv::erode(d, cur.min_depth, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }
  cur.T_world_cam = history_.empty() ? Eigen::Isometry3d::Identity() : history_.back().T_world_cam;

  const auto sigma_z = [&](double z) { return params_.depth_noise * z * z; };
  const auto depth_thr = [&](double z) {
    // Residual of two independent depths: 3·√2·σ(z), floored.
    return std::max<double>(params_.min_depth_residual, 3.0 * std::sqrt(2.0) * sigma_z(z));
  };

  std::vector<Eigen::Vector3d> flagged;  // (u, v, z) of moving evidence in the current frame
  std::size_t num_keypoint_flags = 0;    // flagged[0, this) are keypoints, the rest warp pixels
  if (!history_.empty()) {
    const Past& ref = history_.front();
    const auto inside_held = [&](const Eigen::Vector3d& p_world) {
      for (const Held& h : held_) {
        const Eigen::Vector3d lo = h.corners_world.colwise().minCoeff().transpose();
        const Eigen::Vector3d hi = h.corners_world.colwise().maxCoeff().transpose();
        if ((p_world.array() >= lo.array()).all() && (p_world.array() <= hi.array()).all()) {
          return true;
        }
      }
      return false;
    };
    // 1. Mutual best matches with the reference.
    std::vector<cv::DMatch> matches;
    if (!cur.features.descriptors.empty() && !ref.features.descriptors.empty()) {
      cv::BFMatcher matcher(cv::NORM_HAMMING, true);
      matcher.match(cur.features.descriptors, ref.features.descriptors, matches);
    }
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    std::vector<std::pair<int, int>> pairs;  // (current, reference) of each usable match
    std::vector<std::uint8_t> for_pose;
    for (const cv::DMatch& m : matches) {
      if (m.distance > static_cast<float>(params_.max_match_distance)) continue;
      const auto r = static_cast<std::size_t>(m.trainIdx);
      const auto c = static_cast<std::size_t>(m.queryIdx);
      if (!ref.features.has_depth(r)) continue;
      const Eigen::Vector2f& ur = ref.features.undistorted[r];
      const Eigen::Vector3d p = back_project_pinhole(camera, ur.x(), ur.y(), ref.features.depth[r]);
      pairs.emplace_back(m.queryIdx, m.trainIdx);
      for_pose.push_back(inside_held(ref.T_world_cam * p) ? 0 : 1);
      if (for_pose.back() != 0U) {
        obj.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(p.z()));
        const Eigen::Vector2f& uc = cur.features.undistorted[c];
        img.emplace_back(uc.x(), uc.y());
      }
    }
    stats_.num_matches = static_cast<int>(pairs.size());
    if (static_cast<int>(obj.size()) < 2 * params_.min_pose_inliers) {
      // Known objects cover most matches: the exclusion would starve the pose; use every match.
      obj.clear();
      img.clear();
      for (const auto& [c_idx, r_idx] : pairs) {
        const auto r = static_cast<std::size_t>(r_idx);
        const Eigen::Vector2f& ur = ref.features.undistorted[r];
        const Eigen::Vector3d p =
            back_project_pinhole(camera, ur.x(), ur.y(), ref.features.depth[r]);
        obj.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()),
                         static_cast<float>(p.z()));
        const Eigen::Vector2f& uc = cur.features.undistorted[static_cast<std::size_t>(c_idx)];
        img.emplace_back(uc.x(), uc.y());
      }
    }
    // 2. Robust pose T_cur_ref (EPnP-RANSAC, then Levenberg-Marquardt on the inliers).
    Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
    if (static_cast<int>(obj.size()) >= params_.min_pose_inliers) {
      const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
      cv::Mat rvec;
      cv::Mat tvec;
      std::vector<int> inliers;
      const bool ok = cv::solvePnPRansac(
          obj, img, K, cv::noArray(), rvec, tvec, false, params_.ransac_iterations,
          static_cast<float>(std::sqrt(params_.chi2_2dof) * 1.5), 0.99, inliers, cv::SOLVEPNP_EPNP);
      if (ok && static_cast<int>(inliers.size()) >= params_.min_pose_inliers) {
        std::vector<cv::Point3f> oi;
        std::vector<cv::Point2f> ii;
        for (const int i : inliers) {
          oi.push_back(obj[static_cast<std::size_t>(i)]);
          ii.push_back(img[static_cast<std::size_t>(i)]);
        }
        cv::solvePnP(oi, ii, K, cv::noArray(), rvec, tvec, true, cv::SOLVEPNP_ITERATIVE);
        cv::Mat R;
        cv::Rodrigues(rvec, R);
        Eigen::Matrix3d Re;
        for (int a = 0; a < 3; ++a) {
          for (int b = 0; b < 3; ++b) Re(a, b) = R.at<double>(a, b);
        }
        T_cur_ref.linear() = Re;
        T_cur_ref.translation() =
            Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2));
        stats_.pose_ok = T_cur_ref.matrix().allFinite();
        stats_.num_pose_inliers = static_cast<int>(inliers.size());
      }
    }
    if (stats_.pose_ok) {
      cur.T_world_cam = ref.T_world_cam * T_cur_ref.inverse();
      // 3. Residuals of every matched keypoint with depth on both sides.
      for (const auto& [c_idx, r_idx] : pairs) {
        const auto c = static_cast<std::size_t>(c_idx);
        const auto r = static_cast<std::size_t>(r_idx);
        if (!cur.features.has_depth(c)) continue;
        const Eigen::Vector2f& ur = ref.features.undistorted[r];
        const Eigen::Vector3d pred =
            T_cur_ref * back_project_pinhole(camera, ur.x(), ur.y(), ref.features.depth[r]);
        if (pred.z() <= 0.0) continue;
        const Eigen::Vector2f& uc = cur.features.undistorted[c];
        const double du = camera.fx * pred.x() / pred.z() + camera.cx - uc.x();
        const double dv = camera.fy * pred.y() / pred.z() + camera.cy - uc.y();
        const double s = extractor_.level_scale(cur.features.keypoints[c].octave);
        const double chi2 = (du * du + dv * dv) / (s * s);
        const double zc = cur.features.depth[c];
        if (chi2 > params_.moving_chi2_factor * params_.chi2_2dof ||
            std::abs(zc - pred.z()) > depth_thr(pred.z())) {
          flagged.emplace_back(cur.features.keypoints[c].pt.x, cur.features.keypoints[c].pt.y, zc);
          ++stats_.num_moving_keypoints;
        }
      }
      num_keypoint_flags = flagged.size();
      // 4. Depth-warp consistency of a grid of the current depth against the reference.
      const Eigen::Isometry3d T_ref_cur = T_cur_ref.inverse();
      int valid = 0;
      int moved = 0;
      std::vector<Eigen::Vector3d> warp_flagged;
      for (int v = params_.warp_stride / 2; v < frame.depth.rows; v += params_.warp_stride) {
        const auto* row = frame.depth.ptr<std::uint16_t>(v);
        for (int u = params_.warp_stride / 2; u < frame.depth.cols; u += params_.warp_stride) {
          if (row[u] == 0) continue;
          const double z = row[u] / camera.depth_scale;
          if (z < 0.1 || z > params_.max_depth) continue;
          const Eigen::Vector3d pr = T_ref_cur * camera.back_project(u, v, z);
          if (pr.z() < 0.1) continue;
          const Eigen::Vector2d q = camera.project(pr);
          const auto qu = static_cast<int>(std::lround(q.x()));
          const auto qv = static_cast<int>(std::lround(q.y()));
          if (qu < 0 || qv < 0 || qu >= ref.min_depth.cols || qv >= ref.min_depth.rows) continue;
          const std::uint16_t m = ref.min_depth.at<std::uint16_t>(qv, qu);
          if (m == 65535) continue;
          ++valid;
          if (m / camera.depth_scale - pr.z() > depth_thr(pr.z())) {
            warp_flagged.emplace_back(u, v, z);
            ++moved;
          }
        }
      }
      // Most of the scene "moving" means the pose is wrong (e.g. a blurred fast turn), not that
      // the world moves: report nothing new rather than removing the static scene.
      if (valid > 0 && 2 * moved < valid) {
        stats_.num_moving_pixels = moved;
        flagged.insert(flagged.end(), warp_flagged.begin(), warp_flagged.end());
      } else {
        flagged.clear();
        num_keypoint_flags = 0;
        stats_.num_moving_keypoints = 0;
      }
    }
  }
  stats_.T_world_cam = cur.T_world_cam;

  // 5. Objects: HDBSCAN of the moving evidence in (u, v, z), metric scales.
  std::vector<Held> confirmed_now;
  if (static_cast<int>(flagged.size()) >= params_.min_cluster_size) {
    RowMatrixXd pts(static_cast<Eigen::Index>(flagged.size()), 3);
    std::vector<double> zs;
    for (std::size_t i = 0; i < flagged.size(); ++i) {
      pts.row(static_cast<Eigen::Index>(i)) = flagged[i].transpose();
      zs.push_back(flagged[i].z());
    }
    std::nth_element(zs.begin(), zs.begin() + static_cast<std::ptrdiff_t>(zs.size() / 2), zs.end());
    const double zmed = zs[zs.size() / 2];
    HdbscanParams hp;
    hp.min_cluster_size = params_.min_cluster_size;
    hp.min_samples = params_.min_samples;
    const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
    for (int c = 0; c < h.num_clusters; ++c) {
      // HDBSCAN is scale-free: it also groups sparse, scattered evidence (descriptor mismatches,
      // edge effects). A moving surface flags the warp grid densely, so keep a cluster only if
      // its median core distance is within dense_factor grid steps at its depth.
      std::vector<double> core;
      std::vector<double> cz;
      int keypoint_evidence = 0;
      for (std::size_t i = 0; i < flagged.size(); ++i) {
        if (h.labels[i] != c) continue;
        core.push_back(h.core_distances[i]);
        cz.push_back(flagged[i].z());
        keypoint_evidence += i < num_keypoint_flags ? 1 : 0;
      }
      // Both kinds of evidence must agree: feature motion (reprojection / depth residuals) and
      // free-space violation (depth warp). Each alone has its own false positives (descriptor
      // mismatches; depth edges and sensor artefacts), which rarely coincide.
      if (keypoint_evidence < params_.min_samples ||
          static_cast<int>(core.size()) - keypoint_evidence < params_.min_samples) {
        continue;
      }
      const auto mid = [](std::vector<double>& v) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        return v[v.size() / 2];
      };
      const double step = params_.warp_stride * mid(cz) / camera.fx;  // grid step [m]
      if (mid(core) > params_.dense_factor * step) continue;
      Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e30);
      Eigen::Vector3d hi = -lo;
      for (std::size_t i = 0; i < flagged.size(); ++i) {
        if (h.labels[i] != c) continue;
        const Eigen::Vector3d p =
            camera.back_project(flagged[i].x(), flagged[i].y(), flagged[i].z());
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
      // Human-scale objects only: a larger cluster is static structure flagged by a wrong pose
      // or a depth artefact, and its box would gate most of the image.
      if ((hi - lo).maxCoeff() > params_.max_object_size) continue;
      lo.array() -= params_.box_margin;
      hi.array() += params_.box_margin;
      Held obj;
      for (int k = 0; k < 8; ++k) {
        const Eigen::Vector3d corner((k & 1) != 0 ? hi.x() : lo.x(), (k & 2) != 0 ? hi.y() : lo.y(),
                                     (k & 4) != 0 ? hi.z() : lo.z());
        obj.corners_world.row(k) = (cur.T_world_cam * corner).transpose();
      }
      obj.centre_world = cur.T_world_cam * (0.5 * (lo + hi));
      obj.last_seen = now;
      const Eigen::Vector3d wlo = obj.corners_world.colwise().minCoeff().transpose();
      const Eigen::Vector3d whi = obj.corners_world.colwise().maxCoeff().transpose();
      // Temporal consistency: evidence must repeat at the same place in consecutive frames
      // (a moving object keeps producing it; a one-frame pose glitch does not), or confirm an
      // object already held.
      const auto overlaps = [&](const Held& x) {
        const Eigen::Vector3d xlo = x.corners_world.colwise().minCoeff().transpose();
        const Eigen::Vector3d xhi = x.corners_world.colwise().maxCoeff().transpose();
        return (xlo.array() <= whi.array()).all() && (wlo.array() <= xhi.array()).all();
      };
      confirmed_now.push_back(obj);
      if (std::none_of(candidates_.begin(), candidates_.end(), overlaps) &&
          std::none_of(held_.begin(), held_.end(), overlaps)) {
        continue;
      }
      // 6. A new sighting replaces held objects whose centre it contains.
      std::erase_if(held_, [&](const Held& x) {
        return (x.centre_world.array() >= wlo.array()).all() &&
               (x.centre_world.array() <= whi.array()).all();
      });
      held_.push_back(obj);
      ++stats_.num_new_objects;
    }
  }
  candidates_ = std::move(confirmed_now);
  std::erase_if(held_, [&](const Held& x) {
    return now - x.last_seen > static_cast<std::size_t>(params_.hold_frames);
  });
  const Eigen::Isometry3d T_cam_world = cur.T_world_cam.inverse();
  for (const Held& x : held_) {
    Eigen::Matrix<float, 8, 3> c;
    for (int k = 0; k < 8; ++k) {
      c.row(k) = (T_cam_world * x.corners_world.row(k).transpose()).cast<float>().transpose();
    }
    out.boxes_3d.push_back(c);
  }
  stats_.num_objects = static_cast<int>(out.boxes_3d.size());

  history_.push_back(std::move(cur));
  while (static_cast<int>(history_.size()) > params_.reference_gap) history_.pop_front();
  return out;
}

}  // namespace ds3d::slam
