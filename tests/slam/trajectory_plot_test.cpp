// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The ATE plot, and the ds3d-eval CLI against the TUM scripts' printed output of every fixture;
// the local ATE windows in both.
#include "ds3d/slam/trajectory_plot.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/detail/json.hpp"
#include "support/cli.hpp"
#include "support/files.hpp"

namespace {

namespace fs = std::filesystem;

fs::path fixture(const std::string& c) { return ds3d::test::data_path("trajectory/" + c); }

TEST(AtePlot, DrawsBothPanels) {
  const auto gt = ds3d::read_tum_trajectory(fixture("walking_xyz_basic") / "groundtruth.txt");
  const auto est = ds3d::read_tum_trajectory(fixture("walking_xyz_basic") / "estimate.txt");
  const auto r = ds3d::evaluate_ate(gt, est);
  const cv::Mat img = ds3d::render_ate_plot(gt, r, {.width = 1000, .height = 500, .title = "t"});
  ASSERT_EQ(img.cols, 1000);
  ASSERT_EQ(img.rows, 500);
  // both halves carry drawing (not blank)
  cv::Mat gray;
  cv::cvtColor(img, gray, cv::COLOR_BGR2GRAY);
  EXPECT_GT(cv::countNonZero(gray(cv::Rect(0, 60, 500, 440)) < 200), 2000);
  EXPECT_GT(cv::countNonZero(gray(cv::Rect(500, 60, 500, 440)) < 200), 2000);
  const fs::path out =
      fs::temp_directory_path() / ("ds3d_plot_" + std::to_string(::getpid()) + ".png");
  ds3d::write_ate_plot(out, gt, r);
  EXPECT_EQ(cv::imread(out.string()).cols, 1400);
  fs::remove(out);
  EXPECT_THROW((void)ds3d::render_ate_plot(gt, r, {.width = 10}), ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::render_ate_plot(gt, ds3d::AteResult{}), ds3d::InvalidArgument);
}

// 10 s at 64 Hz along a curve; the estimate equals it except 20 poses 0.1 m off in [4 s, 5 s).
std::pair<ds3d::Trajectory, ds3d::Trajectory> drift_pair() {
  ds3d::Trajectory gt;
  for (int i = 0; i < 640; ++i) {
    ds3d::TimedPose p;
    p.timestamp = 100.0 + i / 64.0;
    const double a = 0.01 * i;
    p.T_world_cam.translation() = Eigen::Vector3d(std::cos(a), std::sin(a), 0.002 * i);
    gt.push_back(p);
  }
  auto est = gt;
  for (int i = 256; i < 276; ++i) est[i].T_world_cam.translation().x() += 0.1;
  return {gt, est};
}

TEST(AtePlot, DrawsTheWindows) {
  const auto pair = drift_pair();
  const ds3d::Trajectory& gt = pair.first;
  const ds3d::Trajectory& est = pair.second;
  const auto count_magenta = [&](const ds3d::AteResult& r) {
    const cv::Mat img = ds3d::render_ate_plot(gt, r, {.width = 1000, .height = 500});
    cv::Mat mask;
    cv::inRange(img(cv::Rect(500, 60, 500, 440)), cv::Scalar(190, 0, 190), cv::Scalar(210, 10, 210),
                mask);
    return cv::countNonZero(mask);
  };
  EXPECT_EQ(count_magenta(ds3d::evaluate_ate(gt, est)), 0);
  EXPECT_GT(count_magenta(ds3d::evaluate_ate(gt, est, {.window = 1.0})), 300);
}

// One estimate position of 1e197 m is finite, but its squared error overflows: the metrics
// name it instead of reporting rmse inf, and the plot never indexes its colour ramp with NaN.
TEST(AtePlot, HugeFinitePositionsAreRejectedNotPlotted) {
  auto [gt, est] = drift_pair();
  est[300].T_world_cam.translation().x() = 1.25e197;
  try {
    (void)ds3d::evaluate_ate(gt, est);
    FAIL() << "expected InvalidArgument";
  } catch (const ds3d::InvalidArgument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("ds3d::evaluate_ate: rmse is not finite"), std::string::npos) << what;
    EXPECT_NE(what.find("estimate position coordinate 1.25e+197"), std::string::npos) << what;
  }
  EXPECT_THROW((void)ds3d::evaluate_rpe(gt, est), ds3d::InvalidArgument);
  // A result with non-finite statistics is refused; NaN or huge per-match values still draw.
  ds3d::AteResult r = ds3d::evaluate_ate(gt, drift_pair().second);
  r.matches[10].error = std::numeric_limits<double>::quiet_NaN();
  r.matches[20].error = std::numeric_limits<double>::infinity();
  r.matches[30].p_est = Eigen::Vector3d(1e300, -1e300, 0.0);
  const cv::Mat img = ds3d::render_ate_plot(gt, r, {.width = 1000, .height = 500});
  EXPECT_EQ(img.cols, 1000);
  r.max = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)ds3d::render_ate_plot(gt, r), ds3d::InvalidArgument);
}

