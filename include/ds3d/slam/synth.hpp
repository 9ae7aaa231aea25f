// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#pragma once
/// @file synth.hpp
/// @brief Synthetic dynamic RGB-D sequences with ground truth for the dynamic part
/// (compiled into ds3d::slam; uses OpenCV for images and PNG files).
///
/// A textured indoor room (walls, floor, ceiling, furniture boxes with random high-contrast
/// textures that ORB can track) with 0-4 humanoids built from capsules and ellipsoids (torso,
/// head, upper/lower arms and legs), walking with a sinusoidal gait or sitting and moving a
/// little. The camera follows TUM-like trajectories (static, xyz, halfsphere, rpy) at 30 Hz.
/// Rendering is our own z-buffer rasteriser of tessellated primitives (no OpenGL). Depth is
/// Kinect-like: Gaussian noise sigma = 1.425e-3 z^2 m (Khoshelham & Elberink 2012), disparity
/// quantised to 1/8 pixel (baseline 7.5 cm), holes at depth discontinuities and beyond 4.5 m.
///
/// World frame: z up, the floor is z = 0, the room spans [0, X] x [0, Y] x [0, Z] m with
/// (X, Y, Z) = SynthOptions::room_size (default 4.5 x 5 x 2.8). The camera starts 0.5 m from the
/// x = 0 wall at mid-width, looking along +x; walkers and seats are placed relative to the room.
/// Camera frame and poses follow TUM (x right, y down, z forward; T_world_cam camera-to-world).

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include "ds3d/camera.hpp"
#include "ds3d/detail/abi_guard.hpp"

