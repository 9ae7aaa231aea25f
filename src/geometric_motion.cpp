// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/geometric_motion.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include <Eigen/Cholesky>
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
  DS3D_CHECK(std::isfinite(match_ratio) && match_ratio > 0 && match_ratio <= 1, f,
             ": match_ratio must be in (0, 1] (got ", match_ratio, ")");
  DS3D_CHECK(ransac_iterations >= 1, f, ": ransac_iterations must be >= 1 (got ", ransac_iterations,
             ")");
  DS3D_CHECK(std::isfinite(chi2_2dof) && chi2_2dof > 0, f, ": chi2_2dof must be > 0 (got ",
             chi2_2dof, ")");
  DS3D_CHECK(std::isfinite(moving_chi2) && moving_chi2 > 0, f, ": moving_chi2 must be > 0 (got ",
             moving_chi2, ")");
  DS3D_CHECK(std::isfinite(min_pixel_sigma) && min_pixel_sigma > 0, f,
             ": min_pixel_sigma must be > 0 (got ", min_pixel_sigma, ")");
  DS3D_CHECK(std::isfinite(depth_noise) && depth_noise >= 0, f, ": depth_noise must be >= 0 (got ",
             depth_noise, ")");
  DS3D_CHECK(std::isfinite(min_depth_residual) && min_depth_residual > 0, f,
             ": min_depth_residual must be > 0 (got ", min_depth_residual, ")");
  DS3D_CHECK(depth_window >= 0, f, ": depth_window must be >= 0 (got ", depth_window, ")");
  DS3D_CHECK(std::isfinite(min_inlier_ratio) && min_inlier_ratio >= 0 && min_inlier_ratio <= 1, f,
             ": min_inlier_ratio must be in [0, 1] (got ", min_inlier_ratio, ")");
  DS3D_CHECK(min_pose_inliers >= 6, f, ": min_pose_inliers must be >= 6 (got ", min_pose_inliers,
             ")");
  DS3D_CHECK(warp_stride >= 1, f, ": warp_stride must be >= 1 (got ", warp_stride, ")");
  DS3D_CHECK(warp_window >= 0, f, ": warp_window must be >= 0 (got ", warp_window, ")");
  DS3D_CHECK(std::isfinite(max_depth) && max_depth > 0, f, ": max_depth must be > 0 (got ",
             max_depth, ")");
  DS3D_CHECK(min_cluster_size >= 2, f, ": min_cluster_size must be >= 2 (got ", min_cluster_size,
             ")");
  DS3D_CHECK(min_samples >= 1, f, ": min_samples must be >= 1 (got ", min_samples, ")");
  DS3D_CHECK(std::isfinite(min_support) && min_support > 0 && min_support <= 1, f,
             ": min_support must be in (0, 1] (got ", min_support, ")");
  DS3D_CHECK(std::isfinite(max_object_size) && max_object_size > 0, f,
             ": max_object_size must be > 0 (got ", max_object_size, ")");
  DS3D_CHECK(std::isfinite(box_margin) && box_margin >= 0, f, ": box_margin must be >= 0 (got ",
             box_margin, ")");
  DS3D_CHECK(hold_frames >= 0, f, ": hold_frames must be >= 0 (got ", hold_frames, ")");
}

