// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// TUM trajectory reading/writing and ATE/RPE parity with the TUM benchmark scripts: every case in
// tests/data/trajectory/*/expected.json (copied from ../shared/fixtures/trajectory) must match.
#include "ds3d/eval/trajectory.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <string>
#include <tuple>
#include <vector>

#include "ds3d/eval/trajectory_metrics.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;
using ds3d::detail::JsonValue;

std::vector<std::string> fixture_cases() {
  std::vector<std::string> cases;
  for (const auto& e : fs::directory_iterator(ds3d::test::data_path("trajectory"))) {
    if (e.is_directory() && fs::exists(e.path() / "expected.json")) {
      cases.push_back(e.path().filename().string());
    }
  }
  std::sort(cases.begin(), cases.end());
  return cases;
}

// |got - expected| <= max(1e-9 |expected|, floor), the fixtures' rule.
::testing::AssertionResult within(const char* what, double got, double expected, double floor) {
  const double tol = std::max(1e-9 * std::abs(expected), floor);
  if (std::isfinite(got) && std::abs(got - expected) <= tol) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << what << ": got " << got << " expected " << expected << " (diff "
         << std::abs(got - expected) << ", tol " << tol << ")";
}

void expect_stats(const std::string& what, const ds3d::ErrorStats& got, const JsonValue& exp,
                  double floor) {
  EXPECT_TRUE(within((what + ".rmse").c_str(), got.rmse, exp.at("rmse").as_number(), floor));
  EXPECT_TRUE(within((what + ".mean").c_str(), got.mean, exp.at("mean").as_number(), floor));
  EXPECT_TRUE(within((what + ".median").c_str(), got.median, exp.at("median").as_number(), floor));
  EXPECT_TRUE(within((what + ".std").c_str(), got.std, exp.at("std").as_number(), floor));
  EXPECT_TRUE(within((what + ".min").c_str(), got.min, exp.at("min").as_number(), floor));
  EXPECT_TRUE(within((what + ".max").c_str(), got.max, exp.at("max").as_number(), floor));
}

std::vector<std::vector<double>> read_table(const fs::path& p) {
  std::vector<std::vector<double>> rows;
  for (const auto& line : ds3d::test::read_lines(p)) {
    if (line[0] == '#') continue;
    std::vector<double> row;
    const char* s = line.c_str();
    char* end = nullptr;
    for (double v = std::strtod(s, &end); end != s; v = std::strtod(s, &end)) {
      row.push_back(v);
      s = end;
    }
    rows.push_back(row);
  }
  return rows;
}

class TumFixture : public ::testing::TestWithParam<std::string> {
 protected:
  fs::path dir() const { return ds3d::test::data_path("trajectory/" + GetParam()); }
};

TEST_P(TumFixture, AteMatchesEvaluateAtePy) {
  const JsonValue exp = ds3d::test::read_json(dir() / "expected.json");
  const JsonValue& ate = exp.at("ate");
  // evaluate_ate.py reads positions only: zero quaternions do not drop a line.
  const auto gt = ds3d::read_tum_file(dir() / "groundtruth.txt", {.keep_zero_quaternion = true});
  const auto est = ds3d::read_tum_file(dir() / "estimate.txt", {.keep_zero_quaternion = true});
  EXPECT_EQ(gt.trajectory.size(), static_cast<std::size_t>(ate.at("n_gt_poses_read").as_int()));
  EXPECT_EQ(est.trajectory.size(), static_cast<std::size_t>(ate.at("n_est_poses_read").as_int()));

  const auto r = ds3d::evaluate_ate(gt.trajectory, est.trajectory);
  ASSERT_EQ(r.compared_pose_pairs,
            static_cast<std::size_t>(ate.at("compared_pose_pairs").as_int()));
  expect_stats("ate", r.stats(), ate, 1e-12);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(r.translation(i), ate.at("alignment").at("translation").at(i).as_number(), 1e-9);
    for (int j = 0; j < 3; ++j) {
      EXPECT_NEAR(r.rotation(i, j), ate.at("alignment").at("rotation").at(i).at(j).as_number(),
                  1e-9);
    }
  }
  const auto assoc = read_table(dir() / ate.at("associations_file").as_string());
  ASSERT_EQ(assoc.size(), r.matches.size());
  for (std::size_t k = 0; k < assoc.size(); ++k) {
    ASSERT_EQ(r.matches[k].t_gt, assoc[k][0]) << "match " << k;  // exact
    ASSERT_EQ(r.matches[k].t_est, assoc[k][1]) << "match " << k;
    EXPECT_TRUE(within("match error", r.matches[k].error, assoc[k][2], 1e-12)) << "match " << k;
  }
}