// Same lines, names and units; numbers equal up to the %f rounding, plus the fixtures' 1e-5 deg
// floor for rotations (arccos near 0 is noise: identity_perfect).
::testing::AssertionResult same_report(const std::string& got, const std::string& want) {
  const auto lines = [](const std::string& s) {
    std::vector<std::string> out;
    std::size_t a = 0;
    for (std::size_t b; (b = s.find('\n', a)) != std::string::npos; a = b + 1)
      out.push_back(s.substr(a, b - a));
    return out;
  };
  const auto g = lines(got);
  const auto w = lines(want);
  if (g.size() != w.size()) return ::testing::AssertionFailure() << got << " vs\n" << want;
  for (std::size_t i = 0; i < g.size(); ++i) {
    char gn[128], gu[16], wn[128], wu[16];
    double gv = 0, wv = 0;
    if (std::sscanf(g[i].c_str(), "%127s %lf %15s", gn, &gv, gu) != 3 ||
        std::sscanf(w[i].c_str(), "%127s %lf %15s", wn, &wv, wu) != 3 || std::string(gn) != wn ||
        std::string(gu) != wu || std::abs(gv - wv) > (std::string(gu) == "deg" ? 1.1e-5 : 1.1e-6)) {
      return ::testing::AssertionFailure()
             << "line " << i << ": '" << g[i] << "' vs '" << w[i] << "'";
    }
  }
  return ::testing::AssertionSuccess();
}

std::string run(const std::string& cmd) {
  std::string out;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return out;
  char buf[4096];
  for (std::size_t n; (n = std::fread(buf, 1, sizeof(buf), p)) > 0;) out.append(buf, n);
  ::pclose(p);
  return out;
}

TEST(Ds3dEvalCli, PrintsWhatTheTumScriptsPrint) {
  const fs::path exe = fs::path(DS3D_BINARY_DIR) / "bin" / "ds3d-eval";
  if (!fs::exists(exe)) GTEST_SKIP() << "ds3d-eval not built";
  for (const auto& e : fs::directory_iterator(ds3d::test::data_path("trajectory"))) {
    if (!fs::exists(e.path() / "expected.json")) continue;
    SCOPED_TRACE(e.path().filename().string());
    const auto exp = ds3d::test::read_json(e.path() / "expected.json");
    const std::string files = " '" + (e.path() / "groundtruth.txt").string() + "' '" +
                              (e.path() / "estimate.txt").string() + "'";
    const auto& ref = exp.at("reference_cli_stdout");
    EXPECT_TRUE(same_report(run(exe.string() + " ate" + files), ref.at("ate").as_string()));
    for (const auto& [key, unit] :
         {std::pair{"rpe_delta_1s", "s"}, std::pair{"rpe_delta_1f", "f"}}) {
      std::string got = run(exe.string() + " rpe" + files + " --delta 1 --delta-unit " + unit);
      std::string want = ref.at(key).as_string();
      // evaluate_rpe.py prints the rotational median in radians (a bug); we print degrees.
      const auto drop_median = [](std::string s) {
        const auto a = s.find("rotational_error.median");
        return a == std::string::npos ? s : s.erase(a, s.find('\n', a) - a + 1);
      };
      EXPECT_TRUE(same_report(drop_median(got), drop_median(want))) << key;
    }
  }
  // bad usage: exit code 2 and a message naming the option
  EXPECT_NE(run(exe.string() + " ate a b --align se2 2>&1").find("se2"), std::string::npos);
  EXPECT_NE(run(exe.string() + " ate /nonexistent/a.txt /nonexistent/b.txt 2>&1").find("a.txt"),
            std::string::npos);
}