namespace ds3d::synth {

/// The scene and camera motion, named like the TUM fr3 dynamic sequences.
enum class Scenario : std::uint8_t {
  kStaticRoom,         ///< "static_room": no humans, xyz camera motion
  kWalkingStatic,      ///< "walking_static": walkers, near-static camera
  kWalkingXyz,         ///< "walking_xyz": walkers, translation along the camera axes
  kWalkingHalfsphere,  ///< "walking_halfsphere": walkers, camera on a half sphere
  kWalkingRpy,         ///< "walking_rpy": walkers, roll/pitch/yaw camera rotation
  kSittingStatic,      ///< "sitting_static": seated humans moving a little, static camera
  kSittingXyz,         ///< "sitting_xyz": seated humans, xyz camera motion
  /// Crowd stress scenarios (see synth_crowd.cpp): 3-6 people on routes with stops and turns,
  /// in view at frame 0, a handheld camera (smooth path + random-walk shake) and motion blur of
  /// the colour image along the image motion where it is large.
  kCrowdCross,     ///< "crowd_cross": 4 people, two crossing 0.7-1.4 m ahead, cut by the edges
  kCrowdBoard,     ///< "crowd_board": 3 people carrying a 1 x 0.7 m board, a box and a bag
  kCrowdStart,     ///< "crowd_start": 5 people, two standing close cover 30-70 % of frame 0
  kCrowdHandheld,  ///< "crowd_handheld": 4 people, fast handheld pans (strong motion blur)
};

/// Parses a scenario name (see Scenario). @throws ds3d::InvalidArgument listing the valid names.
[[nodiscard]] Scenario parse_scenario(std::string_view name);

/// True for the crowd_* stress scenarios.
[[nodiscard]] inline bool is_crowd(Scenario s) {
  return s == Scenario::kCrowdCross || s == Scenario::kCrowdBoard || s == Scenario::kCrowdStart ||
         s == Scenario::kCrowdHandheld;
}

/// The name of a scenario ("walking_xyz", ...).
[[nodiscard]] std::string scenario_name(Scenario s);

/// Generator settings.
struct SynthOptions {
  Scenario scenario = Scenario::kWalkingXyz;  ///< scene and camera motion
  int num_frames = 30;                        ///< frames, 1 ... 100000
  std::uint64_t seed = 1;                     ///< everything random derives from it
  /// 0 ... 4 (crowd_*: 3 ... 6); -1: 2 (0 for static_room; crowd_*: as listed in Scenario)
  int num_humans = -1;
  double fps = 30.0;                 ///< frame rate [Hz], (0, 1000]
  double start_time = 1700000000.0;  ///< stamp of frame 0 [s]
  /// Intrinsics (no distortion allowed); default TUM ROS 525/525/319.5/239.5, 640 x 480.
  PinholeCamera camera = PinholeCamera{};
  bool depth_noise = true;   ///< false: exact depth (still x depth_scale, rounded), no holes
  bool write_parts = false;  ///< also write per-pixel human id and part locations (see below)
  /// Room extent along world x (depth ahead of the camera), y (width) and z (height) [m]:
  /// x in [3.5, 12], y in [3, 12], z in [2.2, 5]. The default gives the original room, and with
  /// it and extra_furniture = 0 the frames are bit-identical to earlier versions.
  Eigen::Vector3d room_size = Eigen::Vector3d(4.5, 5.0, 2.8);
  /// Extra free-standing chairs (seat, back, four legs) and tables (top, four legs) at random
  /// positions and headings on the floor, 0 ... 12, kept 0.5 m from the walkers' paths and seats:
  /// clutter with legs and backs, the furniture a person detector must not mistake for people.
  /// Drawn from their own random stream, so the rest of the scene does not change with it.
  int extra_furniture = 0;
  /// Detector errors of detections_noisy.jsonl (written by generate_sequence when either is > 0):
  /// each visible person box is dropped with this probability per frame, in runs of a few frames
  /// (mean 5), [0, 0.8] ...
  double detection_miss = 0;
  /// ... and a false person box is put on a static surface (furniture or wall) with this
  /// probability per frame, [0, 1]. From a random stream of their own: the frames do not change.
  double detection_false = 0;
  void validate() const;  ///< throws ds3d::InvalidArgument naming the bad field
};

/// A humanoid's gravity-aligned oriented 3-D box (tight around its primitives) in the world.
struct HumanBox {
  int id = 0;                                        ///< 0 ... num_humans-1, stable over time
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  ///< box centre, world [m]
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  ///< extent along its local x (facing), y, z [m]
  double yaw = 0;                                  ///< heading about world z [rad]
  bool sitting = false;                            ///< seated (moves a little) or walking
  /// What the human carries (crowd scenarios): 0 nothing, 1 board, 2 box, 3 bag. The carried
  /// object counts as the human's (human_id, dynamic mask, this box); its part_id is 0.
  int carried = 0;
  int visible_pixels = 0;  ///< pixels of this human in the frame
};

/// One rendered frame.
struct SynthFrame {
  std::size_t index = 0;                                          ///< frame number
  double timestamp = 0;                                           ///< [s]
  Eigen::Isometry3d T_world_cam = Eigen::Isometry3d::Identity();  ///< ground-truth pose
  cv::Mat rgb;                                                    ///< CV_8UC3 BGR
  cv::Mat depth;                ///< CV_16UC1, camera.depth_scale units per metre, 0 = no depth
  cv::Mat depth_true;           ///< CV_32FC1 noiseless z [m], 0 where nothing was hit
  cv::Mat dynamic_mask;         ///< CV_8UC1: 255 where a human is seen, else 0
  cv::Mat human_id;             ///< CV_8UC1: 0 static, k+1 for human k
  cv::Mat part_id;              ///< CV_8UC1: 0 static, else body part 1..10 (see part_names())
  std::vector<HumanBox> boxes;  ///< every human, visible or not
  /// Length [px] of the motion blur applied to rgb (crowd scenarios only; 0: none).
  double blur_px = 0;
};

/// Body-part names for part_id values 1..10 (index 0 is "static").
[[nodiscard]] const std::vector<std::string>& part_names();

/// Intra-object part locations (Part-A2, Shi et al. 2020): for each human pixel with depth, its
/// position inside the human's box, normalised to [0, 1]^3 along the box's x, y, z axes.
/// @return CV_32FC3 image (0 where no human); uses depth_true.
[[nodiscard]] cv::Mat part_locations(const SynthFrame& frame, const PinholeCamera& camera);

/// A procedurally built scene; renders any frame on demand.
/// @note Deterministic: the same options give bit-identical frames. render() is const and safe
///       to call concurrently (one frame per thread). O(pixels + triangles) per frame.
class SyntheticScene {
 public:
  /// Builds the room, furniture, textures and humans from the options.
  /// @throws ds3d::InvalidArgument for bad options.
  explicit SyntheticScene(const SynthOptions& options);
  ~SyntheticScene();
  /// Moves the scene; the source is left empty (only destruction and assignment are valid).
  SyntheticScene(SyntheticScene&&) noexcept;
  /// Move assignment; the source is left empty.
  SyntheticScene& operator=(SyntheticScene&&) noexcept;
  SyntheticScene(const SyntheticScene&) = delete;
  SyntheticScene& operator=(const SyntheticScene&) = delete;