TEST_P(TumFixture, RpeMatchesEvaluateRpePy) {
  const JsonValue exp = ds3d::test::read_json(dir() / "expected.json");
  const auto gt = ds3d::read_tum_trajectory(dir() / "groundtruth.txt");
  const auto est = ds3d::read_tum_trajectory(dir() / "estimate.txt");
  std::size_t checked = 0;
  for (const auto& [key, block] : exp.at("rpe").as_object()) {
    SCOPED_TRACE(key);
    const JsonValue& s = block.at("settings");
    ds3d::RpeOptions opt;
    opt.fixed_delta = s.at("fixed_delta").as_bool();
    if (opt.fixed_delta) {
      opt.delta = s.at("delta").as_number();
      opt.delta_unit = ds3d::parse_delta_unit(s.at("delta_unit").as_string());
    }
    opt.max_pairs = static_cast<std::size_t>(s.at("max_pairs").as_int());
    ASSERT_FALSE(s.at("random_subsampling_triggered").as_bool());
    const auto r = ds3d::evaluate_rpe(gt, est, opt);
    EXPECT_FALSE(r.subsampled);
    ASSERT_EQ(r.compared_pose_pairs,
              static_cast<std::size_t>(block.at("compared_pose_pairs").as_int()));
    expect_stats("trans", r.translational, block.at("translational"), 1e-12);
    expect_stats("rot", r.rotational, block.at("rotational"), 1e-5);
    if (block.contains("pairs_file")) {
      const auto pairs = read_table(dir() / block.at("pairs_file").as_string());
      ASSERT_EQ(pairs.size(), r.pairs.size());
      for (std::size_t k = 0; k < pairs.size(); ++k) {
        const auto& p = r.pairs[k];
        ASSERT_EQ(p.t_est0, pairs[k][0]) << "pair " << k;
        ASSERT_EQ(p.t_est1, pairs[k][1]) << "pair " << k;
        ASSERT_EQ(p.t_gt0, pairs[k][2]) << "pair " << k;
        ASSERT_EQ(p.t_gt1, pairs[k][3]) << "pair " << k;
        EXPECT_TRUE(within("trans", p.trans_error, pairs[k][4], 1e-12)) << "pair " << k;
        EXPECT_TRUE(within("rot", p.rot_error_rad * 180 / std::numbers::pi,
                           pairs[k][5] * 180 / std::numbers::pi, 1e-5))
            << "pair " << k;
      }
    }
    if (block.contains("note_evo_error_convention_trans_rmse")) {
      opt.convention = ds3d::RpeConvention::kEvo;
      const auto evo = ds3d::evaluate_rpe(gt, est, opt);
      EXPECT_EQ(evo.compared_pose_pairs, r.compared_pose_pairs);
      EXPECT_TRUE(within("evo trans rmse", evo.translational.rmse,
                         block.at("note_evo_error_convention_trans_rmse").as_number(), 1e-12));
    }
    ++checked;
  }
  EXPECT_GE(checked, 2U);
}

INSTANTIATE_TEST_SUITE_P(Fixtures, TumFixture, ::testing::ValuesIn(fixture_cases()),
                         [](const ::testing::TestParamInfo<std::string>& p) { return p.param; });

TEST(TumFixtures, AllPresent) { EXPECT_GE(fixture_cases().size(), 13U); }

// ---- reading rules ---------------------------------------------------------------------------

