// SPDX-License-Identifier: Apache-2.0
// SPDX-FileCopyrightText: 2026 ds3d authors
#include "ds3d/slam/trajectory_plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <string>
#include <vector>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "ds3d/detail/tum_text.hpp"
#include "ds3d/errors.hpp"

namespace ds3d {

namespace {

// Perceptually ordered blue -> green -> yellow -> red ramp for v in [0, 1] (BGR).
cv::Scalar ramp(double v) {
  v = std::isnan(v) ? 1.0 : std::clamp(v, 0.0, 1.0);  // NaN would index the stops at INT_MIN
  static const double kStops[5][3] = {{0.19, 0.07, 0.23},
                                      {0.13, 0.47, 0.85},
                                      {0.25, 0.80, 0.35},
                                      {0.98, 0.80, 0.15},
                                      {0.84, 0.15, 0.12}};  // RGB
  const double x = v * 4;
  const int i = std::min(3, static_cast<int>(x));
  const double f = x - i;
  const auto c = [&](int k) { return 255 * ((1 - f) * kStops[i][k] + f * kStops[i + 1][k]); };
  return {c(2), c(1), c(0)};
}

// Pixel coordinate of a double, clamped far outside any image (OpenCV clips the lines) so that
// huge or non-finite values cannot overflow the int conversion.
int to_px(double v) {
  return std::isnan(v) ? 0 : static_cast<int>(std::lround(std::clamp(v, -1e6, 1e6)));
}

std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), f, v);
  return buf;
}

void text(cv::Mat& img, const std::string& s, cv::Point p, double scale = 0.5,
          const cv::Scalar& c = {40, 40, 40}) {
  cv::putText(img, s, p, cv::FONT_HERSHEY_SIMPLEX, scale, c, 1, cv::LINE_AA);
}

// "Nice" tick step for a range.
double tick_step(double range, int target) {
  const double raw = range / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10 * p;
}

// The error-over-time panel's frame: time t0..t1 [s] across, error 0..ytop [m] up.
struct ErrorAxes {
  cv::Rect plot;
  double t0, t1, ytop;
  cv::Point operator()(double t, double e) const {
    return cv::Point(to_px(plot.x + (t - t0) / (t1 - t0) * plot.width),
                     to_px(plot.y + plot.height - e / ytop * plot.height));
  }
};

// Grid lines, tick labels and axis titles of an error-over-time panel.
void draw_error_axes(cv::Mat& img, const ErrorAxes& pt, const std::string& y_title) {
  const cv::Rect& plot = pt.plot;
  const double ys = tick_step(pt.ytop, 5);
  int ticks = 0;  // bounded even if rounding stalls the sum
  for (double y = 0; y <= pt.ytop + 1e-12 && ticks < 100; y += ys, ++ticks) {
    cv::line(img, pt(pt.t0, y), pt(pt.t1, y), {235, 235, 235}, 1);
    text(img, fmt("%.3g", y), pt(pt.t0, y) + cv::Point(-58, 5), 0.42);
  }
  const double xs = tick_step(pt.t1 - pt.t0, 6);
  ticks = 0;
  for (double x = 0; x <= pt.t1 - pt.t0 + 1e-9 && ticks < 100; x += xs, ++ticks) {
    cv::line(img, pt(pt.t0 + x, 0), pt(pt.t0 + x, 0) + cv::Point(0, 5), {40, 40, 40}, 1);
    text(img, fmt("%g", x), pt(pt.t0 + x, 0) + cv::Point(-8, 22), 0.42);
  }
  text(img, "time [s]", {plot.x + plot.width / 2 - 30, plot.y + plot.height + 44}, 0.45);
  text(img, y_title, {plot.x + 6, plot.y + 18}, 0.45);
}

