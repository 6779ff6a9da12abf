#include "trajectory_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

namespace ccm::tools {
namespace {

const cv::Scalar kPalette[] = {{180, 119, 31}, {14, 127, 255}, {44, 160, 44}, {40, 39, 214},
                               {189, 103, 148}, {75, 86, 140}, {194, 119, 227}, {34, 189, 188}};

cv::Scalar Lighter(const cv::Scalar& c) { return (c + cv::Scalar(255, 255, 255) * 2.0) / 3.0; }

double NiceStep(double range) {
  const double raw = range / 6.0;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10.0 * p;
}

std::string Number(double v) {
  char b[32];
  std::snprintf(b, sizeof(b), "%g", std::fabs(v) < 1e-12 ? 0.0 : v);
  return b;
}

// Maps metres to pixels with equal scale on both axes (y up).
struct View {
  double x0, y0, scale;
  int left, bottom;
  cv::Point operator()(double x, double y) const {
    return cv::Point(static_cast<int>(std::lround(left + (x - x0) * scale)),
                     static_cast<int>(std::lround(bottom - (y - y0) * scale)));
  }
};

void PlaneAxes(const EvalReport& report, const std::string& plane, int* a, int* b) {
  if (plane == "xy") *a = 0, *b = 1;
  else if (plane == "xz") *a = 0, *b = 2;
  else if (plane == "yz") *a = 1, *b = 2;
  else {
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
    for (const AgentResult& agent : report.agents) {
      for (const SE3& p : agent.gt_matched) lo = lo.cwiseMin(p.translation()), hi = hi.cwiseMax(p.translation());
    }
    int drop = 0;
    (hi - lo).minCoeff(&drop);
    *a = drop == 0 ? 1 : 0;
    *b = drop == 2 ? 1 : 2;
  }
}

void DrawGrid(cv::Mat* img, const View& v, double x_min, double x_max, double y_min, double y_max,
              double step, int a, int b) {
  const char* names = "xyz";
  const cv::Scalar grid(225, 225, 225), text(60, 60, 60);
  for (double x = std::ceil(x_min / step) * step; x <= x_max; x += step) {
    cv::line(*img, v(x, y_min), v(x, y_max), grid, 1);
    cv::putText(*img, Number(x), v(x, y_min) + cv::Point(-10, 22), cv::FONT_HERSHEY_SIMPLEX, 0.45, text, 1, cv::LINE_AA);
  }
  for (double y = std::ceil(y_min / step) * step; y <= y_max; y += step) {
    cv::line(*img, v(x_min, y), v(x_max, y), grid, 1);
    cv::putText(*img, Number(y), v(x_min, y) + cv::Point(-55, 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, text, 1, cv::LINE_AA);
  }
  cv::rectangle(*img, v(x_min, y_max), v(x_max, y_min), cv::Scalar(120, 120, 120), 1);
  const cv::Point bottom_mid = v(0.5 * (x_min + x_max), y_min);
  cv::putText(*img, std::string(1, names[a]) + " [m]", bottom_mid + cv::Point(-20, 45),
              cv::FONT_HERSHEY_SIMPLEX, 0.55, text, 1, cv::LINE_AA);
  cv::putText(*img, std::string(1, names[b]) + " [m]", v(x_min, y_max) + cv::Point(-60, -12),
              cv::FONT_HERSHEY_SIMPLEX, 0.55, text, 1, cv::LINE_AA);
}

void DrawLegend(cv::Mat* img, const EvalReport& report, cv::Point origin) {
  int row = 0;
  for (size_t i = 0; i < report.agents.size(); ++i) {
    const cv::Scalar color = kPalette[i % 8];
    for (int k = 0; k < 2; ++k, ++row) {
      const cv::Point p = origin + cv::Point(0, 20 * row);
      cv::line(*img, p, p + cv::Point(30, 0), k == 0 ? Lighter(color) : color, k == 0 ? 4 : 2, cv::LINE_AA);
      cv::putText(*img, report.agents[i].name + (k == 0 ? " ground truth" : " estimate (aligned)"),
                  p + cv::Point(38, 5), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(30, 30, 30), 1, cv::LINE_AA);
    }
  }
}

}  // namespace

bool PlotOptions::Validate(std::string* error) const {
  if (plane != "auto" && plane != "xy" && plane != "xz" && plane != "yz") {
    *error = "plot plane must be auto, xy, xz or yz";
    return false;
  }
  if (size_px < 300 || size_px > 8000) {
    *error = "plot size must be in [300, 8000] px";
    return false;
  }
  return true;
}

cv::Mat RenderTopView(const EvalReport& report, const EvalOptions& eval_options,
                      const PlotOptions& options) {
  int a = 0, b = 1;
  PlaneAxes(report, options.plane, &a, &b);
  std::vector<std::vector<Eigen::Vector2d>> gt(report.agents.size()), est(report.agents.size());
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e300), hi = -lo;
  for (size_t i = 0; i < report.agents.size(); ++i) {
    const AgentResult& agent = report.agents[i];
    const std::vector<SE3> aligned = ApplyAlignment(report.joint.gt_from_est, agent.est_matched);
    for (size_t k = 0; k < agent.matched; ++k) {
      const Eigen::Vector3d g = agent.gt_matched[k].translation(), e = aligned[k].translation();
      gt[i].emplace_back(g(a), g(b));
      est[i].emplace_back(e(a), e(b));
      lo = lo.cwiseMin(gt[i].back()).cwiseMin(est[i].back());
      hi = hi.cwiseMax(gt[i].back()).cwiseMax(est[i].back());
    }
  }
  const double range = std::max({hi.x() - lo.x(), hi.y() - lo.y(), 1e-3});
  const Eigen::Vector2d mid = 0.5 * (lo + hi);
  const double half = 0.55 * range;
  const int margin_left = 80, margin_top = 60, plot_px = options.size_px - margin_left - 40;
  const int legend_h = 20 * 2 * static_cast<int>(report.agents.size()) + 10;
  cv::Mat img(options.size_px + legend_h, options.size_px, CV_8UC3, cv::Scalar(255, 255, 255));
  const View view{mid.x() - half, mid.y() - half, (plot_px - 20) / (2 * half), margin_left,
                  margin_top + plot_px - 20};
  DrawGrid(&img, view, mid.x() - half, mid.x() + half, mid.y() - half, mid.y() + half,
           NiceStep(2 * half), a, b);
  for (size_t i = 0; i < gt.size(); ++i) {
    const cv::Scalar color = kPalette[i % 8];
    for (int pass = 0; pass < 2; ++pass) {
      const auto& points = pass == 0 ? gt[i] : est[i];
      std::vector<cv::Point> poly;
      for (const Eigen::Vector2d& p : points) poly.push_back(view(p.x(), p.y()));
      cv::polylines(img, poly, false, pass == 0 ? Lighter(color) : color, pass == 0 ? 4 : 2, cv::LINE_AA);
    }
    if (!gt[i].empty()) cv::circle(img, view(gt[i][0].x(), gt[i][0].y()), 5, color, -1, cv::LINE_AA);
  }
  char title[160];
  std::snprintf(title, sizeof(title), "joint ATE rmse %.4f m (%s, %zu poses)",
                report.joint.ate_m.rmse, ToString(eval_options.alignment), report.joint.matched);
  cv::putText(img, title, cv::Point(margin_left, 30), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  DrawLegend(&img, report, cv::Point(margin_left, options.size_px + 5));
  return img;
}

}  // namespace ccm::tools