TEST(ReadTum, ScriptLineRules) {
  const std::string text =
      "# comment\r\n"
      "\n"
      "3.0 1 2 3 0 0 0 1\r"            // lone CR ends a line
      "1.0,1,2,3,0,0,0,2\n"            // commas, non-unit quaternion
      "2.0\t1e-3\t2\t3\t0\t0\t0\t1\n"  // tabs and exponent
      "3.000 9 9 9 0 0 0 1\n"          // same stamp, later line wins
      "   \n"                          // only spaces: skipped
      "4.0 1_0 0 0 0 0 0 0\n"          // underscore digit grouping; zero quaternion
      "5.0 nan 0 0 0 0 0 1\n";         // NaN: skipped
  const auto r = ds3d::parse_tum_trajectory(text);
  ASSERT_EQ(r.trajectory.size(), 3U);
  EXPECT_EQ(r.num_duplicates, 1U);
  EXPECT_EQ(r.num_zero_quaternion, 1U);
  EXPECT_EQ(r.num_non_finite, 1U);
  EXPECT_EQ(r.first_zero_quaternion_line, 8U);  // line numbers for the tools' warnings
  EXPECT_EQ(r.first_non_finite_line, 9U);
  EXPECT_EQ(r.trajectory[0].timestamp, 1.0);
  EXPECT_TRUE(r.trajectory[0].T_world_cam.linear().isApprox(Eigen::Matrix3d::Identity(), 1e-15));
  EXPECT_EQ(r.trajectory[1].T_world_cam.translation().x(), 1e-3);
  EXPECT_EQ(r.trajectory[2].T_world_cam.translation().x(), 9.0);

  const auto keep = ds3d::parse_tum_trajectory(text, {.keep_zero_quaternion = true});
  ASSERT_EQ(keep.trajectory.size(), 4U);
  EXPECT_EQ(keep.trajectory[3].T_world_cam.translation().x(), 10.0);
}