// The local ATE (AteResult::windows) in the error-over-time panel: each window's RMSE as a
// horizontal segment over its span, and a label at the worst one. `pt` maps (t, error) to pixels.
template <class ToPixel>
void draw_windows(cv::Mat& img, const AteResult& r, const cv::Rect& plot, double t0,
                  const ToPixel& pt) {
  if (r.windows.empty()) return;
  const cv::Scalar colour(200, 0, 200);  // magenta (BGR): no colour of the error ramp
  const AteWindow* worst = &r.windows.front();
  for (const auto& w : r.windows) {
    cv::line(img, pt(w.start, w.rmse), pt(w.end, w.rmse), colour, 2, cv::LINE_AA);
    if (w.rmse > worst->rmse) worst = &w;
  }
  const std::string label = "worst window rmse " + fmt("%.4f", worst->rmse) + " (" +
                            fmt("%.1f", worst->start - t0) + "-" + fmt("%.1f", worst->end - t0) +
                            " s)";
  int baseline = 0;
  const cv::Size ts = cv::getTextSize(label, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &baseline);
  cv::Point at = pt(worst->start, worst->rmse) + cv::Point(0, -8);
  at.x = std::clamp(at.x, plot.x + 4, std::max(plot.x + 4, plot.x + plot.width - ts.width - 4));
  at.y = std::max(at.y, plot.y + 34);  // below the panel's title line
  // White under the label: it sits on the error curve.
  cv::rectangle(img, at + cv::Point(-2, -ts.height - 2), at + cv::Point(ts.width + 2, baseline),
                {255, 255, 255}, cv::FILLED);
  text(img, label, at, 0.45, colour);
  text(img, "window rmse (" + std::to_string(r.windows.size()) + " windows)",
       {plot.x + plot.width - 230, plot.y + 18}, 0.45, colour);
}

// Colours of the estimates in a multi-estimate plot (BGR, Tableau 10 less its grey, which is
// the ground truth's, plus black).
const cv::Scalar kEstimateColours[] = {
    {180, 119, 31}, {14, 127, 255},  {44, 160, 44},  {40, 39, 214},  {189, 103, 148},
    {75, 86, 140},  {194, 119, 227}, {34, 189, 188}, {207, 190, 23}, {0, 0, 0}};
constexpr std::size_t kMaxEstimates = std::size(kEstimateColours);

// The vertical colour bar of the error ramp: 0 at the bottom, emax at the top, ticks in metres.
void draw_colour_bar(cv::Mat& img, const cv::Rect& bar, double emax) {
  for (int y = 0; y < bar.height; ++y) {
    const double v = 1.0 - y / static_cast<double>(bar.height - 1);
    cv::line(img, {bar.x, bar.y + y}, {bar.x + bar.width - 1, bar.y + y}, ramp(v), 1);
  }
  cv::rectangle(img, bar, {80, 80, 80});
  const double step = tick_step(emax, 5);
  int ticks = 0;  // bounded even if rounding stalls the sum
  for (double e = 0; e <= emax * (1 + 1e-9) && ticks < 100; e += step, ++ticks) {
    const int y = to_px(bar.y + bar.height - 1 - e / emax * (bar.height - 1));
    cv::line(img, {bar.x + bar.width, y}, {bar.x + bar.width + 4, y}, {40, 40, 40}, 1);
    text(img, fmt("%.3g", e), {bar.x + bar.width + 7, y + 4}, 0.4);
  }
  text(img, "ATE [m]", {bar.x - 8, bar.y - 10}, 0.42);
}

// A label's last 60 characters (file paths).
std::string short_label(const std::string& s) {
  if (s.size() <= 60) return s;
  std::string out = "...";
  out.append(s, s.size() - 57, 57);
  return out;
}

// The checks of render_ate_plot() on one result, naming the estimate.
void check_result(const AteResult& r, std::size_t k) {
  DS3D_CHECK(!r.matches.empty(), "ds3d::render_multi_ate_plot: estimates[", k,
             "]: the ATE result has no matches");
  DS3D_CHECK(std::isfinite(r.rmse) && std::isfinite(r.max),
             "ds3d::render_multi_ate_plot: ", "estimates[", k,
             "]: the ATE statistics are not finite (rmse ", r.rmse, ", max ", r.max, ")");
}

