#include "core/io/image_codec.h"
#include "core/io/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/errors.h"
#include "core/file_utils.h"

namespace lisfm {

namespace {

constexpr int kWidth = 1200;
constexpr int kTopHeight = 720;
constexpr int kBottomHeight = 280;
constexpr int kMargin = 70;

const cv::Scalar kWhite(255, 255, 255);
const cv::Scalar kBlack(0, 0, 0);
const cv::Scalar kGrid(225, 225, 225);
const cv::Scalar kReferenceColor(60, 60, 60);
const cv::Scalar kEstimateColor(200, 110, 0);  // BGR: blue
const cv::Scalar kErrorColor(30, 30, 210);     // BGR: red

void Text(cv::Mat& img,
          const std::string& s,
          cv::Point at,
          double scale = 0.5,
          const cv::Scalar& color = kBlack) {
  cv::putText(
      img, s, at, cv::FONT_HERSHEY_SIMPLEX, scale, color, 1, cv::LINE_AA);
}

// A "nice" tick step (1, 2 or 5 times a power of ten) for about `ticks` ticks.
double TickStep(double span, int ticks) {
  const double raw = span / std::max(ticks, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (const double m : {1.0, 2.0, 5.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10.0 * p;
}

std::string TickLabel(double v, double step) {
  const int decimals =
      std::max(0, static_cast<int>(-std::floor(std::log10(step))));
  return fmt::format("{:.{}f}", v, decimals);
}

void DrawTopView(cv::Mat& img, const TrajectoryPlotData& data, int top) {
  double min_x = std::numeric_limits<double>::infinity();
  double min_y = min_x;
  double max_x = -min_x;
  double max_y = -min_x;
  for (const auto* list : {&data.reference, &data.estimate}) {
    for (const Vec3& p : *list) {
      min_x = std::min(min_x, p.x());
      max_x = std::max(max_x, p.x());
      min_y = std::min(min_y, p.y());
      max_y = std::max(max_y, p.y());
    }
  }
  // Equal aspect: one scale (px per m) for both axes; at least 1 m shown.
  const double span = std::max({max_x - min_x, max_y - min_y, 1.0});
  const int plot_w = kWidth - 2 * kMargin;
  const int plot_h = kTopHeight - 2 * kMargin;
  const double scale = std::min(plot_w, plot_h) / (1.05 * span);
  const double cx = 0.5 * (min_x + max_x);
  const double cy = 0.5 * (min_y + max_y);
  const cv::Point2d centre(kMargin + 0.5 * plot_w,
                           top + kMargin + 0.5 * plot_h);
  auto to_px = [&](double x, double y) {
    return cv::Point(
        static_cast<int>(std::lround(centre.x + (x - cx) * scale)),
        static_cast<int>(std::lround(centre.y - (y - cy) * scale)));
  };
  const double half_w = 0.5 * plot_w / scale;
  const double half_h = 0.5 * plot_h / scale;
  const double step = TickStep(2 * std::max(half_w, half_h), 10);
  for (double x = std::ceil((cx - half_w) / step) * step; x <= cx + half_w;
       x += step) {
    const cv::Point a = to_px(x, cy - half_h);
    cv::line(img, a, to_px(x, cy + half_h), kGrid, 1);
    Text(img, TickLabel(x, step), cv::Point(a.x - 12, a.y + 18), 0.4);
  }
  for (double y = std::ceil((cy - half_h) / step) * step; y <= cy + half_h;
       y += step) {
    const cv::Point a = to_px(cx - half_w, y);
    cv::line(img, a, to_px(cx + half_w, y), kGrid, 1);
    Text(img, TickLabel(y, step), cv::Point(a.x - 55, a.y + 5), 0.4);
  }
  cv::rectangle(img,
                to_px(cx - half_w, cy + half_h),
                to_px(cx + half_w, cy - half_h),
                kBlack,
                1);
  Text(img, "x [m]", cv::Point(kWidth / 2 - 20, top + kTopHeight - 20));
  Text(img, "y [m]", cv::Point(8, top + kMargin - 10));

  auto polyline = [&](const std::vector<Vec3>& pts,
                      const cv::Scalar& color,
                      int thickness) {
    std::vector<cv::Point> px;
    for (const Vec3& p : pts) px.push_back(to_px(p.x(), p.y()));
    if (px.size() >= 2)
      cv::polylines(img, px, false, color, thickness, cv::LINE_AA);
    if (px.size() == 1)
      cv::circle(img, px[0], 3, color, cv::FILLED, cv::LINE_AA);
  };
  polyline(data.estimate, kEstimateColor, 2);
  if (data.reference_as_markers) {
    for (const Vec3& p : data.reference) {
      cv::circle(img, to_px(p.x(), p.y()), 7, kReferenceColor, 2, cv::LINE_AA);
    }
  } else {
    polyline(data.reference, kReferenceColor, 1);
  }

  // Legend in the top-left corner of the plot area.
  const cv::Point legend(kMargin + 15, top + kMargin + 25);
  if (data.reference_as_markers) {
    cv::circle(
        img, legend + cv::Point(15, -5), 7, kReferenceColor, 2, cv::LINE_AA);
  } else {
    cv::line(img,
             legend + cv::Point(0, -5),
             legend + cv::Point(30, -5),
             kReferenceColor,
             1);
  }
  Text(img, data.reference_label, legend + cv::Point(40, 0));
  cv::line(img,
           legend + cv::Point(0, 20),
           legend + cv::Point(30, 20),
           kEstimateColor,
           2);
  Text(img, data.estimate_label, legend + cv::Point(40, 25));
  Text(img,
       fmt::format("top view, grid {} m", TickLabel(step, step)),
       legend + cv::Point(0, 50),
       0.45);
}

void DrawErrorPanel(cv::Mat& img, const TrajectoryPlotData& data, int top) {
  const int left = kMargin;
  const int right = kWidth - kMargin / 2;
  const int y0 = top + 30;
  const int y1 = top + kBottomHeight - 45;
  cv::rectangle(img, cv::Point(left, y0), cv::Point(right, y1), kBlack, 1);
  Text(img, "error [m] over time [s]", cv::Point(left, top + 20));
  if (data.error_m.empty()) {
    Text(img, "(no associated poses)", cv::Point(left + 20, (y0 + y1) / 2));
    return;
  }
  const auto [t_min_it, t_max_it] =
      std::minmax_element(data.error_time_s.begin(), data.error_time_s.end());
  const double t_min = *t_min_it;
  const double t_span = std::max(*t_max_it - t_min, 1e-9);
  const double e_max = std::max(
      *std::max_element(data.error_m.begin(), data.error_m.end()), 1e-6);
  const double e_top = 1.1 * e_max;
  auto to_px = [&](double t, double e) {
    return cv::Point(static_cast<int>(std::lround(left + (t - t_min) / t_span *
                                                             (right - left))),
                     static_cast<int>(std::lround(y1 - e / e_top * (y1 - y0))));
  };
  const double t_step = TickStep(t_span, 10);
  for (double t = std::ceil(t_min / t_step) * t_step;
       t <= t_min + t_span + 1e-12;
       t += t_step) {
    const cv::Point a = to_px(t, 0);
    cv::line(img, a, cv::Point(a.x, y0), kGrid, 1);
    Text(img, TickLabel(t, t_step), cv::Point(a.x - 12, y1 + 18), 0.4);
  }
  const double e_step = TickStep(e_top, 4);
  for (double e = 0; e <= e_top; e += e_step) {
    const cv::Point a = to_px(t_min, e);
    cv::line(img, a, cv::Point(right, a.y), kGrid, 1);
    Text(img, TickLabel(e, e_step), cv::Point(5, a.y + 5), 0.4);
  }
  Text(img,
       "t [s]",
       cv::Point((left + right) / 2 - 15, top + kBottomHeight - 8));
  std::vector<cv::Point> px;
  for (size_t i = 0; i < data.error_m.size(); ++i) {
    px.push_back(to_px(data.error_time_s[i], data.error_m[i]));
  }
  if (px.size() >= 2)
    cv::polylines(img, px, false, kErrorColor, 1, cv::LINE_AA);
  // Few samples (control points): mark each one.
  if (px.size() <= 100) {
    for (const auto& p : px)
      cv::circle(img, p, 4, kErrorColor, cv::FILLED, cv::LINE_AA);
  }
  Text(img,
       fmt::format("max {:.4f} m", e_max),
       cv::Point(right - 150, y0 + 20),
       0.45,
       kErrorColor);
}

}  // namespace

void WriteTrajectoryPlot(const std::string& path,
                         const TrajectoryPlotData& data) {
  THROW_CHECK_MSG(!data.reference.empty() || !data.estimate.empty(),
                  "WriteTrajectoryPlot: nothing to draw");
  THROW_CHECK_EQ(data.error_time_s.size(), data.error_m.size());
  cv::Mat img(kTopHeight + kBottomHeight, kWidth, CV_8UC3, kWhite);
  if (!data.title.empty()) Text(img, data.title, cv::Point(kMargin, 30), 0.6);
  DrawTopView(img, data, 0);
  cv::line(
      img, cv::Point(0, kTopHeight), cv::Point(kWidth, kTopHeight), kGrid, 2);
  DrawErrorPanel(img, data, kTopHeight);
  WriteFileAtomically(path, EncodePng(img));
}

}  // namespace lisfm
