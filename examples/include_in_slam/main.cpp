// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// What this shows: an existing RGB-D SLAM system ("toyslam", with its OWN keypoint, frame and
// map-point types) includes ds3d's header-only core (no OpenCV, no Ceres) to
//   1. drop keypoints on people before tracking: box-gated HDBSCAN (ds3d/dynamic/dynamic_filter.hpp),
//      fed with its keypoints and the person boxes of some detector;
//   2. preprocess its own point cloud through a PointCloudTraits adaptor (ds3d/preprocess/preprocess.hpp):
//      voxel centroids, floor removal, outlier removal.
// The frames are made in code: a room (floor, back and side walls) and a person in front of the
// back wall who walks to the right; the detector misses the person on the last frame, where the
// region carried from the previous frame still removes them.
// It prints per frame how many keypoints on the person were removed and how many others were
// kept, and exits with 1 when fewer than 90 % of the person's keypoints are removed, when more
// than 10 % of the keypoints off the person are removed, or when preprocessing misses the floor.
// The walk-through is docs/integration.md.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <vector>

#include <ds3d/cloud.hpp>
#include <ds3d/dynamic/dynamic_filter.hpp>
#include <ds3d/preprocess/preprocess.hpp>
#include <ds3d/version.hpp>

// ---------------------------------------------------------------------------------------------
// The host SLAM system's own types (they know nothing about ds3d).
namespace toyslam {

// Like cv::KeyPoint plus ORB-SLAM2's mvDepth, but the host's own.
struct KeyPoint {
  float x = 0, y = 0;  // pixel column, row
  int octave = 0;      // pyramid level
  float depth = -1;    // [m], <= 0 when the depth image has a hole there
};

// What the host's 2-D detector returns.
struct PersonBox {
  int left = 0, top = 0, right = 0, bottom = 0;  // [px], inclusive
  float confidence = 0;
};

struct Intrinsics {
  double fx = 525, fy = 525, cx = 319.5, cy = 239.5;
  int width = 640, height = 480;
  double depth_factor = 5000;  // 16-bit depth units per metre (TUM convention)
};

struct Frame {
  std::vector<std::uint16_t> depth;  // row-major width x height, 0 = no measurement
  std::vector<KeyPoint> keypoints;
  std::vector<bool> on_person;  // ground truth of this toy scene (a real system has none)
  std::vector<PersonBox> persons;
};

struct MapPoint {  // the host's cloud point: double precision, plus bookkeeping ds3d ignores
  double pos[3] = {0, 0, 0};
  int observations = 0;
};
using PointMap = std::vector<MapPoint>;

// Deterministic pseudo-random numbers (SplitMix64), so the example prints the same every run.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31U);
  }
  double uniform() { return static_cast<double>(next() >> 11U) * 0x1.0p-53; }
  double normal() {  // Box-Muller
    const double u1 = std::max(uniform(), 1e-300);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * uniform());
  }
};

// A person standing on the floor at depth `z` [m], centred at camera x = `x` [m]: head, torso,
// arms and legs as axis-aligned pieces in the plane z (camera frame: x right, y down, the floor at
// y = +1.2 m). Returns the depth of the body surface at (X, Y) on that plane, or 0 if none.
double person_depth(double px, double py, double x, double z) {
  struct Piece {
    double x0, x1, y0, y1;
  };
  const double dx = px - x;
  const Piece pieces[] = {
      {-0.20, 0.20, -0.33, 0.35},   // torso
      {-0.30, -0.21, -0.30, 0.25},  // arms
      {0.21, 0.30, -0.30, 0.25},    //
      {-0.17, -0.03, 0.35, 1.20},   // legs
      {0.03, 0.17, 0.35, 1.20},     //
  };
  for (const Piece& p : pieces) {
    if (dx >= p.x0 && dx <= p.x1 && py >= p.y0 && py <= p.y1) {
      const double c = (dx - 0.5 * (p.x0 + p.x1)) / (0.5 * (p.x1 - p.x0));
      return z - 0.08 * std::sqrt(std::max(0.0, 1.0 - c * c));  // rounded limbs
    }
  }
  const double hx = dx, hy = py + 0.45;  // head: a disc of radius 0.11 m
  if (hx * hx + hy * hy <= 0.11 * 0.11) return z - 0.08;
  return 0.0;
}