TEST(Ds3dEvalCli, WindowTextJsonAndPlot) {
  const fs::path exe = fs::path(DS3D_BINARY_DIR) / "bin" / "ds3d-eval";
  if (!fs::exists(exe)) GTEST_SKIP() << "ds3d-eval not built";
  const fs::path dir = fs::temp_directory_path() / ("ds3d_window_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto [gt, est] = drift_pair();
  ds3d::write_tum_trajectory(dir / "gt.txt", gt);
  ds3d::write_tum_trajectory(dir / "est.txt", est);
  const auto want = ds3d::evaluate_ate(gt, est, {.window = 1.0});
  const std::string files =
      " '" + (dir / "gt.txt").string() + "' '" + (dir / "est.txt").string() + "'";

  const std::string plain = run(exe.string() + " ate" + files);
  const std::string text = run(exe.string() + " ate" + files + " --window 1");
  ASSERT_EQ(text.rfind(plain, 0), 0U) << text;  // the usual lines first, unchanged
  const std::string extra = text.substr(plain.size());
  EXPECT_EQ(extra.rfind("windows 10 (1 s each)\n", 0), 0U) << extra;
  double worst = 0, start = 0, end = 0;
  ASSERT_EQ(std::sscanf(extra.c_str() + extra.find("worst_window_rmse"),
                        "worst_window_rmse %lf m (start %lf end %lf)", &worst, &start, &end),
            3)
      << extra;
  EXPECT_NEAR(worst, want.worst_window_rmse, 1e-6);
  EXPECT_GT(worst, 1.5 * want.rmse);  // the global figure smears the drift out
  EXPECT_EQ(start, 104.0);
  EXPECT_EQ(end, 104.0 + 63.0 / 64);

  const auto j =
      ds3d::detail::parse_json(run(exe.string() + " ate" + files + " --window 1 --json"));
  EXPECT_EQ(j.at("compared_pose_pairs").as_int(), 640);
  ASSERT_EQ(j.at("windows").size(), want.windows.size());
  for (std::size_t k = 0; k < want.windows.size(); ++k) {
    const auto& w = j.at("windows").at(k);
    EXPECT_NEAR(w.at("start").as_number(), want.windows[k].start, 1e-9);
    EXPECT_NEAR(w.at("end").as_number(), want.windows[k].end, 1e-9);
    EXPECT_EQ(w.at("pairs").as_int(), static_cast<std::int64_t>(want.windows[k].pairs));
    EXPECT_NEAR(w.at("rmse").as_number(), want.windows[k].rmse, 1e-12);
  }
  EXPECT_NEAR(j.at("worst_window_rmse").as_number(), want.worst_window_rmse, 1e-12);
  EXPECT_FALSE(
      ds3d::detail::parse_json(run(exe.string() + " ate" + files + " --json")).contains("windows"));

  const fs::path png = dir / "plot.png";
  (void)run(exe.string() + " ate" + files + " --window 1 --plot '" + png.string() + "'");
  const cv::Mat img = cv::imread(png.string());
  ASSERT_EQ(img.cols, 1400);
  cv::Mat mask;
  cv::inRange(img, cv::Scalar(190, 0, 190), cv::Scalar(210, 10, 210), mask);
  EXPECT_GT(cv::countNonZero(mask), 300);  // the window segments

  EXPECT_NE(run(exe.string() + " ate" + files + " --window -1 2>&1").find("window"),
            std::string::npos);
  fs::remove_all(dir);
}

// Two estimates: the drifting one and one with a constant 5 cm offset and noise.
std::vector<ds3d::AtePlotEstimate> two_estimates(const ds3d::Trajectory& gt,
                                                 const ds3d::Trajectory& drift) {
  auto noisy = gt;
  for (std::size_t i = 0; i < noisy.size(); ++i) {
    noisy[i].T_world_cam.translation() +=
        Eigen::Vector3d(0.05, 0.02 * std::sin(0.3 * static_cast<double>(i)), 0);
  }
  return {{"drift.txt", ds3d::evaluate_ate(gt, drift, {.alignment = ds3d::Alignment::kNone})},
          {"noisy.txt", ds3d::evaluate_ate(gt, noisy, {.alignment = ds3d::Alignment::kNone})}};
}

// Pixels of exactly one colour (BGR).
int count_colour(const cv::Mat& img, const cv::Scalar& c) {
  cv::Mat m;
  cv::inRange(img, c, c, m);
  return cv::countNonZero(m);
}

TEST(AtePlot, DrawsSeveralEstimatesWithAColourBar) {
  const auto [gt, drift] = drift_pair();
  const auto est = two_estimates(gt, drift);
  const cv::Mat img = ds3d::render_multi_ate_plot(gt, est, {.width = 1000, .height = 600});
  ASSERT_EQ(img.cols, 1000);
  ASSERT_EQ(img.rows, 600);
  // Each estimate in its own colour (Tableau blue, orange): the wide line under the error ramp.
  EXPECT_GT(count_colour(img, {180, 119, 31}), 300);
  EXPECT_GT(count_colour(img, {14, 127, 255}), 300);
  // The colour bar beside the top view (header 34 + 2 x 18 px; view 410 px wide from x = 20):
  // the ramp's top colour (largest error) at its top, its bottom colour at its bottom.
  const cv::Vec3b top = img.at<cv::Vec3b>(111, 454);
  const cv::Vec3b bottom = img.at<cv::Vec3b>(548, 454);
  EXPECT_NEAR(top[2], 0.84 * 255, 3);  // red
  EXPECT_NEAR(top[0], 0.12 * 255, 3);
  EXPECT_NEAR(bottom[2], 0.19 * 255, 3);  // dark violet
  EXPECT_NEAR(bottom[0], 0.23 * 255, 3);
  // One estimate works too; none, eleven, or too little height do not.
  EXPECT_EQ(ds3d::render_multi_ate_plot(gt, {est[0]}).cols, 1400);
  EXPECT_THROW((void)ds3d::render_multi_ate_plot(gt, {}), ds3d::InvalidArgument);
  EXPECT_THROW(
      (void)ds3d::render_multi_ate_plot(gt, std::vector<ds3d::AtePlotEstimate>(11, est[0])),
      ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::render_multi_ate_plot(gt, std::vector<ds3d::AtePlotEstimate>(10, est[0]),
                                                 {.height = 400}),
               ds3d::InvalidArgument);
  EXPECT_THROW((void)ds3d::render_multi_ate_plot(gt, {{"x", ds3d::AteResult{}}}),
               ds3d::InvalidArgument);
}

// ate GT EST1 EST2: a block per estimate, a JSON list of them, one plot of both.
TEST(Ds3dEvalCli, SeveralEstimates) {
  if (!fs::exists(ds3d::test::tool_path("ds3d-eval"))) GTEST_SKIP() << "ds3d-eval not built";
  const fs::path dir = fs::temp_directory_path() / ("ds3d_multi_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const auto [gt, drift] = drift_pair();
  auto noisy = gt;
  for (auto& p : noisy) p.T_world_cam.translation().y() += 0.03;
  ds3d::write_tum_trajectory(dir / "gt.txt", gt);
  ds3d::write_tum_trajectory(dir / "a.txt", drift);
  ds3d::write_tum_trajectory(dir / "b.txt", noisy);
  const std::string g = "'" + (dir / "gt.txt").string() + "'";
  const std::string a = (dir / "a.txt").string();
  const std::string b = (dir / "b.txt").string();
  const std::string files = " " + g + " '" + a + "' '" + b + "'";
  const fs::path png = dir / "p.png";
  auto r =
      ds3d::test::run_tool("ds3d-eval", "ate" + files + " --json --plot '" + png.string() + "'");
  ASSERT_EQ(r.code, 0) << r.output;
  const auto j = ds3d::detail::parse_json(r.output);
  EXPECT_EQ(j.at("ground_truth").as_string(), (dir / "gt.txt").string());
  ASSERT_EQ(j.at("estimates").size(), 2U);
  EXPECT_EQ(j.at("estimates").at(0).at("file").as_string(), a);
  EXPECT_EQ(j.at("estimates").at(1).at("file").as_string(), b);
  EXPECT_NEAR(j.at("estimates").at(0).at("rmse").as_number(), ds3d::evaluate_ate(gt, drift).rmse,
              1e-12);
  EXPECT_NEAR(j.at("estimates").at(1).at("rmse").as_number(), ds3d::evaluate_ate(gt, noisy).rmse,
              1e-12);
  const cv::Mat img = cv::imread(png.string());
  EXPECT_EQ(img.cols, 1400);
  EXPECT_EQ(img.rows, 640);
  EXPECT_GT(count_colour(img, {14, 127, 255}), 300);  // the second estimate's colour
  // Text: "estimate FILE" and the usual block for each, the single-estimate text unchanged.
  r = ds3d::test::run_tool("ds3d-eval", "ate" + files);
  ASSERT_EQ(r.code, 0) << r.output;
  const auto one = [&](const std::string& est) {
    return ds3d::test::run_tool("ds3d-eval", "ate " + g + " '" + est + "'").output;
  };
  EXPECT_EQ(r.output, "estimate " + a + "\n" + one(a) + "\nestimate " + b + "\n" + one(b));
  r = ds3d::test::run_tool("ds3d-eval", "rpe" + files + " --json");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(ds3d::detail::parse_json(r.output).at("estimates").size(), 2U);
  fs::remove_all(dir);
}

TEST(Ds3dEvalCli, HugePositionsAndBadIntegersFailClearly) {
  if (!fs::exists(ds3d::test::tool_path("ds3d-eval"))) GTEST_SKIP() << "ds3d-eval not built";
  const fs::path dir = fs::temp_directory_path() / ("ds3d_huge_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  auto [gt, est] = drift_pair();
  est[300].T_world_cam.translation().x() = 1.25e197;
  ds3d::write_tum_trajectory(dir / "gt.txt", gt);
  ds3d::write_tum_trajectory(dir / "est.txt", est);
  const std::string files =
      " '" + (dir / "gt.txt").string() + "' '" + (dir / "est.txt").string() + "'";
  const std::string plot = " --plot '" + (dir / "p.png").string() + "'";
  for (const std::string& extra : {std::string(), std::string(" --json"), plot}) {
    const auto r = ds3d::test::run_tool("ds3d-eval", "ate" + files + extra);
    EXPECT_EQ(r.code, 2) << extra << ": " << r.output;
    EXPECT_NE(r.output.find("1.25e+197"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("est.txt"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("rmse inf"), std::string::npos) << r.output;
  }
  EXPECT_FALSE(fs::exists(dir / "p.png"));
  EXPECT_EQ(ds3d::test::run_tool("ds3d-eval", "rpe" + files).code, 2);
  // Integer options out of range, and the tool name once per message.
  for (const std::string opt : {"--max-pairs -1", "--seed 1e30", "--seed 2.5"}) {
    const auto r = ds3d::test::run_tool("ds3d-eval", "rpe" + files + " " + opt);
    EXPECT_EQ(r.code, 2) << opt;
    EXPECT_EQ(r.output.rfind("ds3d-eval: error: --", 0), 0U) << r.output;
    EXPECT_EQ(r.output.find("ds3d-eval:", 1), std::string::npos) << r.output;
  }
  fs::remove_all(dir);
}

}  // namespace