// Top-view projection: the plane of the two principal axes of the ground truth, scaled to fit
// every position into `view` with equal scale on both axes.
class TopView {
 public:
  TopView(const std::vector<Eigen::Vector3d>& gpts, const std::vector<Eigen::Vector3d>& all,
          const cv::Rect& view)
      : view_(view) {
    for (const auto& p : gpts) mean_ += p;
    mean_ /= static_cast<double>(gpts.size());
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : gpts) cov += (p - mean_) * (p - mean_).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    ax_ = es.eigenvectors().col(2);
    ay_ = es.eigenvectors().col(1);
    Eigen::Vector2d lo(1e300, 1e300);
    Eigen::Vector2d hi(-1e300, -1e300);
    for (const auto& p : all) {
      lo = lo.cwiseMin(to2(p));
      hi = hi.cwiseMax(to2(p));
    }
    span_ = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-6});
    DS3D_CHECK(std::isfinite(span_), "ds3d::render_multi_ate_plot: the positions' extent is ",
               "not finite (", span_, " m)");
    scale_ = 0.9 * std::min(view.width, view.height) / span_;
    mid_ = 0.5 * (lo + hi);
  }
  [[nodiscard]] cv::Point operator()(const Eigen::Vector3d& p) const {
    const Eigen::Vector2d q = to2(p) - mid_;
    return {to_px(view_.x + view_.width / 2.0 + scale_ * q.x()),
            to_px(view_.y + view_.height / 2.0 - scale_ * q.y())};
  }
  [[nodiscard]] double span() const { return span_; }
  [[nodiscard]] double scale() const { return scale_; }

 private:
  [[nodiscard]] Eigen::Vector2d to2(const Eigen::Vector3d& p) const {
    return {(p - mean_).dot(ax_), (p - mean_).dot(ay_)};
  }
  cv::Rect view_;
  Eigen::Vector3d mean_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d ax_;
  Eigen::Vector3d ay_;
  Eigen::Vector2d mid_;
  double span_ = 0;
  double scale_ = 0;
};

// The top-view panel of the multi-estimate plot.
void draw_multi_top_view(cv::Mat& img, const Trajectory& gt,
                         const std::vector<AtePlotEstimate>& estimates, const cv::Rect& view,
                         double emax) {
  std::vector<Eigen::Vector3d> gpts;
  for (const auto& p : gt) {
    if (p.T_world_cam.translation().allFinite()) gpts.push_back(p.T_world_cam.translation());
  }
  for (const auto& e : estimates) {
    for (const auto& m : e.result.matches) gpts.push_back(m.p_gt);
  }
  std::vector<Eigen::Vector3d> all = gpts;
  for (const auto& e : estimates) {
    for (const auto& m : e.result.matches) all.push_back(m.p_est);
  }
  const TopView px(gpts, all, view);
  cv::rectangle(img, view, {200, 200, 200});
  text(img, "top view (principal plane of ground truth)", {view.x + 6, view.y + 18}, 0.45);
  const double bar = tick_step(px.span(), 4);
  const int bar_px = to_px(bar * px.scale());
  const cv::Point b0(view.x + 10, view.y + view.height - 14);
  cv::line(img, b0, b0 + cv::Point(bar_px, 0), {40, 40, 40}, 2);
  text(img, fmt("%g m", bar), b0 + cv::Point(bar_px + 6, 5), 0.45);
  std::vector<cv::Point> gline;
  for (const auto& p : gt) {
    if (p.T_world_cam.translation().allFinite()) gline.push_back(px(p.T_world_cam.translation()));
  }
  cv::polylines(img, gline, false, {150, 150, 150}, 2, cv::LINE_AA);
  for (std::size_t k = 0; k < estimates.size(); ++k) {
    const auto& ms = estimates[k].result.matches;
    std::vector<cv::Point> line;
    for (const auto& m : ms) line.push_back(px(m.p_est));
    cv::polylines(img, line, false, kEstimateColours[k], 6, cv::LINE_AA);
    for (std::size_t i = 0; i + 1 < ms.size(); ++i) {
      cv::line(img, line[i], line[i + 1], ramp(ms[i].error / emax), 2, cv::LINE_AA);
    }
    std::string number = "[";
    number += std::to_string(k + 1);
    number += ']';
    // Stacked: estimates that end at the same place keep readable numbers.
    text(img, number, line.back() + cv::Point(6, 4 + 16 * static_cast<int>(k)), 0.5,
         kEstimateColours[k]);
  }
  const Eigen::Vector3d start = estimates.front().result.matches.front().p_gt;
  cv::circle(img, px(start), 5, {0, 140, 0}, cv::FILLED, cv::LINE_AA);
  text(img, "start", px(start) + cv::Point(7, -7), 0.45, {0, 120, 0});
}