// Renders one frame: room + person at (person_x, person_z), Kinect-like noise and a few holes;
// keypoints on a jittered grid (denser on the textured clothes), like FAST corners would be.
Frame make_frame(const Intrinsics& K, double person_x, double person_z, std::uint64_t seed,
                 bool detector_fires) {
  Frame f;
  Rng rng{seed};
  f.depth.assign(static_cast<std::size_t>(K.width) * static_cast<std::size_t>(K.height), 0);
  std::vector<std::uint8_t> person(f.depth.size(), 0);
  int left = K.width, top = K.height, right = -1, bottom = -1;
  for (int v = 0; v < K.height; ++v) {
    for (int u = 0; u < K.width; ++u) {
      const double rx = (u - K.cx) / K.fx, ry = (v - K.cy) / K.fy;   // ray (rx, ry, 1)
      double z = 4.0;                                                // back wall
      if (ry > 1e-6) z = std::min(z, 1.2 / ry);                      // floor y = 1.2
      if (std::abs(rx) > 1e-6) z = std::min(z, 2.0 / std::abs(rx));  // side walls x = ±2
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(K.width) +
                            static_cast<std::size_t>(u);
      const double zp = person_depth(rx * person_z, ry * person_z, person_x, person_z);
      if (zp > 0.0 && zp < z) {
        z = zp;
        person[i] = 1;
        left = std::min(left, u), right = std::max(right, u);
        top = std::min(top, v), bottom = std::max(bottom, v);
      }
      z += 1.425e-3 * z * z * rng.normal();  // sensor noise (Khoshelham & Elberink 2012)
      if (rng.uniform() < 0.02) z = 0.0;     // holes
      f.depth[i] =
          static_cast<std::uint16_t>(std::lround(std::clamp(z, 0.0, 6.0) * K.depth_factor));
    }
  }
  for (int v = 8; v < K.height - 8; v += 4) {
    for (int u = 8; u < K.width - 8; u += 4) {
      const std::size_t i = static_cast<std::size_t>(v) * static_cast<std::size_t>(K.width) +
                            static_cast<std::size_t>(u);
      // Walls and floor are plain: one corner per ~14x14 px; clothes: one per ~6x6 px.
      if (rng.uniform() > (person[i] != 0 ? 0.45 : 0.08)) continue;
      KeyPoint kp;
      kp.x = static_cast<float>(u + 4.0 * rng.uniform() - 2.0);
      kp.y = static_cast<float>(v + 4.0 * rng.uniform() - 2.0);
      kp.octave = static_cast<int>(rng.next() % 4U);
      const std::size_t j =
          static_cast<std::size_t>(std::lround(kp.y)) * static_cast<std::size_t>(K.width) +
          static_cast<std::size_t>(std::lround(kp.x));
      kp.depth = f.depth[j] > 0 ? static_cast<float>(f.depth[j] / K.depth_factor) : -1.0F;
      f.keypoints.push_back(kp);
      f.on_person.push_back(person[j] != 0);
    }
  }
  if (detector_fires && right >= 0)
    f.persons.push_back({left - 6, top - 6, right + 6, bottom + 6, 0.9F});
  return f;
}

// The host's own back-projection into its own map-point type.
PointMap back_project(const Frame& f, const Intrinsics& K, int step) {
  PointMap cloud;
  for (int v = 0; v < K.height; v += step) {
    for (int u = 0; u < K.width; u += step) {
      const std::uint16_t d =
          f.depth[static_cast<std::size_t>(v) * static_cast<std::size_t>(K.width) +
                  static_cast<std::size_t>(u)];
      if (d == 0) continue;
      const double z = d / K.depth_factor;
      cloud.push_back({{(u - K.cx) * z / K.fx, (v - K.cy) * z / K.fy, z}, 0});
    }
  }
  return cloud;
}

}  // namespace toyslam

// ---------------------------------------------------------------------------------------------
// The glue: all a host needs to use ds3d. (1) a PointCloudTraits specialisation for its cloud
// type (ds3d only reads through it), (2) conversions of its camera, keypoints and boxes.
template <>
struct ds3d::PointCloudTraits<toyslam::PointMap> {
  static std::size_t size(const toyslam::PointMap& c) { return c.size(); }
  static Eigen::Vector3f point(const toyslam::PointMap& c, std::size_t i) {
    return Eigen::Vector3d(c[i].pos[0], c[i].pos[1], c[i].pos[2]).cast<float>();
  }
};
static_assert(ds3d::PointCloud<toyslam::PointMap>);

namespace glue {

ds3d::PinholeCamera camera(const toyslam::Intrinsics& K) {
  ds3d::PinholeCamera c;
  c.fx = K.fx, c.fy = K.fy, c.cx = K.cx, c.cy = K.cy;
  c.width = K.width, c.height = K.height, c.depth_scale = K.depth_factor;
  return c;
}

// N x 3 rows (u, v, depth); a depth <= 0 means "no depth" to ds3d as well.
ds3d::Keypoints3f keypoints(const std::vector<toyslam::KeyPoint>& kps) {
  ds3d::Keypoints3f out(static_cast<Eigen::Index>(kps.size()), 3);
  for (std::size_t i = 0; i < kps.size(); ++i) {
    out.row(static_cast<Eigen::Index>(i)) << kps[i].x, kps[i].y, kps[i].depth;
  }
  return out;
}

std::vector<ds3d::ImageBox> boxes(const std::vector<toyslam::PersonBox>& persons) {
  std::vector<ds3d::ImageBox> out;
  for (const toyslam::PersonBox& p : persons) {
    ds3d::ImageBox b;
    b.x_min = static_cast<float>(p.left), b.y_min = static_cast<float>(p.top);
    b.x_max = static_cast<float>(p.right), b.y_max = static_cast<float>(p.bottom);
    b.score = p.confidence;
    out.push_back(b);
  }
  return out;
}

}  // namespace glue