// ds3d-eval says why poses are missing: one warning line per kind of skipped line.
TEST(ReadTum, Ds3dEvalWarnsAboutSkippedLines) {
  if (!std::filesystem::exists(ds3d::test::tool_path("ds3d-eval"))) GTEST_SKIP() << "not built";
  const auto dir =
      std::filesystem::temp_directory_path() / ("ds3d_eval_warn_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  std::string gt;
  std::string est;
  for (int i = 0; i < 10; ++i) {
    const std::string t = std::to_string(i) + ".0 " + std::to_string(0.1 * i) + " 0 0 ";
    gt += t + "0 0 0 1\n";
    est += t + (i < 8 ? "0 0 0 0\n" : "0 0 0 1\n");  // 8 zero quaternions
  }
  est += "10.0 nan 0 0 0 0 0 1\n11.0 1 2 3 0 0 0 inf\n";
  std::ofstream(dir / "gt.txt") << gt;
  std::ofstream(dir / "est.txt") << est;
  const auto r = ds3d::test::run_tool(
      "ds3d-eval", "rpe '" + (dir / "gt.txt").string() + "' '" + (dir / "est.txt").string() + "'");
  EXPECT_NE(r.output.find("est.txt: 2 of 12 line(s) skipped for a NaN or infinite value (first: "
                          "line 11)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("est.txt: 8 of 12 line(s) skipped for a 0 0 0 0 quaternion (first: "
                          "line 1;"),
            std::string::npos)
      << r.output;
  std::filesystem::remove_all(dir);
}

TEST(ReadTum, RejectsMalformedLinesNamingTheLine) {
  const auto throws_with = [](const std::string& text, const std::string& needle) {
    try {
      (void)ds3d::parse_tum_trajectory(text, {}, "f.txt");
    } catch (const ds3d::IoError& e) {
      return std::string(e.what()).find(needle) != std::string::npos;
    }
    return false;
  };
  EXPECT_TRUE(throws_with("1 2 3 4 5 6 7\n", "f.txt line 1"));               // 7 numbers
  EXPECT_TRUE(throws_with("1 2 3 4 5 6 7 8\nx 2 3 4 5 6 7 8\n", "line 2"));  // not a number
  EXPECT_TRUE(throws_with("0x10 2 3 4 5 6 7 8\n", "'0x10'"));                // hex (Python rejects)
  EXPECT_TRUE(throws_with(" # comment after a space\n", "line 1"));          // not a comment
  EXPECT_TRUE(throws_with("1. 2 3 4 5 6 7 1e\n", "'1e'"));
  EXPECT_THROW((void)ds3d::read_tum_trajectory("/nonexistent/ds3d/gt.txt"), ds3d::IoError);
}

TEST(ReadTum, PythonFloatGrammar) {
  using ds3d::detail::parse_py_float;
  EXPECT_EQ(parse_py_float("1e-3").value(), 1e-3);
  EXPECT_EQ(parse_py_float("+.5").value(), 0.5);
  EXPECT_EQ(parse_py_float("5.").value(), 5.0);
  EXPECT_EQ(parse_py_float("1_000.5").value(), 1000.5);
  EXPECT_TRUE(std::isinf(parse_py_float("-Infinity").value()));
  EXPECT_TRUE(std::isnan(parse_py_float("NaN").value()));
  for (const char* bad :
       {"", ".", "1__0", "_1", "1_", "0x1p3", "1e", "e5", "1.2.3", "--1", "infx"}) {
    EXPECT_FALSE(parse_py_float(bad).has_value()) << bad;
  }
}

TEST(WriteTum, RoundTripIsExactAndAtomic) {
  ds3d::Trajectory traj;
  for (int i = 0; i < 50; ++i) {
    ds3d::TimedPose p;
    p.timestamp = 1341846313.6433 + 0.0333 * i;
    p.T_world_cam.linear() =
        Eigen::AngleAxisd(0.1 * i, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    p.T_world_cam.translation() = Eigen::Vector3d(0.1 * i, -0.7, 1.0 / 3.0 * i);
    traj.push_back(p);
  }
  const fs::path dir = fs::temp_directory_path() / ("ds3d_traj_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  ds3d::write_tum_trajectory(dir / "t.txt", traj);
  const auto back = ds3d::read_tum_trajectory(dir / "t.txt");
  ASSERT_EQ(back.size(), traj.size());
  for (std::size_t i = 0; i < traj.size(); ++i) {
    EXPECT_EQ(back[i].timestamp, traj[i].timestamp);
    EXPECT_EQ(back[i].T_world_cam.translation(), traj[i].T_world_cam.translation());
    EXPECT_TRUE(back[i].T_world_cam.linear().isApprox(traj[i].T_world_cam.linear(), 1e-14));
  }
  std::size_t files = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++files;
  EXPECT_EQ(files, 1U);  // no temporary left behind
  EXPECT_THROW(ds3d::write_tum_trajectory(dir / "missing_dir" / "t.txt", traj), ds3d::IoError);
  traj[3].T_world_cam.translation().x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ds3d::write_tum_trajectory(dir / "nan.txt", traj), ds3d::InvalidArgument);
  EXPECT_FALSE(fs::exists(dir / "nan.txt"));
  fs::remove_all(dir);
}

// ---- metric behaviour beyond the fixtures -----------------------------------------------------

ds3d::Trajectory helix(int n, double dt, double t0 = 100.0) {
  ds3d::Trajectory t;
  for (int i = 0; i < n; ++i) {
    ds3d::TimedPose p;
    p.timestamp = t0 + dt * i;
    const double a = 0.05 * i;
    p.T_world_cam.linear() = Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    p.T_world_cam.translation() = Eigen::Vector3d(std::cos(a), std::sin(a), 0.01 * i);
    t.push_back(p);
  }
  return t;
}

TEST(Ate, RecoversRigidAndSimilarityTransforms) {
  const auto gt = helix(200, 0.01);
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -1, 2).normalized()).toRotationMatrix();
  x.translation() = Eigen::Vector3d(3, -2, 0.5);
  ds3d::Trajectory est = gt;
  for (auto& p : est) p.T_world_cam = x * p.T_world_cam;
  const auto r = ds3d::evaluate_ate(gt, est);
  EXPECT_EQ(r.compared_pose_pairs, 200U);
  EXPECT_LT(r.rmse, 1e-12);
  EXPECT_TRUE(r.rotation.isApprox(x.linear().transpose(), 1e-12));

  for (auto& p : est) p.T_world_cam.translation() *= 0.5;  // a monocular-like scale error
  EXPECT_GT(ds3d::evaluate_ate(gt, est).rmse, 0.1);
  const auto s = ds3d::evaluate_ate(gt, est, {.alignment = ds3d::Alignment::kSim3});
  EXPECT_LT(s.rmse, 1e-12);
  EXPECT_NEAR(s.scale_factor, 2.0, 1e-12);
  const auto none = ds3d::evaluate_ate(gt, gt, {.alignment = ds3d::Alignment::kNone});
  EXPECT_EQ(none.rmse, 0.0);
}

TEST(Ate, NonFinitePosesAreSkippedAndCounted) {
  auto gt = helix(100, 0.01);
  auto est = gt;
  est[10].T_world_cam.translation().y() = std::numeric_limits<double>::quiet_NaN();
  est[20].timestamp = std::numeric_limits<double>::infinity();
  const auto r = ds3d::evaluate_ate(gt, est);
  EXPECT_EQ(r.num_non_finite, 2U);
  EXPECT_EQ(r.compared_pose_pairs, 98U);
  EXPECT_TRUE(std::isfinite(r.rmse));
  for (const auto& m : r.matches) EXPECT_TRUE(m.p_est.allFinite());
}

// A finite position whose squares overflow (the trajectory fuzz target's self-ATE input
// "1.0 1e197 0 0 0 0 0 1"): named, never a NaN or inf statistic.
TEST(Ate, PositionsWhoseSquaresOverflowAreNamed) {
  auto t = helix(50, 0.01);
  t[5].T_world_cam.translation().x() = 1.25e197;
  for (const auto& [gt, est, who] : {std::tuple{helix(50, 0.01), t, "estimate"},
                                     std::tuple{t, helix(50, 0.01), "ground-truth"}}) {
    try {
      (void)ds3d::evaluate_ate(gt, est);
      FAIL() << "expected InvalidArgument";
    } catch (const ds3d::InvalidArgument& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(std::string(who) + " position coordinate 1.25e+197 at stamp"),
                std::string::npos)
          << what;
    }
    EXPECT_THROW(
        (void)ds3d::evaluate_rpe(gt, est, {.delta = 1, .delta_unit = ds3d::DeltaUnit::kFrames}),
        ds3d::InvalidArgument);
  }
}