// The error-over-time panel of the multi-estimate plot: one curve per estimate in its colour.
void draw_multi_errors(cv::Mat& img, const std::vector<AtePlotEstimate>& estimates,
                       const cv::Rect& plot, double emax) {
  cv::rectangle(img, plot, {200, 200, 200});
  double t0 = estimates.front().result.matches.front().t_gt;
  double t1 = estimates.front().result.matches.back().t_gt;
  for (const auto& e : estimates) {
    t0 = std::min(t0, e.result.matches.front().t_gt);
    t1 = std::max(t1, e.result.matches.back().t_gt);
  }
  t1 = std::max(t1, t0 + 1e-6);
  const double ytop = emax * 1.08;
  DS3D_CHECK(std::isfinite(ytop) && std::isfinite(t1 - t0),
             "ds3d::render_multi_ate_plot: the error range ", ytop, " or the time span ", t1 - t0,
             " s is not finite");
  const ErrorAxes pt{plot, t0, t1, ytop};
  draw_error_axes(img, pt, "translational error [m] (thin: rmse)");
  for (std::size_t k = 0; k < estimates.size(); ++k) {
    const auto& r = estimates[k].result;
    std::vector<cv::Point> line;
    for (const auto& m : r.matches) line.push_back(pt(m.t_gt, m.error));
    cv::polylines(img, line, false, kEstimateColours[k], 2, cv::LINE_AA);
    cv::line(img, pt(t0, r.rmse), pt(t1, r.rmse), kEstimateColours[k], 1, cv::LINE_AA);
  }
}

}  // namespace

void AtePlotOptions::validate() const {
  DS3D_CHECK(width >= 400 && width <= 8000,
             "ds3d::render_ate_plot: width must be in [400, 8000] (got ", width, ")");
  DS3D_CHECK(height >= 300 && height <= 8000,
             "ds3d::render_ate_plot: height must be in [300, 8000] (got ", height, ")");
}

