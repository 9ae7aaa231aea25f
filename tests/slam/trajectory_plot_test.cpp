// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
// The ATE plot, and the ds3d-eval CLI against the TUM scripts' printed output of every fixture.
#include "ds3d/slam/trajectory_plot.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

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

}  // namespace