  [[nodiscard]] std::size_t size() const;               ///< options.num_frames
  [[nodiscard]] const SynthOptions& options() const;    ///< as given
  [[nodiscard]] double timestamp(std::size_t i) const;  ///< start_time + i / fps
  /// Camera pose at any time t [s] (the trajectory is analytic), camera-to-world.
  [[nodiscard]] Eigen::Isometry3d camera_pose(double t) const;
  /// Renders frame i. @throws ds3d::InvalidArgument for i >= size().
  [[nodiscard]] SynthFrame render(std::size_t i) const;

 private:
  struct Impl;
  Impl* impl_ = nullptr;
};

/// What generate_sequence() wrote.
struct SynthSummary {
  std::size_t frames = 0;          ///< frames written
  std::size_t dynamic_pixels = 0;  ///< total human pixels over all frames
  double render_seconds = 0;       ///< CPU time of the calling thread spent rendering (no PNG)
  double total_seconds = 0;        ///< wall time of the whole call
};

/// Writes a TUM-layout folder: rgb/TIME.png, depth/TIME.png (16-bit, x depth_scale), rgb.txt,
/// depth.txt, groundtruth.txt (100 Hz, analytic), camera.txt, mask/TIME.png (dynamic pixels,
/// 0/255), boxes.jsonl (one JSON object per frame: timestamp, frame, boxes[{id, center, size,
/// yaw, sitting, visible_pixels}]; crowd scenarios add "carried"), with detection_miss or
/// detection_false > 0 detections_noisy.jsonl (ds3d::DetectionsFile format: 3-D "corners" in the
/// camera frame, class "person", score 1, one line per frame), and with options.write_parts:
/// parts/TIME.png (CV_8UC3: B = human id (k+1), G = part id, R = 0) and parts_loc/TIME.png
/// (CV_16UC3, x y z location in the box x 65535); TIME is the frame's timestamp. Every file is
/// written to a temporary name and flushed to the device (fsync); the lists are written last.
/// The whole sequence goes into a hidden sibling folder (.NAME.tmpN) that is renamed to out_dir
/// at the end, so an interrupted run never leaves a half-written or mixed folder; an earlier
/// out_dir (with overwrite) is removed only once the new one is in place.
/// @param out_dir created if missing (with its parents); must be empty unless `overwrite`
/// @param options scenario, frames, seed, humans, fps, noise and parts (validated first)
/// @param overwrite replace a non-empty out_dir (e.g. an earlier sequence)
/// @throws ds3d::InvalidArgument for bad options; ds3d::IoError when out_dir is a file or a
///   non-empty folder without `overwrite` (naming it), or when writing fails.
SynthSummary generate_sequence(const std::filesystem::path& out_dir, const SynthOptions& options,
                               bool overwrite = false);

}  // namespace ds3d::synth