TEST(Ate, RejectsBadOptionsAndNoOverlap) {
  const auto gt = helix(50, 0.01);
  EXPECT_THROW((void)ds3d::evaluate_ate(gt, gt, {.max_difference = -1}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_ate(gt, gt, {.scale = 0}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_ate(gt, gt, {.offset = std::nan("")}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_ate(gt, helix(50, 0.01, 500.0)), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_ate({}, {}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::parse_alignment("se2"), ds3d::InvalidArgument);
}

TEST(Ate, OffsetShiftsTheAssociation) {
  const auto gt = helix(100, 0.01);
  auto est = gt;
  for (auto& p : est) p.timestamp -= 0.5;
  EXPECT_EQ(ds3d::evaluate_ate(gt, est).compared_pose_pairs, 50U);  // only half overlaps
  const auto r = ds3d::evaluate_ate(gt, est, {.offset = 0.5});
  EXPECT_EQ(r.compared_pose_pairs, 100U);
  EXPECT_LT(r.rmse, 1e-9);
}

// ---- local ATE per window ---------------------------------------------------------------------

// 640 poses at 64 Hz (10 s, stamps exact in binary so no pose sits on a rounding boundary).
TEST(AteWindow, LocalDriftShowsInOneWindowOnly) {
  const auto gt = helix(640, 1.0 / 64);
  auto est = gt;
  for (int i = 256; i < 276; ++i) est[i].T_world_cam.translation().x() += 0.1;  // in [4 s, 5 s)
  const auto r = ds3d::evaluate_ate(gt, est, {.window = 1.0});
  ASSERT_EQ(r.windows.size(), 10U);
  EXPECT_EQ(r.num_short_windows, 0U);
  for (std::size_t k = 0; k < r.windows.size(); ++k) {
    const auto& w = r.windows[k];
    SCOPED_TRACE(k);
    EXPECT_EQ(w.pairs, 64U);
    EXPECT_EQ(w.start, 100.0 + static_cast<double>(k));
    EXPECT_EQ(w.end, 100.0 + static_cast<double>(k) + 63.0 / 64);
    EXPECT_TRUE(std::isfinite(w.rmse));
    if (k == 4) {
      EXPECT_GT(w.rmse, 0.03);  // 20 of 64 poses 0.1 m off: ~0.046 m after the local alignment
    } else {
      EXPECT_LT(w.rmse, 1e-9);
    }
  }
  EXPECT_EQ(r.worst_window_rmse, r.windows[4].rmse);
  EXPECT_GT(r.worst_window_rmse, 2 * r.rmse);  // the global figure smears the drift out
}

TEST(AteWindow, OneLongWindowEqualsTheGlobalAte) {
  const auto gt = helix(300, 0.01);
  auto est = gt;
  Eigen::Isometry3d x = Eigen::Isometry3d::Identity();
  x.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  x.translation() = Eigen::Vector3d(1, 2, -1);
  for (std::size_t i = 0; i < est.size(); ++i) {
    est[i].T_world_cam = x * est[i].T_world_cam;
    est[i].T_world_cam.translation() *= 0.8;
    est[i].T_world_cam.translation().y() += 0.02 * std::sin(0.37 * static_cast<double>(i));
  }
  for (const auto a : {ds3d::Alignment::kSE3, ds3d::Alignment::kSim3, ds3d::Alignment::kNone}) {
    SCOPED_TRACE(static_cast<int>(a));
    const auto r = ds3d::evaluate_ate(gt, est, {.alignment = a, .window = 1000.0});
    ASSERT_EQ(r.windows.size(), 1U);
    EXPECT_EQ(r.windows[0].pairs, r.compared_pose_pairs);
    EXPECT_EQ(r.windows[0].start, r.matches.front().t_gt);
    EXPECT_EQ(r.windows[0].end, r.matches.back().t_gt);
    EXPECT_NEAR(r.windows[0].rmse, r.rmse, 1e-9 * r.rmse);
    EXPECT_EQ(r.worst_window_rmse, r.windows[0].rmse);
  }
}

TEST(AteWindow, ShortWindowsAreSkippedAndCounted) {
  // windows of 1 s: [0,1) 4 pairs, [1,2) 1, [2,3) 2, [3,4) 3, [4,6) empty (not counted), [6,7) 3
  const std::vector<double> stamps = {0,   0.25, 0.5, 0.75, 1.25, 2.0, 2.5,
                                      3.0, 3.25, 3.5, 6.0,  6.5,  6.75};
  ds3d::Trajectory gt;
  for (const double t : stamps) {
    ds3d::TimedPose p;
    p.timestamp = t;
    p.T_world_cam.translation() = Eigen::Vector3d(std::cos(t), std::sin(2 * t), 0.1 * t * t);
    gt.push_back(p);
  }
  auto est = gt;
  for (auto& p : est) p.T_world_cam.translation().z() += 0.01 * std::cos(5 * p.timestamp);
  const auto r = ds3d::evaluate_ate(gt, est, {.window = 1.0});
  ASSERT_EQ(r.windows.size(), 3U);
  EXPECT_EQ(r.num_short_windows, 2U);
  EXPECT_EQ(r.windows[0].pairs, 4U);
  EXPECT_EQ(r.windows[0].start, 0.0);
  EXPECT_EQ(r.windows[0].end, 0.75);
  EXPECT_EQ(r.windows[1].pairs, 3U);
  EXPECT_EQ(r.windows[1].start, 3.0);
  EXPECT_EQ(r.windows[1].end, 3.5);
  EXPECT_EQ(r.windows[2].start, 6.0);
  double worst = 0;
  for (const auto& w : r.windows) {
    EXPECT_TRUE(std::isfinite(w.rmse));
    worst = std::max(worst, w.rmse);
  }
  EXPECT_EQ(r.worst_window_rmse, worst);
  // the same through the free function; window 0 is off
  const auto direct = ds3d::ate_windows(r, 1.0, ds3d::Alignment::kSE3);
  ASSERT_EQ(direct.windows.size(), 3U);
  EXPECT_EQ(direct.windows[2].rmse, r.windows[2].rmse);
  const auto off = ds3d::evaluate_ate(gt, est);
  EXPECT_TRUE(off.windows.empty());
  EXPECT_EQ(off.worst_window_rmse, 0.0);
  EXPECT_EQ(off.num_short_windows, 0U);
  EXPECT_TRUE(ds3d::ate_windows(r, 0.0, ds3d::Alignment::kSE3).windows.empty());
  // every window short: no window, worst 0
  const auto tiny = ds3d::evaluate_ate(gt, est, {.window = 0.1});
  EXPECT_TRUE(tiny.windows.empty());
  EXPECT_EQ(tiny.num_short_windows, stamps.size());
  EXPECT_EQ(tiny.worst_window_rmse, 0.0);
}

TEST(AteWindow, RejectsBadWindow) {
  const auto gt = helix(50, 0.01);
  for (const double w : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    try {
      (void)ds3d::evaluate_ate(gt, gt, {.window = w});
      ADD_FAILURE() << "no throw for window " << w;
    } catch (const ds3d::InvalidArgument& e) {
      EXPECT_NE(std::string(e.what()).find("window"), std::string::npos) << e.what();
    }
  }
  const auto r = ds3d::evaluate_ate(gt, gt);
  EXPECT_THROW((void)ds3d::ate_windows(r, -0.5, ds3d::Alignment::kSE3), ds3d::InvalidArgument);
}

TEST(Associate, GreedyOneToOneNotNearestNeighbour) {
  // 2.0 is the nearest first-stamp of both 2.004 and 2.005: greedy gives it to 2.004 (0.004)
  // and 2.005 then takes 2.01 (0.005).
  const auto m = ds3d::associate_timestamps({1.99, 2.0, 2.01}, {2.004, 2.005}, 0.0, 0.02);
  ASSERT_EQ(m.size(), 2U);
  EXPECT_EQ(m[0], std::make_pair(std::size_t{1}, std::size_t{0}));
  EXPECT_EQ(m[1], std::make_pair(std::size_t{2}, std::size_t{1}));
  EXPECT_THROW((void)ds3d::associate_timestamps({2, 1}, {1}, 0, 0.02), ds3d::InvalidArgument);
}

TEST(Rpe, PerfectEstimateHasZeroErrorForEveryUnit) {
  const auto gt = helix(300, 1.0 / 30);
  for (const char* unit : {"s", "f", "m", "rad", "deg"}) {
    ds3d::RpeOptions o;
    o.delta_unit = ds3d::parse_delta_unit(unit);
    o.delta = std::string(unit) == "deg" ? 5.0 : 0.3;
    const auto r = ds3d::evaluate_rpe(gt, gt, o);
    EXPECT_GT(r.compared_pose_pairs, 100U) << unit;
    EXPECT_LT(r.translational.max, 1e-12) << unit;
    EXPECT_LT(r.rotational.max, 1e-5) << unit;
  }
}

TEST(Rpe, SubsamplingIsSeededAndBounded) {
  const auto gt = helix(300, 1.0 / 30);
  auto est = gt;
  for (std::size_t i = 0; i < est.size(); ++i)
    est[i].T_world_cam.translation().x() += 1e-3 * static_cast<double>(i % 7);
  ds3d::RpeOptions o;
  o.fixed_delta = false;
  o.max_pairs = 500;
  const auto a = ds3d::evaluate_rpe(gt, est, o);
  const auto b = ds3d::evaluate_rpe(gt, est, o);
  EXPECT_TRUE(a.subsampled);
  EXPECT_LE(a.compared_pose_pairs, 500U);
  EXPECT_EQ(a.translational.rmse, b.translational.rmse);
}

TEST(Rpe, RejectsBadInput) {
  const auto gt = helix(50, 0.01);
  EXPECT_THROW((void)ds3d::parse_delta_unit("km"), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_rpe(gt, gt, {.delta = std::nan("")}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_rpe(gt, {gt[0]}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::evaluate_rpe(gt, helix(50, 0.01, 1000.0)), ds3d::InvalidArgument);
}

}  // namespace

namespace {

// DynaSLAM's own trajectories and the numbers its authors' run of the TUM scripts printed
// (../shared/data/tum_fr3_dynamic_groundtruth): numbers nobody here made. Skipped without data.
std::map<std::string, double> printed_numbers(const fs::path& p) {
  std::map<std::string, double> out;
  for (const auto& line : ds3d::test::read_lines(p)) {
    char name[128];
    double v = 0;
    if (std::sscanf(line.c_str(), "%127s %lf", name, &v) == 2) out[name] = v;
  }
  return out;
}

TEST(RealData, DynaSlamTrajectoriesGiveThePrintedAteAndRpe) {
  const fs::path root = ds3d::test::shared_data_dir();
  if (root.empty() || !fs::exists(root / "tum_fr3_dynamic_groundtruth")) GTEST_SKIP() << "no data";
  const fs::path dir = root / "tum_fr3_dynamic_groundtruth";
  std::size_t checked = 0;
  for (const char* seq : {"fr3_sitting_static", "fr3_walk_halfsphere", "fr3_walk_rpy",
                          "fr3_walk_static", "fr3_walk_xyz"}) {
    SCOPED_TRACE(seq);
    const fs::path res = dir / "dynaslam_results" / seq;
    const fs::path ate_file = res / (std::string(seq) + "_ate_0.txt");
    if (!fs::exists(ate_file)) continue;
    const fs::path gt_file = dir / (std::string(seq) + ".txt");
    const auto gt = ds3d::read_tum_file(gt_file, {.keep_zero_quaternion = true}).trajectory;
    const auto est =
        ds3d::read_tum_file(res / "CameraTrajectory_0.txt", {.keep_zero_quaternion = true})
            .trajectory;
    const auto ate = ds3d::evaluate_ate(gt, est);
    auto want = printed_numbers(ate_file);
    EXPECT_EQ(static_cast<double>(ate.compared_pose_pairs), want["compared_pose_pairs"]);
    EXPECT_NEAR(ate.rmse, want["absolute_translational_error.rmse"], 6e-7);
    EXPECT_NEAR(ate.mean, want["absolute_translational_error.mean"], 6e-7);
    EXPECT_NEAR(ate.median, want["absolute_translational_error.median"], 6e-7);
    EXPECT_NEAR(ate.max, want["absolute_translational_error.max"], 6e-7);
    const fs::path rpe_file = res / (std::string(seq) + "_rpe_0.txt");
    if (fs::exists(rpe_file)) {
      const auto rpe =
          ds3d::evaluate_rpe(ds3d::read_tum_trajectory(gt_file),
                             ds3d::read_tum_trajectory(res / "CameraTrajectory_0.txt"));
      want = printed_numbers(rpe_file);
      EXPECT_EQ(static_cast<double>(rpe.compared_pose_pairs), want["compared_pose_pairs"]);
      EXPECT_NEAR(rpe.translational.rmse, want["translational_error.rmse"], 6e-7);
      EXPECT_NEAR(rpe.translational.max, want["translational_error.max"], 6e-7);
      EXPECT_NEAR(rpe.rotational.rmse, want["rotational_error.rmse"], 6e-7);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 5U);
}

}  // namespace