cv::Mat render_ate_plot(const Trajectory& gt, const AteResult& r, const AtePlotOptions& o) {
  o.validate();
  DS3D_CHECK(!r.matches.empty(), "ds3d::render_ate_plot: the ATE result has no matches");
  DS3D_CHECK(std::isfinite(r.rmse) && std::isfinite(r.max) && std::isfinite(r.worst_window_rmse),
             "ds3d::render_ate_plot: result: the ATE statistics are not finite (rmse ", r.rmse,
             ", max ", r.max, ", worst window rmse ", r.worst_window_rmse, ")");
  cv::Mat img(o.height, o.width, CV_8UC3, cv::Scalar(255, 255, 255));
  const int header = 58;
  text(img, o.title.empty() ? std::string("ATE") : o.title, {14, 22}, 0.6);
  text(img,
       "pairs " + std::to_string(r.compared_pose_pairs) + "   rmse " + fmt("%.4f", r.rmse) +
           " m   mean " + fmt("%.4f", r.mean) + "   median " + fmt("%.4f", r.median) + "   std " +
           fmt("%.4f", r.std) + "   min " + fmt("%.4f", r.min) + "   max " + fmt("%.4f", r.max) +
           " m" + (r.scale_factor != 1.0 ? "   scale " + fmt("%.4f", r.scale_factor) : ""),
       {14, 46}, 0.5);

  // ---- top view: principal plane of the GT positions
  std::vector<Eigen::Vector3d> gpts;
  for (const auto& p : gt) {
    if (p.T_world_cam.translation().allFinite()) gpts.push_back(p.T_world_cam.translation());
  }
  for (const auto& m : r.matches) gpts.push_back(m.p_gt);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : gpts) mean += p;
  mean /= static_cast<double>(gpts.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : gpts) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  Eigen::Vector3d ax = es.eigenvectors().col(2);
  Eigen::Vector3d ay = es.eigenvectors().col(1);
  const auto to2 = [&](const Eigen::Vector3d& p) {
    return Eigen::Vector2d((p - mean).dot(ax), (p - mean).dot(ay));
  };
  Eigen::Vector2d lo(1e300, 1e300);
  Eigen::Vector2d hi(-1e300, -1e300);
  for (const auto& p : gpts) {
    lo = lo.cwiseMin(to2(p));
    hi = hi.cwiseMax(to2(p));
  }
  for (const auto& m : r.matches) {
    lo = lo.cwiseMin(to2(m.p_est));
    hi = hi.cwiseMax(to2(m.p_est));
  }
  const int panel_w = std::min(o.height - header - 20, o.width / 2 - 20);
  const cv::Rect view(20, header + 10, panel_w, o.height - header - 30);
  const double span = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-6});
  DS3D_CHECK(std::isfinite(span), "ds3d::render_ate_plot: the positions' extent is not finite (",
             span, " m)");
  const double scale = 0.9 * std::min(view.width, view.height) / span;
  const Eigen::Vector2d mid = 0.5 * (lo + hi);
  const auto px = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d q = to2(p) - mid;
    return cv::Point(to_px(view.x + view.width / 2.0 + scale * q.x()),
                     to_px(view.y + view.height / 2.0 - scale * q.y()));
  };
  cv::rectangle(img, view, {200, 200, 200});
  text(img, "top view (principal plane of ground truth)", {view.x + 6, view.y + 18}, 0.45);
  // scale bar
  const double bar = tick_step(span, 4);
  const int bar_px = to_px(bar * scale);
  const cv::Point b0(view.x + 10, view.y + view.height - 14);
  cv::line(img, b0, b0 + cv::Point(bar_px, 0), {40, 40, 40}, 2);
  text(img, fmt("%g m", bar), b0 + cv::Point(bar_px + 6, 5), 0.45);
  std::vector<cv::Point> gline;
  for (const auto& p : gt) {
    if (p.T_world_cam.translation().allFinite()) gline.push_back(px(p.T_world_cam.translation()));
  }
  cv::polylines(img, gline, false, {150, 150, 150}, 2, cv::LINE_AA);
  const double emax = std::max(r.max, 1e-12);
  for (std::size_t k = 0; k < r.matches.size(); ++k) {
    const auto& m = r.matches[k];
    const cv::Scalar c = ramp(m.error / emax);
    if (k + 1 < r.matches.size()) {
      cv::line(img, px(m.p_est), px(r.matches[k + 1].p_est), c, 2, cv::LINE_AA);
    }
  }
  cv::circle(img, px(r.matches.front().p_gt), 5, {0, 140, 0}, cv::FILLED, cv::LINE_AA);
  text(img, "start", px(r.matches.front().p_gt) + cv::Point(7, -7), 0.45, {0, 120, 0});
  // legend
  const int lx = view.x + view.width - 190;
  cv::line(img, {lx, view.y + 34}, {lx + 30, view.y + 34}, {150, 150, 150}, 2);
  text(img, "ground truth", {lx + 36, view.y + 39}, 0.45);
  for (int i = 0; i < 30; ++i) {
    cv::line(img, {lx + i, view.y + 54}, {lx + i + 1, view.y + 54}, ramp(i / 29.0), 3);
  }
  text(img, "estimate (aligned)", {lx + 36, view.y + 59}, 0.45);

  // ---- error over time
  const cv::Rect plot(view.x + view.width + 70, header + 10, o.width - view.width - 110,
                      o.height - header - 60);
  cv::rectangle(img, plot, {200, 200, 200});
  const double t0 = r.matches.front().t_gt;
  const double t1 = std::max(r.matches.back().t_gt, t0 + 1e-6);
  // A window RMSE stays below the largest error (its own alignment is optimal for it); max() only
  // guards rounding.
  const double ytop = std::max(emax, r.worst_window_rmse) * 1.08;
  DS3D_CHECK(std::isfinite(ytop) && std::isfinite(t1 - t0),
             "ds3d::render_ate_plot: result: the error range ", ytop, " or the time span ", t1 - t0,
             " s is not finite");
  const ErrorAxes pt{plot, t0, t1, ytop};
  draw_error_axes(img, pt, "translational error [m]");
  for (std::size_t k = 0; k + 1 < r.matches.size(); ++k) {
    const auto& a = r.matches[k];
    const auto& b = r.matches[k + 1];
    cv::line(img, pt(a.t_gt, a.error), pt(b.t_gt, b.error), ramp(a.error / emax), 2, cv::LINE_AA);
  }
  cv::line(img, pt(t0, r.rmse), pt(t1, r.rmse), {60, 60, 200}, 1, cv::LINE_AA);
  text(img, "rmse " + fmt("%.4f", r.rmse), pt(t1, r.rmse) + cv::Point(-110, -6), 0.45,
       {60, 60, 200});
  draw_windows(img, r, plot, t0, pt);
  return img;
}

