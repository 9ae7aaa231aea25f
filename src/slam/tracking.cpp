// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// SlamFrontend::Impl, per frame: matching against the last frame, a keyframe and the local map,
// pose-only optimisation, relocalisation, and the tracking state machine.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <utility>
#include <vector>

#include <opencv2/calib3d.hpp>

#include "ds3d/errors.hpp"
#include "slam_frontend_impl.hpp"

namespace ds3d::slam {

FrameData SlamFrontend::Impl::make_frame_data(const PreparedFrame& pf) const {
  FrameData f;
  const auto& feat = pf.features;
  f.close_depth = feat.close_depth;
  const std::vector<float> w =
      cfg.disparity_sigma > 0 ? disparity_inv_sigma2(pf, cfg, extractor) : std::vector<float>{};
  for (std::size_t i = 0; i < feat.size(); ++i) {
    if (!pf.dynamic.empty() && pf.dynamic[i] != 0) continue;
    f.uv.push_back(feat.undistorted[i]);
    f.depth.push_back(feat.depth[i]);
    f.octave.push_back(feat.keypoints[i].octave);
    if (!w.empty()) f.disp_inv_sigma2.push_back(w[i]);
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

// Projects `candidates` into frame `f` at pose T_cw and assigns each to the best unmatched
// keypoint within `radius_px` × level scale (ORB-SLAM2's SearchByProjection). Returns matches.
int SlamFrontend::Impl::search_by_projection(FrameData& f, const Eigen::Isometry3d& T_cw,
                                             const std::vector<int>& candidates, double th,
                                             bool local_map, std::size_t stamp) {
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
      raised_visible.push_back(pid);
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
int SlamFrontend::Impl::match_keyframe(const Keyframe& kf, FrameData& f) const {
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
int SlamFrontend::Impl::optimize_frame(FrameData& f, Eigen::Isometry3d& T_cw) const {
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
  const auto r = optimize_pose(k, T_cw, pw, obs, cfg.pose, prior);
  T_cw = r.T_cam_world;
  for (std::size_t j = 0; j < idx.size(); ++j) {
    if (r.inlier[j] == 0) f.points[idx[j]] = -1;
  }
  return r.num_inliers;
}

// PnP-RANSAC on the current 3-D/2-D matches (pixels are undistorted, so no distortion).
bool SlamFrontend::Impl::pnp_ransac(const FrameData& f, Eigen::Isometry3d& T_cw) const {
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
  const bool ok = cv::solvePnPRansac(obj, img, K, cv::noArray(), rvec, tvec, false, 200, 4.0F, 0.99,
                                     inliers, cv::SOLVEPNP_EPNP);
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

bool SlamFrontend::Impl::track_motion_model(FrameData& f, Eigen::Isometry3d& T_cw) {
  std::vector<int> cand;
  for (std::size_t i = 0; i < last.size(); ++i) {
    if (last.points[i] >= 0) cand.push_back(last.points[i]);
  }
  T_cw = velocity * last_T_cw;
  if (search_widening(f, T_cw, cand) < 20) return false;
  return optimize_frame(f, T_cw) >= 10;
}

// Clears this frame's "matched" mark of each candidate, so that a later search may use it.
void SlamFrontend::Impl::forget_seen(const std::vector<int>& cand) {
  for (const int pid : cand)
    points[static_cast<std::size_t>(pid)].last_frame_seen = std::numeric_limits<std::size_t>::max();
}

// Clears every map point's "seen / searched in this frame" marks (frame_counter), so that another
// attempt on the same frame searches them again.
void SlamFrontend::Impl::clear_frame_marks() {
  for (auto& p : points) {
    if (p.last_frame_seen == frame_counter)
      p.last_frame_seen = std::numeric_limits<std::size_t>::max();
    if (p.local_stamp == frame_counter) p.local_stamp = std::numeric_limits<std::size_t>::max();
  }
}

// Matches `cand` into the frame at T_cw by projection (f.points reset first), in a window of 15 px
// × level scale, or 30 px when fewer than 20 match (ORB-SLAM2's motion-model windows for
// monocular and RGB-D input). Returns the matches.
int SlamFrontend::Impl::search_widening(FrameData& f, const Eigen::Isometry3d& T_cw,
                                        const std::vector<int>& cand) {
  std::fill(f.points.begin(), f.points.end(), -1);
  const int n = search_by_projection(f, T_cw, cand, 15.0, false, frame_counter);
  if (n >= 20) return n;
  std::fill(f.points.begin(), f.points.end(), -1);
  forget_seen(cand);
  return search_by_projection(f, T_cw, cand, 30.0, false, frame_counter);
}

bool SlamFrontend::Impl::track_keyframe(const Keyframe& kf, FrameData& f, Eigen::Isometry3d& T_cw,
                                        int min_inliers) {
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

bool SlamFrontend::Impl::relocalize(FrameData& f, Eigen::Isometry3d& T_cw) {
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

// FrontendConfig::recover_by_projection: a frame after a lost one, before relocalisation. The
// map points of the reference keyframe and its best covisible neighbours projected at T_cw (the
// last tracked pose), then a pose-only optimisation on those matches. True (T_cw and f.points
// set) when it keeps 20 inliers; the caller then tracks the local map.
bool SlamFrontend::Impl::recover_by_projection(FrameData& f, Eigen::Isometry3d& T_cw) {
  if (ref_kf < 0 || keyframes[static_cast<std::size_t>(ref_kf)].bad) return false;
  std::vector<int> kfs = best_covisible(ref_kf, 10);
  kfs.push_back(ref_kf);
  const std::vector<int> cand = keyframe_points(kfs);
  Eigen::Isometry3d T = T_cw;
  const bool ok = search_widening(f, T, cand) >= 20 && optimize_frame(f, T) >= 20;
  // The last pose may lie centimetres off: the local map, searched at the optimised pose, may
  // match again what this first pass rejected.
  forget_seen(cand);
  if (!ok) {
    std::fill(f.points.begin(), f.points.end(), -1);
    return false;
  }
  T_cw = T;
  return true;
}

// Local map: keyframes sharing points with the frame plus their best covisible neighbours.
std::vector<int> SlamFrontend::Impl::local_keyframes(const FrameData& f) {
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

int SlamFrontend::Impl::track_local_map(FrameData& f, Eigen::Isometry3d& T_cw) {
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
    if (pid < 0) continue;
    ++points[static_cast<std::size_t>(pid)].found;
    raised_found.push_back(pid);
  }
  return inliers;
}

// FrontendConfig::prior_acceleration: the prior of this frame's pose-only optimisations, at the
// constant-velocity prediction when the velocity comes from two frames tracked in a row.
void SlamFrontend::Impl::set_prior(double dt) {
  prior.sigma = 0;
  if (!motion_prior || !velocity_trusted || !last_tracked || !(dt > 0)) return;
  prior.centre = (velocity * last_T_cw).inverse().translation();
  prior.sigma = cfg.prior_acceleration * dt * dt;
  prior.huber = 2.0;  // beyond 2 σ a constant pull: matches that contradict the prediction win
}

namespace {

// Distance between the camera centres of two world-to-camera poses [m].
double centre_distance(const Eigen::Isometry3d& a_cw, const Eigen::Isometry3d& b_cw) {
  return (a_cw.inverse().translation() - b_cw.inverse().translation()).norm();
}

}  // namespace

// FrontendConfig::max_acceleration / max_angular_acceleration: can the camera have moved from the
// constant-velocity prediction `pred` to `T_cw` in the `dt` seconds since the last frame?
bool SlamFrontend::Impl::plausible(const Eigen::Isometry3d& T_cw, const Eigen::Isometry3d& pred,
                                   double dt) const {
  const double dt2 = dt * dt;
  if (cfg.max_acceleration > 0) {
    const double moved = centre_distance(T_cw, pred);
    if (moved > cfg.max_acceleration * dt2) return false;
  }
  if (cfg.max_angular_acceleration > 0) {
    const double turned = Eigen::AngleAxisd(pred.linear().transpose() * T_cw.linear()).angle();
    if (turned > cfg.max_angular_acceleration * dt2) return false;
  }
  return true;
}

// Unmatches the matches of `f` that the pose `T_cw` does not explain: behind the camera, or
// beyond 4 × the χ² thresholds. Returns how many are left.
int SlamFrontend::Impl::keep_agreeing(FrameData& f, const Eigen::Isometry3d& T_cw) const {
  int agree = 0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    if (f.points[i] < 0) continue;
    const Observation o = observation(f, i);
    bool front = false;
    const double chi2 =
        reprojection_chi2(k, T_cw, points[static_cast<std::size_t>(f.points[i])].pos, o, &front);
    const double th = 4.0 * (o.stereo() ? cfg.pose.chi2_stereo : cfg.pose.chi2_mono);
    if (!front || chi2 > th) {
      f.points[i] = -1;
    } else {
      ++agree;
    }
  }
  return agree;
}

// The motion gate's second hypothesis (FrontendConfig::max_acceleration): the last frame's points
// matched at the prediction, only the matches that agree with it (4 × the χ² threshold) start the
// pose-only optimisation, then the local map. True (T_cw and inliers set) when that pose is
// plausible and has min_tracked_inliers local-map inliers.
bool SlamFrontend::Impl::track_from_prediction(FrameData& f, Eigen::Isometry3d& T_cw,
                                               const Eigen::Isometry3d& pred, double dt,
                                               int& inliers) {
  clear_frame_marks();  // undo the first attempt's "seen in this frame" marks
  std::vector<int> cand;
  for (const int pid : last.points) {
    if (pid >= 0) cand.push_back(pid);
  }
  std::fill(f.points.begin(), f.points.end(), -1);
  Eigen::Isometry3d T = pred;
  search_by_projection(f, T, cand, 15.0, false, frame_counter);
  const int agree = keep_agreeing(f, pred);
  if (agree < 10 || optimize_frame(f, T) < 10) return false;
  const int n = track_local_map(f, T);
  if (n < cfg.min_tracked_inliers || !plausible(T, pred, dt)) return false;
  T_cw = T;
  inliers = n;
  return true;
}

namespace {

// Takes back the raises log[from, to) of a map-point counter (MapPoint::visible or found) and
// removes them from the log.
void take_back(std::vector<MapPoint>& points, std::vector<int>& log, std::size_t from,
               std::size_t to, int MapPoint::*counter) {
  for (std::size_t i = from; i < to; ++i) --(points[static_cast<std::size_t>(log[i])].*counter);
  log.erase(log.begin() + static_cast<std::ptrdiff_t>(from),
            log.begin() + static_cast<std::ptrdiff_t>(to));
}

}  // namespace

// After a retry of the pose that started at `m`: the map's counters and the reference keyframe
// stay those of the hypothesis kept, as if the other had never been tried (the counters decide
// which map points are culled).
void SlamFrontend::Impl::settle_retry(const RetryMark& m, bool kept) {
  if (kept) {
    take_back(points, raised_visible, 0, m.visible, &MapPoint::visible);
    take_back(points, raised_found, 0, m.found, &MapPoint::found);
  } else {
    take_back(points, raised_visible, m.visible, raised_visible.size(), &MapPoint::visible);
    take_back(points, raised_found, m.found, raised_found.size(), &MapPoint::found);
    ref_kf = m.ref_kf;
  }
}

// A second hypothesis for the frame's pose: tracked from `pred` (track_from_prediction), it
// replaces f, T_cw and inliers when it succeeds and its camera centre lies within `within` [m]
// of pred's; either way only the hypothesis kept counts in the map (settle_retry).
bool SlamFrontend::Impl::retry_pose(FrameData& f, Eigen::Isometry3d& T_cw, int& inliers,
                                    const Eigen::Isometry3d& pred, double dt, double within) {
  FrameData retried = f;
  Eigen::Isometry3d T = T_cw;
  int n = 0;
  const RetryMark mark = retry_mark();
  const bool kept =
      track_from_prediction(retried, T, pred, dt, n) && centre_distance(T, pred) < within;
  settle_retry(mark, kept);
  if (!kept) return false;
  f = std::move(retried);
  T_cw = T;
  inliers = n;
  return true;
}

// FrontendConfig::source_motion_gate: the source's ego-motion applied to the pose of its
// reference frame (a tracked frame of this map segment) against the tracked pose T_cw. True when
// the retry from the source's motion replaced T_cw: as the geometric source's own second
// hypothesis, it must lie less than half as far from that motion as the first pose. Where the
// motion gate has refused T_cw too (`implausible`) and the retry fails, the source's motion is
// the pose (FrontendConfig::hold_source_motion).
bool SlamFrontend::Impl::gate_by_source_motion(const EgoMotion& em, double timestamp, double dt,
                                               FrameData& f, Eigen::Isometry3d& T_cw, int& inliers,
                                               bool implausible) {
  const double gap = timestamp - em.reference_timestamp;
  if (!(gap > 0) || !(dt > 0)) return false;
  const FrameRecord* ref = nullptr;
  for (auto it = records.rbegin(); it != records.rend() && ref == nullptr; ++it) {
    if (it->timestamp < em.reference_timestamp) break;
    if (it->timestamp == em.reference_timestamp) ref = &*it;
  }
  if (ref == nullptr || !ref->tracked || ref->ref_kf < 0 ||
      (!segment_starts.empty() && ref->ref_kf < segment_starts.back())) {
    return false;
  }
  const Eigen::Isometry3d pred = em.T_cur_ref * record_pose(*ref);
  const double off0 = centre_distance(T_cw, pred);
  if (off0 <= cfg.source_motion_gate * gap * gap) return false;
  if (retry_pose(f, T_cw, inliers, pred, dt, 0.5 * off0)) return true;
  if (!implausible || !cfg.hold_source_motion) return false;
  // FrontendConfig::hold_source_motion: the source's motion is the pose, with the first pose's
  // matches that it explains.
  T_cw = pred;
  inliers = keep_agreeing(f, pred);
  return true;
}

TrackResult SlamFrontend::Impl::track(PreparedFrame pf) {
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_ms();
  const FrameInput& in = pf.input;
  DS3D_CHECK(std::isfinite(in.timestamp),
             "ds3d::slam::SlamFrontend::track: timestamp must be finite (got ", in.timestamp, ")");
  DS3D_CHECK(in.timestamp >= last_timestamp,
             "ds3d::slam::SlamFrontend::track: time went backwards: frame ", in.index,
             " has timestamp ", in.timestamp, " < previous ", last_timestamp);
  const double prev_ts = last_timestamp;
  last_timestamp = in.timestamp;
  apply_ba_if_due(false);
  raised_visible.clear();
  raised_found.clear();

  TrackResult res;
  res.index = in.index;
  res.timestamp = in.timestamp;
  res.num_features = static_cast<int>(pf.features.size());
  res.num_refilled = pf.num_refilled;
  res.keypoints.reserve(pf.features.size());
  for (const auto& kp : pf.features.keypoints) res.keypoints.push_back(kp.pt);
  res.keypoint_status.assign(pf.features.size(), KeypointStatus::kUnmatched);
  std::vector<std::size_t> kept;  // feature index of each FrameData entry
  for (std::size_t i = 0; i < pf.features.size(); ++i) {
    if (!pf.dynamic.empty() && pf.dynamic[i] == kDepthEdgeFlag) {
      res.keypoint_status[i] = KeypointStatus::kDepthEdge;
      ++res.num_depth_edge;
    } else if (!pf.dynamic.empty() && pf.dynamic[i] != 0) {
      res.keypoint_status[i] = KeypointStatus::kDynamic;
      ++res.num_dynamic;
    } else {
      kept.push_back(i);
    }
  }
  FrameData f = make_frame_data(pf);
  if (frame_counter < static_cast<std::size_t>(cfg.retrack_first_frames)) {
    first_frames.emplace_back(records.size(), f);
  }
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
    bool recovered = false;
    set_prior(in.timestamp - prev_ts);
    if (last_tracked && velocity_valid) ok = track_motion_model(f, T_cw);
    if (!ok && last_tracked) {
      T_cw = last_T_cw;
      ok = track_keyframe(keyframes[static_cast<std::size_t>(ref_kf)], f, T_cw, 10);
    }
    if (!ok && last_tracked && cfg.odometry_fallback) {
      ok = track_last_frame(f, T_cw);
      res.odometry = ok;
    }
    if (!ok) prior.sigma = 0;  // relocalisation searches without the prediction
    if (!ok && !last_tracked && lost_count > 0 && cfg.recover_by_projection) {
      T_cw = last_T_cw;
      ok = recover_by_projection(f, T_cw);
      relocalized = ok;
      recovered = ok;
    }
    if (!ok) {
      std::fill(f.points.begin(), f.points.end(), -1);
      ok = relocalize(f, T_cw);
      relocalized = ok;
    }
    if (ok) {
      just_relocalized = relocalized;
      const Eigen::Isometry3d T_before = T_cw;
      inliers = track_local_map(f, T_cw);
      ok = inliers >= (relocalized && !recovered ? std::max(50, cfg.min_tracked_inliers)
                                                 : cfg.min_tracked_inliers);
      if (!ok && res.odometry) {
        // Too few map points to trust a map pose: keep the odometry pose, start fresh points.
        T_cw = T_before;
        std::fill(f.points.begin(), f.points.end(), -1);
        ok = true;
      }
    }
    if (!ok && last_tracked && !res.odometry && !relocalized && cfg.odometry_fallback) {
      // The map was found but too weakly: frame-to-frame odometry instead of losing the frame.
      Eigen::Isometry3d T = last_T_cw;
      if (track_last_frame(f, T)) {
        res.odometry = true;
        T_cw = T;
        inliers = track_local_map(f, T);
        if (inliers >= cfg.min_tracked_inliers) {
          T_cw = T;
        } else {
          std::fill(f.points.begin(), f.points.end(), -1);
        }
        ok = true;
      }
    }
    const bool gate = cfg.max_acceleration > 0 || cfg.max_angular_acceleration > 0;
    const Eigen::Isometry3d pred = gate ? velocity * last_T_cw : T_cw;
    bool implausible = false;  // the motion gate refused the pose and its retry found none
    if (gate && ok && !relocalized && velocity_trusted && in.timestamp > prev_ts &&
        !plausible(T_cw, pred, in.timestamp - prev_ts)) {
      // Two hypotheses: keep the first pose unless tracking from the prediction gives a
      // plausible one.
      res.motion_gated = retry_pose(f, T_cw, inliers, pred, in.timestamp - prev_ts,
                                    std::numeric_limits<double>::infinity());
      implausible = !res.motion_gated;
    }
    if (cfg.source_motion_gate > 0 && ok && !relocalized && pf.objects.ego_motion &&
        gate_by_source_motion(*pf.objects.ego_motion, in.timestamp, in.timestamp - prev_ts, f, T_cw,
                              inliers, implausible)) {
      res.motion_gated = true;
    }
    // The velocity of the next frame's motion gate must come from two frames tracked here, not
    // from a re-anchored or relocalised one, whose pose may be far off.
    const bool normal = ok && !relocalized;
    if (ok) {
      res.state = relocalized ? TrackState::kRelocalized : TrackState::kTracking;
      lost_count = 0;
      velocity = T_cw * last_T_cw.inverse();
      velocity_valid = last_tracked;
      velocity_trusted = normal && last_normal;
      if (res.odometry || need_keyframe(f, inliers)) {
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
      velocity_trusted = false;
      res.state = TrackState::kLost;
      std::fill(f.points.begin(), f.points.end(), -1);
      if (cfg.reanchor_after_lost > 0 && lost_count >= cfg.reanchor_after_lost &&
          n_depth >= cfg.min_init_points) {
        // A new map segment at the last known pose: keeps a trajectory going (with a jump
        // bounded by the motion during the outage) instead of staying lost for ever.
        const int id = add_keyframe(f, T_cw, in);
        f = keyframes[static_cast<std::size_t>(id)].data;
        segment_starts.push_back(id);
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
  if (ref_kf >= 0) rec.T_c_ref = T_cw * keyframes[static_cast<std::size_t>(ref_kf)].T_cw.inverse();
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
  last_normal = res.state == TrackState::kTracking;
  have_last = true;
  ++frame_counter;
  res.times = pf.times;
  res.times.track_ms = ms_since(t0);
  res.times.track_cpu_ms = thread_cpu_ms() - c0;
  return res;
}

}  // namespace ds3d::slam
