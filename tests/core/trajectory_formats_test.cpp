// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// KITTI and EuRoC trajectories: reading hand-written files, errors naming file and line, format
// detection, round trips, and ds3d-eval's --format/--timestamps options and convert command.
#include "ds3d/eval/trajectory_formats.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ds3d/detail/json.hpp"
#include "ds3d/eval/trajectory_frames.hpp"
#include "ds3d/eval/trajectory_metrics.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

// GCC 12 -O3 reports a false -Wrestrict inside std::string's operator+ as inlined here.
#pragma GCC diagnostic ignored "-Wrestrict"

namespace {

namespace fs = std::filesystem;
using ds3d::TrajectoryFormat;

// A curved path with a turning camera, 40 poses at 10 Hz from t = 1.5 s (exact in binary).
ds3d::Trajectory curve() {
  ds3d::Trajectory out;
  for (int i = 0; i < 40; ++i) {
    ds3d::TimedPose p;
    p.timestamp = 1.5 + 0.125 * i;
    p.T_world_cam.linear() = (Eigen::AngleAxisd(0.05 * i, Eigen::Vector3d::UnitZ()) *
                              Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()))
                                 .toRotationMatrix();
    p.T_world_cam.translation() = Eigen::Vector3d(std::cos(0.1 * i), std::sin(0.1 * i), 0.01 * i);
    out.push_back(p);
  }
  return out;
}

void expect_same_poses(const ds3d::Trajectory& a, const ds3d::Trajectory& b, double t_tol) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_NEAR(a[i].timestamp, b[i].timestamp, t_tol) << i;
    EXPECT_TRUE(a[i].T_world_cam.matrix().isApprox(b[i].T_world_cam.matrix(), 1e-12)) << i;
  }
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::exception& e) {
    return e.what();
  }
  return "";
}

TEST(KittiFormat, ReadsPosesWithIndexOrListedTimestamps) {
  const std::string text =
      "1 0 0 0 0 1 0 0 0 0 1 0\n"
      "0 -1 0 1.5 1 0 0 -2 0 0 1 0.25\n"  // 90 degrees about z
      "\n"
      "1,0,0,3\t0 1 0 0 0 0 1 0\n";  // ',' and TAB separate like ' '
  auto r = ds3d::parse_kitti_trajectory(text);
  ASSERT_EQ(r.trajectory.size(), 3U);
  EXPECT_EQ(r.num_lines, 3U);
  EXPECT_EQ(r.trajectory[0].timestamp, 0.0);
  EXPECT_EQ(r.trajectory[2].timestamp, 2.0);
  EXPECT_TRUE(r.trajectory[1].T_world_cam.translation().isApprox(Eigen::Vector3d(1.5, -2, 0.25)));
  EXPECT_TRUE(r.trajectory[1].T_world_cam.linear().isApprox(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-15));
  EXPECT_EQ(r.trajectory[2].T_world_cam.translation().x(), 3.0);
  const std::vector<double> stamps{10.0, 10.5, 11.0};
  r = ds3d::parse_kitti_trajectory(text, &stamps);
  EXPECT_EQ(r.trajectory[1].timestamp, 10.5);
  EXPECT_EQ(ds3d::parse_timestamp_list("# times\n10\n1.05e1 x\n11.0\n"),
            (std::vector<double>{10.0, 10.5, 11.0}));
}