namespace {

OrbParams orb_params(const GeometricMotionParams& p) {
  OrbParams o;
  o.num_features = p.num_features;
  o.max_depth = p.max_depth;
  o.max_range = std::max(o.max_range, p.max_depth);
  return o;
}

// Ray through an undistorted pixel (z = 1).
Eigen::Vector3d ray(const PinholeCamera& c, const Eigen::Vector2f& u) {
  return {(u.x() - c.cx) / c.fx, (u.y() - c.cy) / c.fy, 1.0};
}

// Spread (max - min) of the valid depths [m] in a (2r+1)² window around (u, v); 0 if < 2 valid.
double depth_spread(const cv::Mat& depth, double scale, float u, float v, int r) {
  const int x0 = static_cast<int>(std::lround(u));
  const int y0 = static_cast<int>(std::lround(v));
  std::uint16_t lo = std::numeric_limits<std::uint16_t>::max();
  std::uint16_t hi = 0;
  for (int y = std::max(0, y0 - r); y <= std::min(depth.rows - 1, y0 + r); ++y) {
    const auto* row = depth.ptr<std::uint16_t>(y);
    for (int x = std::max(0, x0 - r); x <= std::min(depth.cols - 1, x0 + r); ++x) {
      if (row[x] == 0) continue;
      lo = std::min(lo, row[x]);
      hi = std::max(hi, row[x]);
    }
  }
  return hi > lo ? (hi - lo) / scale : 0.0;
}

double median_of(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

struct Box3 {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  void add(const Eigen::Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
};

}  // namespace

GeometricMotionSource::GeometricMotionSource(const GeometricMotionParams& params)
    : params_((params.validate(), params)), extractor_(orb_params(params)) {}

DynamicObjects GeometricMotionSource::detect(const FrameInput& frame, const PinholeCamera& camera) {
  stats_ = {};
  const std::size_t now = frame_count_++;
  DynamicObjects out;
  if (frame.depth.empty() || frame.depth.type() != CV_16UC1 || frame.rgb.empty()) return out;
  if (frame.depth.cols != camera.width || frame.depth.rows != camera.height) return out;

  Past cur;
  cur.features = extractor_.extract(frame.rgb, frame.depth, camera);
  cur.depth = frame.depth;  // shared, never written
  {
    cv::Mat d = frame.depth.clone();
    d.setTo(65535, d == 0);
    const int k = 2 * params_.warp_window + 1;
    cv::erode(d, cur.min_depth, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(k, k)));
  }

  // Reference: the oldest remembered frame whose world pose is chained from trusted poses. With
  // none (a long run of untrusted poses), the world frame of held objects is lost: restart.
  const Past* ref = nullptr;
  for (const Past& p : history_) {
    if (p.pose_valid) {
      ref = &p;
      break;
    }
  }
  if (ref == nullptr) {
    held_.clear();
    candidates_.clear();
    if (!history_.empty()) ref = &history_.back();
  }
  cur.T_world_cam = ref != nullptr ? ref->T_world_cam : Eigen::Isometry3d::Identity();
  cur.pose_valid = history_.empty();  // the first frame defines the world frame

  const auto sigma_z = [&](double z, double spread) {
    const double s = params_.depth_noise * z * z;
    return std::max<double>(params_.min_depth_residual / 3.0,
                            std::sqrt(s * s + 0.25 * spread * spread));
  };

  // Largest depth spread of a continuous surface in the keypoint window: that of the noise, or of
  // min_depth_residual (a slanted surface), whichever is larger.
  const auto edge_thr = [&](double z) {
    return std::max<double>(params_.min_depth_residual,
                            3.0 * std::sqrt(2.0) * params_.depth_noise * z * z);
  };
  struct Tested {
    Eigen::Vector3d uvz;  // raw pixel and current depth
    bool moving = false;
    double chi2 = 0;
  };
  std::vector<Tested> tested;
  tested_.clear();
  Eigen::Isometry3d T_cur_ref = Eigen::Isometry3d::Identity();
  double pixel_sigma = params_.min_pixel_sigma;
  if (ref != nullptr) {
    const auto inside_held = [&](const Eigen::Vector3d& p_world) {
      return std::any_of(held_.begin(), held_.end(), [&](const Held& h) {
        const Eigen::Vector3d lo = h.corners_world.colwise().minCoeff().transpose();
        const Eigen::Vector3d hi = h.corners_world.colwise().maxCoeff().transpose();
        return (p_world.array() >= lo.array()).all() && (p_world.array() <= hi.array()).all();
      });
    };
    // 1. Mutual best matches with the reference.
    // Mutual best matches that also pass Lowe's ratio test (Lowe 2004, §7.1): repeated texture
    // (keyboards, tiles) gives ambiguous descriptors whose mismatches share one wrong offset and
    // would form a dense "moving" cluster on static structure.
    std::vector<cv::DMatch> matches;
    if (!cur.features.descriptors.empty() && ref->features.descriptors.rows >= 2) {
      cv::BFMatcher matcher(cv::NORM_HAMMING, false);
      std::vector<std::vector<cv::DMatch>> knn;
      std::vector<cv::DMatch> back;
      matcher.knnMatch(cur.features.descriptors, ref->features.descriptors, knn, 2);
      matcher.match(ref->features.descriptors, cur.features.descriptors, back);
      for (const auto& k : knn) {
        if (k.size() < 2 || k[0].distance >= params_.match_ratio * k[1].distance) continue;
        if (back[static_cast<std::size_t>(k[0].trainIdx)].trainIdx != k[0].queryIdx) continue;
        matches.push_back(k[0]);
      }
    }
    std::vector<std::pair<std::size_t, std::size_t>> pairs;  // (current, reference)
    std::vector<cv::Point3f> obj;
    std::vector<cv::Point2f> img;
    std::vector<cv::Point3f> obj_all;
    std::vector<cv::Point2f> img_all;
    for (const cv::DMatch& m : matches) {
      if (m.distance > static_cast<float>(params_.max_match_distance)) continue;
      const auto c = static_cast<std::size_t>(m.queryIdx);
      const auto r = static_cast<std::size_t>(m.trainIdx);
      if (!ref->features.has_depth(r)) continue;
      const Eigen::Vector3d p = ref->features.depth[r] * ray(camera, ref->features.undistorted[r]);
      const cv::Point3f pf(static_cast<float>(p.x()), static_cast<float>(p.y()),
                           static_cast<float>(p.z()));
      const cv::Point2f uc(cur.features.undistorted[c].x(), cur.features.undistorted[c].y());
      pairs.emplace_back(c, r);
      obj_all.push_back(pf);
      img_all.push_back(uc);
      if (!inside_held(ref->T_world_cam * p)) {
        obj.push_back(pf);
        img.push_back(uc);
      }
    }
    stats_.num_matches = static_cast<int>(pairs.size());
    // Known objects covering most matches would starve the pose: then use every match.
    if (static_cast<int>(obj.size()) < 2 * params_.min_pose_inliers) {
      obj = obj_all;
      img = img_all;
    }
    // 2. Robust pose T_cur_ref (EPnP-RANSAC, then Levenberg-Marquardt on the inliers).
    if (static_cast<int>(obj.size()) >= params_.min_pose_inliers) {
      const cv::Matx33d K(camera.fx, 0, camera.cx, 0, camera.fy, camera.cy, 0, 0, 1);
      cv::Mat rvec;
      cv::Mat tvec;
      std::vector<int> inliers;
      const bool ok = cv::solvePnPRansac(
          obj, img, K, cv::noArray(), rvec, tvec, false, params_.ransac_iterations,
          static_cast<float>(std::sqrt(params_.chi2_2dof) * 1.5), 0.99, inliers, cv::SOLVEPNP_EPNP);
      const double ratio = static_cast<double>(inliers.size()) /
                           static_cast<double>(std::max<std::size_t>(obj.size(), 1));
      stats_.num_pose_inliers = static_cast<int>(inliers.size());
      if (ok && static_cast<int>(inliers.size()) >= params_.min_pose_inliers &&
          ratio >= params_.min_inlier_ratio) {
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
      }
    }
    if (stats_.pose_ok) {
      cur.T_world_cam = ref->T_world_cam * T_cur_ref.inverse();
      cur.pose_valid = true;
      // σ_px of this frame: the median reprojection error of all matches, in level-0 pixels per
      // pyramid scale, over the median of a 2-D Rayleigh (σ·√(2 ln 2)). Robust up to half the
      // matches being outliers, and it grows with blur and rolling-shutter distortion.
      std::vector<double> e;
      for (const auto& [c, r] : pairs) {
        const Eigen::Vector3d q =
            T_cur_ref * (ref->features.depth[r] * ray(camera, ref->features.undistorted[r]));
        if (q.z() <= 0.0) continue;
        const Eigen::Vector2d du(
            camera.fx * q.x() / q.z() + camera.cx - cur.features.undistorted[c].x(),
            camera.fy * q.y() / q.z() + camera.cy - cur.features.undistorted[c].y());
        e.push_back(du.norm() / extractor_.level_scale(cur.features.keypoints[c].octave));
      }
      pixel_sigma =
          std::max(params_.min_pixel_sigma, median_of(e) / std::sqrt(2.0 * std::log(2.0)));
      // 3. χ² (3 dof) of each keypoint's (Δu, Δv, Δz) with its own covariance.
      const Eigen::Matrix3d& R = T_cur_ref.linear();
      for (const auto& [c, r] : pairs) {
        if (!cur.features.has_depth(c)) continue;
        const double zr = ref->features.depth[r];
        const double zc = cur.features.depth[c];
        if (zr > params_.max_depth || zc > params_.max_depth) continue;
        const Eigen::Vector3d d = ray(camera, ref->features.undistorted[r]);
        const Eigen::Vector3d q = T_cur_ref * (zr * d);
        if (q.z() <= 0.1) continue;
        const Eigen::Vector2f& uc = cur.features.undistorted[c];
        const Eigen::Vector3d res(uc.x() - (camera.fx * q.x() / q.z() + camera.cx),
                                  uc.y() - (camera.fy * q.y() / q.z() + camera.cy), zc - q.z());
        // Jacobian of the prediction (u, v, z) with respect to the reference depth.
        const Eigen::Vector3d dq = R * d;
        const Eigen::Vector3d g(camera.fx * (dq.x() * q.z() - q.x() * dq.z()) / (q.z() * q.z()),
                                camera.fy * (dq.y() * q.z() - q.y() * dq.z()) / (q.z() * q.z()),
                                dq.z());
        const cv::Point2f& pc = cur.features.keypoints[c].pt;
        const cv::Point2f& pr = ref->features.keypoints[r].pt;
        // Keypoints on a depth discontinuity (silhouettes, T-junctions, thin structures) are not
        // fixed 3-D points: the corner slides along the occluding contour as the view changes,
        // and RGB-depth misregistration gives them either depth. They are no evidence either way.
        const double spr =
            depth_spread(ref->depth, camera.depth_scale, pr.x, pr.y, params_.depth_window);
        const double spc =
            depth_spread(frame.depth, camera.depth_scale, pc.x, pc.y, params_.depth_window);
        if (spr > edge_thr(zr) || spc > edge_thr(zc)) continue;
        const double szr = sigma_z(zr, spr);
        const double szc = sigma_z(zc, spc);
        const double sc = extractor_.level_scale(cur.features.keypoints[c].octave);
        const double sr = extractor_.level_scale(ref->features.keypoints[r].octave);
        const double spx2 = pixel_sigma * pixel_sigma * (sc * sc + sr * sr);
        Eigen::Matrix3d S = Eigen::Vector3d(spx2, spx2, szc * szc).asDiagonal();
        S += g * g.transpose() * (szr * szr);
        const double chi2 = res.dot(S.ldlt().solve(res));
        Tested t;
        t.uvz = Eigen::Vector3d(pc.x, pc.y, zc);
        t.moving = std::isfinite(chi2) && chi2 > params_.moving_chi2;
        t.chi2 = std::isfinite(chi2) ? chi2 : 0.0;
        stats_.num_moving_keypoints += t.moving ? 1 : 0;
        tested.push_back(t);
      }
      stats_.num_tested = static_cast<int>(tested.size());
    }
  }
  stats_.pixel_sigma = pixel_sigma;

  // 4. Candidates: HDBSCAN of the moving keypoints in (u, v, z), metric scales; compactness and
  //    support tests.
  struct Candidate {
    Box3 box;         // camera frame, of the evidence
    cv::Rect2d rect;  // image rectangle of the moving keypoints
    double z_lo = 0, z_hi = 0;
  };
  std::vector<Candidate> found;
  std::vector<Eigen::Vector3d> moving;
  std::vector<std::size_t> moving_idx;  // index into tested
  for (std::size_t i = 0; i < tested.size(); ++i) {
    const Tested& t = tested[i];
    TestedKeypoint k;
    k.u = static_cast<float>(t.uvz.x());
    k.v = static_cast<float>(t.uvz.y());
    k.z = static_cast<float>(t.uvz.z());
    k.chi2 = static_cast<float>(t.chi2);
    k.moving = t.moving;
    tested_.push_back(k);
    if (!t.moving) continue;
    moving.push_back(t.uvz);
    moving_idx.push_back(i);
  }
  if (static_cast<int>(moving.size()) >= params_.min_cluster_size) {
    RowMatrixXd pts(static_cast<Eigen::Index>(moving.size()), 3);
    std::vector<double> zs;
    for (std::size_t i = 0; i < moving.size(); ++i) {
      pts.row(static_cast<Eigen::Index>(i)) = moving[i].transpose();
      zs.push_back(moving[i].z());
    }
    const double zmed = median_of(zs);
    HdbscanParams hp;
    hp.min_cluster_size = params_.min_cluster_size;
    hp.min_samples = params_.min_samples;
    const HdbscanResult h = hdbscan(pts, hp, {zmed / camera.fx, zmed / camera.fy, 1.0});
    for (int cl = 0; cl < h.num_clusters; ++cl) {
      Candidate cand;
      double u0 = 1e30, u1 = -1e30, v0 = 1e30, v1 = -1e30, z0 = 1e30, z1 = -1e30;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] != cl) continue;
        tested_[moving_idx[i]].cluster = cl;
        const Eigen::Vector3d& m = moving[i];
        cand.box.add(camera.back_project(m.x(), m.y(), m.z()));
        u0 = std::min(u0, m.x()), u1 = std::max(u1, m.x());
        v0 = std::min(v0, m.y()), v1 = std::max(v1, m.y());
        z0 = std::min(z0, m.z()), z1 = std::max(z1, m.z());
      }
      // Human-scale objects only: larger clusters are static structure under a wrong pose.
      if ((cand.box.hi - cand.box.lo).maxCoeff() > params_.max_object_size) continue;
      // Support: a moving object moves as a whole, so most tested keypoints in its region move;
      // false alarms on static structure are scattered among consistent keypoints.
      const double dz = 3.0 * sigma_z(z1, 0.0);
      int in_region = 0;
      int moving_in_region = 0;
      for (const Tested& t : tested) {
        if (t.uvz.x() < u0 || t.uvz.x() > u1 || t.uvz.y() < v0 || t.uvz.y() > v1) continue;
        if (t.uvz.z() < z0 - dz || t.uvz.z() > z1 + dz) continue;
        ++in_region;
        moving_in_region += t.moving ? 1 : 0;
      }
      if (moving_in_region < params_.min_support * in_region) continue;
      for (std::size_t i = 0; i < moving.size(); ++i) {
        if (h.labels[i] == cl) tested_[moving_idx[i]].candidate = true;
      }
      cand.rect = cv::Rect2d(u0, v0, u1 - u0, v1 - v0);
      cand.z_lo = z0 - dz;
      cand.z_hi = z1 + dz;
      found.push_back(cand);
    }
  }
  stats_.num_candidates = static_cast<int>(found.size());

  // 5. Depth-warp check around the candidates: grid pixels in front of everything the reference
  //    saw in a window extend the object (it moved into empty space).
  if (!found.empty() && ref != nullptr) {
    const Eigen::Isometry3d T_ref_cur = T_cur_ref.inverse();
    const int s = params_.warp_stride;
    for (Candidate& cand : found) {
      // The region a moving object may occupy beyond its keypoints: half its size on each side.
      const cv::Rect2d grown(cand.rect.x - 0.5 * cand.rect.width,
                             cand.rect.y - 0.5 * cand.rect.height, 2.0 * cand.rect.width,
                             2.0 * cand.rect.height);
      const int v_lo = std::max(0, static_cast<int>(grown.y));
      const int v_hi = std::min(frame.depth.rows - 1, static_cast<int>(grown.y + grown.height));
      const int u_lo = std::max(0, static_cast<int>(grown.x));
      const int u_hi = std::min(frame.depth.cols - 1, static_cast<int>(grown.x + grown.width));
      for (int v = v_lo - v_lo % s + s / 2; v <= v_hi; v += s) {
        const auto* row = frame.depth.ptr<std::uint16_t>(v);
        for (int u = u_lo - u_lo % s + s / 2; u <= u_hi; u += s) {
          if (row[u] == 0) continue;
          const double z = row[u] / camera.depth_scale;
          if (z < cand.z_lo || z > cand.z_hi) continue;
          const Eigen::Vector3d pc = camera.back_project(u, v, z);
          const Eigen::Vector3d pr = T_ref_cur * pc;
          if (pr.z() < 0.1) continue;
          const Eigen::Vector2d q = camera.project(pr);
          const auto qu = static_cast<int>(std::lround(q.x()));
          const auto qv = static_cast<int>(std::lround(q.y()));
          if (qu < 0 || qv < 0 || qu >= ref->min_depth.cols || qv >= ref->min_depth.rows) continue;
          const std::uint16_t m = ref->min_depth.at<std::uint16_t>(qv, qu);
          if (m == 65535) continue;  // no reference depth anywhere in the window: unknown
          const double zr = m / camera.depth_scale;
          if (zr - pr.z() > 3.0 * std::sqrt(2.0) * sigma_z(pr.z(), 0.0)) {
            cand.box.add(pc);
            ++stats_.num_moving_pixels;
          }
        }
      }
    }
  }

  // 6. Confirmation over consecutive frames, and holding in the world frame.
  std::vector<Held> candidates_now;
  for (const Candidate& cand : found) {
    if ((cand.box.hi - cand.box.lo).maxCoeff() > params_.max_object_size) continue;
    const Eigen::Vector3d lo = cand.box.lo.array() - params_.box_margin;
    const Eigen::Vector3d hi = cand.box.hi.array() + params_.box_margin;
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
    const auto overlaps = [&](const Held& x) {
      const Eigen::Vector3d xlo = x.corners_world.colwise().minCoeff().transpose();
      const Eigen::Vector3d xhi = x.corners_world.colwise().maxCoeff().transpose();
      return (xlo.array() <= whi.array()).all() && (wlo.array() <= xhi.array()).all();
    };
    candidates_now.push_back(obj);
    if (std::none_of(candidates_.begin(), candidates_.end(), overlaps) &&
        std::none_of(held_.begin(), held_.end(), overlaps)) {
      continue;
    }
    // A new sighting replaces the held objects it overlaps: the object moved there.
    std::erase_if(held_, overlaps);
    held_.push_back(obj);
    ++stats_.num_new_objects;
  }
  candidates_ = std::move(candidates_now);
  std::erase_if(held_, [&](const Held& x) {
    return now - x.last_seen > static_cast<std::size_t>(params_.hold_frames);
  });
  stats_.T_world_cam = cur.T_world_cam;
  // 7. Report held objects in the current camera frame; without a trusted pose their place in
  //    this frame is unknown, so nothing is reported (the masker carries the last regions).
  if (cur.pose_valid) {
    const Eigen::Isometry3d T_cam_world = cur.T_world_cam.inverse();
    for (const Held& x : held_) {
      Eigen::Matrix<float, 8, 3> c;
      for (int k = 0; k < 8; ++k) {
        c.row(k) = (T_cam_world * x.corners_world.row(k).transpose()).cast<float>().transpose();
      }
      out.boxes_3d.push_back(c);
    }
  }
  stats_.num_objects = static_cast<int>(out.boxes_3d.size());

  history_.push_back(std::move(cur));
  while (static_cast<int>(history_.size()) > params_.reference_gap) history_.pop_front();
  return out;
}

}  // namespace ds3d::slam