int main() {
  const toyslam::Intrinsics K;
  const ds3d::PinholeCamera cam = glue::camera(K);
  // One filter per sequence (it carries the dynamic regions of the last frame over a detector
  // miss); default parameters are metric, so they hold for any resolution and distance.
  ds3d::DynamicFeatureFilter filter;
  bool ok = true;

  std::printf("toyslam + ds3d %s (header-only core)\n", ds3d::kVersion);
  std::printf("frame  keypoints  in-box  on-person  removed-on-person  removed-elsewhere  boxes\n");
  for (int t = 0; t < 3; ++t) {
    // The person walks 5 cm to the right per frame; the detector misses them on frame 2.
    const toyslam::Frame f =
        toyslam::make_frame(K, -0.25 + 0.05 * t, 2.0, 1000 + static_cast<std::uint64_t>(t), t < 2);
    // Tracking step of the host, right after feature extraction and before matching:
    const ds3d::DynamicFilterResult r =
        filter.filter(glue::keypoints(f.keypoints), glue::boxes(f.persons), cam);
    std::vector<toyslam::KeyPoint> kept;  // what the host's matcher / pose optimiser gets
    std::size_t person = 0, person_removed = 0, other = 0, other_removed = 0;
    for (std::size_t i = 0; i < f.keypoints.size(); ++i) {
      const bool removed = r.dynamic[i] != 0;
      if (!removed) kept.push_back(f.keypoints[i]);
      (f.on_person[i] ? person : other) += 1;
      (f.on_person[i] ? person_removed : other_removed) += removed ? 1 : 0;
    }
    int in_box = 0;
    for (const ds3d::BoxOutcome& b : r.boxes) in_box += b.num_keypoints;
    const double recall =
        person > 0 ? static_cast<double>(person_removed) / static_cast<double>(person) : 1.0;
    const double false_rate =
        other > 0 ? static_cast<double>(other_removed) / static_cast<double>(other) : 0.0;
    std::printf("%5d  %9zu  %6d  %9zu  %10zu (%3.0f%%)  %10zu (%4.1f%%)  %zu detected%s\n", t,
                f.keypoints.size(), in_box, person, person_removed, 100.0 * recall, other_removed,
                100.0 * false_rate, f.persons.size(),
                r.boxes.size() > f.persons.size() ? " + carried" : "");
    if (recall < 0.9 || false_rate > 0.1 ||
        kept.size() + static_cast<std::size_t>(r.num_dynamic) != f.keypoints.size()) {
      std::printf(
          "  FAILED on frame %d: removed %.0f%% of the person's keypoints (want >= 90%%), "
          "%.1f%% of the others (want <= 10%%)\n",
          t, 100.0 * recall, 100.0 * false_rate);
      ok = false;
    }

    if (t == 0) {
      // Preprocessing the host's own cloud type through the traits adaptor: voxel centroids,
      // floor (RANSAC with a "camera y is down" prior), radius outliers.
      const toyslam::PointMap cloud = toyslam::back_project(f, K, 2);
      const ds3d::PreprocessResult p = ds3d::preprocess_cloud(cloud);
      // The same chain straight from the host's 16-bit depth buffer (no copy of the image).
      const ds3d::PreprocessResult q =
          ds3d::preprocess(f.depth.data(), K.width, K.height, K.width, cam);
      std::printf(
          "preprocess(PointMap via traits): %zu points -> %zu voxels -> %zu after floor "
          "(%zu) and outliers (%zu); floor normal (%.2f, %.2f, %.2f), d = %.2f m\n",
          p.num_input, p.num_voxels, static_cast<std::size_t>(p.points.rows()), p.num_ground,
          p.num_outliers, p.ground_plane[0], p.ground_plane[1], p.ground_plane[2],
          p.ground_plane[3]);
      std::printf("preprocess(uint16 depth buffer): %zu points -> %zu voxels -> %zu kept\n",
                  q.num_input, q.num_voxels, static_cast<std::size_t>(q.points.rows()));
      // Camera 1.2 m above the floor, y down: the floor is 0·x - 1·y + 0·z + 1.2 = 0.
      const bool floor_ok = p.ground_found && q.ground_found && p.ground_plane[1] < -0.95 &&
                            std::abs(p.ground_plane[3] - 1.2) < 0.05 && p.points.allFinite() &&
                            p.points.rows() > 0;
      if (!floor_ok) {
        std::printf("  FAILED: the floor plane was not found where it is (y = 1.2 m)\n");
        ok = false;
      }
    }
  }
  std::printf("%s\n", ok ? "include_in_slam: OK" : "include_in_slam: FAILED");
  return ok ? 0 : 1;
}