TEST(KittiFormat, ErrorsNameTheFileAndLine) {
  const auto err = [](const std::string& text, const std::vector<double>* t = nullptr) {
    return error_of([&] { (void)ds3d::parse_kitti_trajectory(text, t, "poses.txt"); });
  };
  EXPECT_EQ(err("1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1\n"),
            "ds3d::read_kitti_trajectory: poses.txt line 2: expected 12 numbers (a 3x4 row-major "
            "pose [R | t]), got 11");
  EXPECT_NE(err("1 0 0 0 0 1 0 0 0 0 1 abc\n").find("poses.txt line 1: 'abc' is not a number"),
            std::string::npos);
  EXPECT_NE(
      err("\n2 0 0 0 0 1 0 0 0 0 1 0\n").find("poses.txt line 2: the 3x3 part is not a rotation"),
      std::string::npos);
  EXPECT_NE(err("-1 0 0 0 0 1 0 0 0 0 1 0\n").find("not a rotation"), std::string::npos);
  const std::vector<double> two{1, 2};
  EXPECT_EQ(err("1 0 0 0 0 1 0 0 0 0 1 0\n", &two),
            "ds3d::read_kitti_trajectory: poses.txt: 1 pose lines but 2 timestamps");
  EXPECT_NE(error_of([] {
              (void)ds3d::parse_timestamp_list("1\nnan\n", "times.txt");
            }).find("times.txt line 2: 'nan' is not a finite number"),
            std::string::npos);
  // A NaN pose is skipped and counted, as in TUM files.
  const auto r =
      ds3d::parse_kitti_trajectory("1 0 0 nan 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_EQ(r.trajectory.size(), 1U);
  EXPECT_EQ(r.trajectory[0].timestamp, 1.0);
  EXPECT_EQ(r.num_non_finite, 1U);
  EXPECT_EQ(r.first_non_finite_line, 1U);
}

TEST(EurocFormat, ReadsGroundTruthCsvWithExtraColumns) {
  // EuRoC's state_groundtruth_estimate0/data.csv: 17 columns, w first.
  const std::string text =
      "#timestamp,p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],q_RS_y [],q_RS_z [],"
      "v_RS_R_x [m s^-1],v_RS_R_y [m s^-1],v_RS_R_z [m s^-1],b_w_RS_S_x [rad s^-1],"
      "b_w_RS_S_y [rad s^-1],b_w_RS_S_z [rad s^-1],b_a_RS_S_x [m s^-2],b_a_RS_S_y [m s^-2],"
      "b_a_RS_S_z [m s^-2]\n"
      "1403636580013555456,4.688319,-1.786938,0.783338,0.7071067811865476,0,0,0.7071067811865476,"
      "-0.027876,0.033207,0.800006,-0.003172,0.021267,0.078502,-0.025266,0.136696,0.075593\n"
      "1403636579758555392,4.6,-1.7,0.7,1,0,0,0,0,0,0,0,0,0,0,0,0\r\n";
  const auto r = ds3d::parse_euroc_trajectory(text);
  ASSERT_EQ(r.trajectory.size(), 2U);  // sorted by time
  EXPECT_EQ(r.trajectory[0].timestamp, 1403636579.758555392);
  EXPECT_EQ(r.trajectory[1].timestamp, 1403636580.013555456);
  EXPECT_TRUE(r.trajectory[1].T_world_cam.translation().isApprox(
      Eigen::Vector3d(4.688319, -1.786938, 0.783338)));
  EXPECT_TRUE(r.trajectory[1].T_world_cam.linear().isApprox(
      Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-15));
  EXPECT_TRUE(r.trajectory[0].T_world_cam.linear().isIdentity());
  EXPECT_EQ(ds3d::detect_trajectory_format("data.txt", text), TrajectoryFormat::kEuroc);

  const auto err = [](const std::string& t) {
    return error_of([&] { (void)ds3d::parse_euroc_trajectory(t, {}, "data.csv"); });
  };
  EXPECT_EQ(err("#timestamp\n1,2,3,4,1,0,0\n"),
            "ds3d::read_euroc_trajectory: data.csv line 2: expected at least 8 values 'timestamp "
            "[ns], px, py, pz [m], qw, qx, qy, qz', got 7");
  EXPECT_NE(err("1,2,3,4,1,0,0,zero\n").find("data.csv line 1: 'zero' is not a number"),
            std::string::npos);
  // A 0 0 0 0 quaternion is skipped unless kept (as for TUM).
  EXPECT_EQ(ds3d::parse_euroc_trajectory("1,2,3,4,0,0,0,0\n").num_zero_quaternion, 1U);
  EXPECT_EQ(ds3d::parse_euroc_trajectory("1,2,3,4,0,0,0,0\n", {.keep_zero_quaternion = true})
                .trajectory.size(),
            1U);
}

TEST(TrajectoryFormats, DetectsByExtensionAndContent) {
  using ds3d::detect_trajectory_format;
  EXPECT_EQ(detect_trajectory_format("a.CSV", "1 2 3 4 5 6 7 8\n"), TrajectoryFormat::kEuroc);
  EXPECT_EQ(detect_trajectory_format("a.txt", "# poses\n1 0 0 0 0 1 0 0 0 0 1 0\n"),
            TrajectoryFormat::kKitti);
  EXPECT_EQ(detect_trajectory_format("a.txt", "1000,1,2,3,1,0,0,0\n"), TrajectoryFormat::kEuroc);
  EXPECT_EQ(detect_trajectory_format("a.txt", "1.5,1,2,3,0,0,0,1\n"), TrajectoryFormat::kTum);
  EXPECT_EQ(
      detect_trajectory_format("a.txt", "# timestamp tx ty tz qx qy qz qw\n1 1 2 3 0 0 0 1\n"),
      TrajectoryFormat::kTum);
  EXPECT_EQ(detect_trajectory_format("a.txt", ""), TrajectoryFormat::kTum);
  EXPECT_EQ(ds3d::parse_trajectory_format("kitti"), TrajectoryFormat::kKitti);
  EXPECT_EQ(error_of([] { (void)ds3d::parse_trajectory_format("csv"); }),
            "ds3d::parse_trajectory_format: format must be tum, kitti or euroc (got 'csv')");
  // Every TUM fixture is detected as TUM and read exactly as read_tum_file() reads it.
  for (const auto& dir : fs::directory_iterator(ds3d::test::data_path("trajectory"))) {
    for (const char* name : {"groundtruth.txt", "estimate.txt"}) {
      const fs::path p = dir.path() / name;
      if (!fs::exists(p)) continue;
      SCOPED_TRACE(p.string());
      const auto r = ds3d::read_trajectory(p);
      EXPECT_EQ(r.format, TrajectoryFormat::kTum);
      const auto want = ds3d::read_tum_file(p);
      EXPECT_EQ(ds3d::format_tum_trajectory(r.trajectory),
                ds3d::format_tum_trajectory(want.trajectory));
    }
  }
}

TEST(TrajectoryFormats, RoundTrips) {
  const auto traj = curve();
  const fs::path dir = fs::temp_directory_path() / ("ds3d_formats_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::vector<double> stamps;
  for (const auto& p : traj) stamps.push_back(p.timestamp);
  for (const auto f :
       {TrajectoryFormat::kTum, TrajectoryFormat::kKitti, TrajectoryFormat::kEuroc}) {
    SCOPED_TRACE(ds3d::to_string(f));
    const fs::path p = dir / (std::string("t.") + (f == TrajectoryFormat::kEuroc ? "csv" : "txt"));
    ds3d::write_trajectory(p, traj, f);
    const auto r = ds3d::read_trajectory(p, {.kitti_timestamps = stamps});
    EXPECT_EQ(r.format, f);  // detected
    expect_same_poses(r.trajectory, traj, 0.0);
    // Written again and read back: the same poses (quaternion <-> matrix changes last bits only).
    const fs::path q = dir / (std::string("u.") + (f == TrajectoryFormat::kEuroc ? "csv" : "txt"));
    ds3d::write_trajectory(q, r.trajectory, f);
    expect_same_poses(ds3d::read_trajectory(q, {.kitti_timestamps = stamps}).trajectory, traj, 0.0);
  }
  // EuRoC nanoseconds survive a round trip to the double's spacing.
  const std::string csv = "#timestamp [ns],x\n1403636579758555392,1,2,3,1,0,0,0\n";
  const auto back = ds3d::format_euroc_trajectory(ds3d::parse_euroc_trajectory(csv).trajectory);
  const std::string line = back.substr(back.find('\n') + 1);
  EXPECT_LE(std::abs(std::stoll(line.substr(0, line.find(','))) - 1403636579758555392LL), 240);
  EXPECT_EQ(line.substr(line.find(',')), ",1,2,3,1,0,0,0\n");
  ds3d::Trajectory bad(1);
  bad[0].timestamp = 1e10;
  EXPECT_THROW((void)ds3d::format_euroc_trajectory(bad), ds3d::InvalidArgument);
  bad[0].timestamp = NAN;
  EXPECT_THROW((void)ds3d::format_kitti_trajectory(bad), ds3d::InvalidArgument);
  fs::remove_all(dir);
}

// ds3d-eval reads any format (detected or --format), takes --timestamps for KITTI, and converts.
TEST(TrajectoryFormats, Ds3dEvalReadsAndConverts) {
  if (!fs::exists(ds3d::test::tool_path("ds3d-eval"))) GTEST_SKIP() << "ds3d-eval not built";
  const fs::path dir =
      fs::temp_directory_path() / ("ds3d_formats_cli_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto gt = curve();
  auto est = gt;
  for (std::size_t i = 0; i < est.size(); ++i)
    est[i].T_world_cam.translation().y() += 0.01 * static_cast<double>(i % 3);
  ds3d::write_tum_trajectory(dir / "gt.txt", gt);
  ds3d::write_trajectory(dir / "est.csv", est, TrajectoryFormat::kEuroc);
  ds3d::write_trajectory(dir / "est.kitti", est, TrajectoryFormat::kKitti);
  {
    std::ofstream t(dir / "times.txt");
    for (const auto& p : gt) t << p.timestamp << "\n";
  }
  const std::string d = "'" + dir.string() + "/";
  const auto tum =
      ds3d::test::run_tool("ds3d-eval", "ate " + d + "gt.txt' " + d + "est.csv' --json");
  ASSERT_EQ(tum.code, 0) << tum.output;
  const auto want = ds3d::evaluate_ate(gt, est);
  EXPECT_NEAR(ds3d::detail::parse_json(tum.output).at("rmse").as_number(), want.rmse, 1e-12);
  EXPECT_EQ(ds3d::detail::parse_json(tum.output).at("compared_pose_pairs").as_int(), 40);
  auto r = ds3d::test::run_tool("ds3d-eval", "rpe " + d + "gt.txt' " + d +
                                                 "est.kitti' --est-format kitti --timestamps " + d +
                                                 "times.txt' --json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(ds3d::detail::parse_json(r.output).at("compared_pose_pairs").as_int(),
            static_cast<std::int64_t>(ds3d::evaluate_rpe(gt, est).compared_pose_pairs));
  EXPECT_NEAR(ds3d::detail::parse_json(r.output).at("translational").at("rmse").as_number(),
              ds3d::evaluate_rpe(gt, est).translational.rmse, 1e-12);
  // Without --timestamps the KITTI stamps are 0, 1, ..., 39: 5 of them (2 .. 6 s) meet the
  // ground truth's (1.5 .. 6.375 s every 0.125 s).
  r = ds3d::test::run_tool("ds3d-eval",
                           "ate " + d + "gt.txt' " + d + "est.kitti' --est-format kitti");
  EXPECT_EQ(r.output.rfind("compared_pose_pairs 5 pairs\n", 0), 0U) << r.output;
  // Bad names and bad lines are named.
  r = ds3d::test::run_tool("ds3d-eval", "ate " + d + "gt.txt' " + d + "est.csv' --format csv");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.output, "ds3d-eval: error: --format must be tum, kitti or euroc (got 'csv')\n");
  std::ofstream(dir / "broken.csv") << "#timestamp [ns]\n1,2,3,4,1,0,0,0\n5,6\n";
  r = ds3d::test::run_tool("ds3d-eval", "ate " + d + "gt.txt' " + d + "broken.csv'");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.output.find((dir / "broken.csv").string() + " line 3: expected at least 8 values"),
            std::string::npos)
      << r.output;
  // convert: EuRoC -> KITTI -> TUM (with the stamps back), and the format from OUT's extension.
  r = ds3d::test::run_tool("ds3d-eval", "convert " + d + "est.csv' " + d + "k.txt' --to kitti");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output, "40 poses written to " + (dir / "k.txt").string() + " (kitti)\n");
  r = ds3d::test::run_tool(
      "ds3d-eval", "convert " + d + "k.txt' " + d + "t.txt' --timestamps " + d + "times.txt'");
  ASSERT_EQ(r.code, 0) << r.output;
  expect_same_poses(ds3d::read_tum_trajectory(dir / "t.txt"), est, 1e-6);
  r = ds3d::test::run_tool("ds3d-eval", "convert " + d + "t.txt' " + d + "e.csv'");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(ds3d::read_trajectory(dir / "e.csv").format, TrajectoryFormat::kEuroc);
  expect_same_poses(ds3d::read_trajectory(dir / "e.csv").trajectory, est, 1e-6);
  // --bonn-camera: the library's marker-to-camera transform; refused by ate.
  r = ds3d::test::run_tool("ds3d-eval", "convert " + d + "gt.txt' " + d + "cam.txt' --bonn-camera");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output, "40 poses written to " + (dir / "cam.txt").string() +
                          " (tum, Bonn marker poses -> camera poses)\n");
  expect_same_poses(ds3d::read_tum_trajectory(dir / "cam.txt"), ds3d::bonn_marker_to_camera(gt),
                    1e-9);
  r = ds3d::test::run_tool("ds3d-eval", "ate " + d + "gt.txt' " + d + "est.csv' --bonn-camera");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.output.find("unknown option '--bonn-camera' for ate"), std::string::npos) << r.output;
  fs::remove_all(dir);
}

}  // namespace