void write_ate_plot(const std::filesystem::path& path, const Trajectory& gt,
                    const AteResult& result, const AtePlotOptions& options) {
  const cv::Mat img = render_ate_plot(gt, result, options);
  std::vector<std::uint8_t> buf;
  DS3D_CHECK_AS(IoError, cv::imencode(".png", img, buf),
                "ds3d::write_ate_plot: PNG encoding failed");
  detail::write_file_atomically(
      path, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()),
      "ds3d::write_ate_plot");
}

cv::Mat render_multi_ate_plot(const Trajectory& gt, const std::vector<AtePlotEstimate>& estimates,
                              const AtePlotOptions& o) {
  o.validate();
  DS3D_CHECK(!estimates.empty() && estimates.size() <= kMaxEstimates,
             "ds3d::render_multi_ate_plot: estimates: expected 1 to ", kMaxEstimates,
             " estimates (got ", estimates.size(), ")");
  double emax = 1e-12;
  for (std::size_t k = 0; k < estimates.size(); ++k) {
    check_result(estimates[k].result, k);
    emax = std::max(emax, estimates[k].result.max);
  }
  const int n = static_cast<int>(estimates.size());
  const int header = 34 + 18 * n;
  DS3D_CHECK(o.height - header >= 200,
             "ds3d::render_multi_ate_plot: height must be >= ", header + 200, " for ", n,
             " estimates (got ", o.height, ")");
  cv::Mat img(o.height, o.width, CV_8UC3, cv::Scalar(255, 255, 255));
  text(img, o.title.empty() ? std::string("ATE") : o.title, {14, 22}, 0.6);
  for (int k = 0; k < n; ++k) {
    const auto& e = estimates[static_cast<std::size_t>(k)];
    const AteResult& r = e.result;
    const int y = 42 + 18 * k;
    cv::rectangle(img, {14, y - 9}, {26, y + 1}, kEstimateColours[k], cv::FILLED);
    std::string line = "[";  // appended piecewise: GCC 12 warns falsely on a + chain here
    line += std::to_string(k + 1);
    line += "] ";
    line += short_label(e.label);
    line += "   pairs " + std::to_string(r.compared_pose_pairs);
    line += "   rmse " + fmt("%.4f", r.rmse);
    line += " m   mean " + fmt("%.4f", r.mean);
    line += "   median " + fmt("%.4f", r.median);
    line += "   max " + fmt("%.4f", r.max) + " m";
    if (r.scale_factor != 1.0) line += "   scale " + fmt("%.4f", r.scale_factor);
    text(img, line, {32, y}, 0.45, kEstimateColours[k]);
  }
  const int panel_w = std::min(o.height - header - 20, o.width / 2 - 90);
  const cv::Rect view(20, header + 10, panel_w, o.height - header - 30);
  draw_multi_top_view(img, gt, estimates, view, emax);
  const cv::Rect bar(view.x + view.width + 18, view.y + 30, 14, view.height - 60);
  draw_colour_bar(img, bar, emax);
  const int px0 = bar.x + bar.width + 110;
  draw_multi_errors(img, estimates, {px0, header + 10, o.width - px0 - 40, o.height - header - 60},
                    emax);
  return img;
}

namespace {

void write_png(const std::filesystem::path& path, const cv::Mat& img, const char* function) {
  std::vector<std::uint8_t> buf;
  DS3D_CHECK_AS(IoError, cv::imencode(".png", img, buf), function, ": PNG encoding failed");
  detail::write_file_atomically(
      path, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()), function);
}

}  // namespace

void write_multi_ate_plot(const std::filesystem::path& path, const Trajectory& gt,
                          const std::vector<AtePlotEstimate>& estimates,
                          const AtePlotOptions& options) {
  write_png(path, render_multi_ate_plot(gt, estimates, options), "ds3d::write_multi_ate_plot");
}

}  // namespace ds3d
