#include "tests/sim/top_view.h"

#include <algorithm>
#include <limits>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace ccm::sim {

bool WriteTopView(const Simulation& sim, const std::string& path, int width_px, std::string* error) {
  Eigen::Vector2d lo(std::numeric_limits<double>::max(), std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  const auto& surfaces = sim.world()->surfaces();
  auto corners = [](const Surface& s) {
    return std::array<Eigen::Vector3d, 4>{s.origin, s.origin + s.size_u_m * s.axis_u,
                                          s.origin + s.size_u_m * s.axis_u + s.size_v_m * s.axis_v,
                                          s.origin + s.size_v_m * s.axis_v};
  };
  for (const Surface& s : surfaces) {
    for (const auto& c : corners(s)) lo = lo.cwiseMin(c.head<2>()), hi = hi.cwiseMax(c.head<2>());
  }
  const double margin = 1.0;
  lo.array() -= margin;
  hi.array() += margin;
  const double scale = width_px / (hi.x() - lo.x());
  const int height_px = std::max(1, static_cast<int>((hi.y() - lo.y()) * scale));
  cv::Mat img(height_px, width_px, CV_8UC3, cv::Scalar(255, 255, 255));
  auto px = [&](const Eigen::Vector3d& p) {
    return cv::Point(static_cast<int>((p.x() - lo.x()) * scale), static_cast<int>((hi.y() - p.y()) * scale));
  };
  for (const Surface& s : surfaces) {
    if (std::abs(s.normal().z()) > 0.9) continue;  // floors, ceilings, tops: outlines come from the sides
    const auto c = corners(s);
    cv::line(img, px(c[0]), px(c[1]), cv::Scalar(90, 90, 90), 2, cv::LINE_AA);
  }
  static const cv::Scalar kColours[] = {{200, 60, 30}, {30, 140, 30}, {30, 30, 200}, {200, 30, 200},
                                        {30, 160, 200}, {120, 60, 0}, {0, 110, 200}, {140, 140, 0}};
  for (int a = 0; a < sim.num_agents(); ++a) {
    const cv::Scalar colour = kColours[a % 8];
    const Trajectory& t = sim.trajectory(a);
    for (double time = 0.0; time + 0.1 <= t.duration_s(); time += 0.1) {
      cv::line(img, px(t.Position(time)), px(t.Position(time + 0.1)), colour, 1, cv::LINE_AA);
    }
    for (double time = 0.0; time <= t.duration_s(); time += 2.0) {  // viewing direction every 2 s
      const SE3 pose = t.WorldFromCam(time);
      const Eigen::Vector3d tip = pose.translation() + 0.8 * (pose.rotation() * Eigen::Vector3d::UnitZ());
      cv::line(img, px(pose.translation()), px(tip), colour, 1, cv::LINE_AA);
    }
    cv::circle(img, px(t.Position(0.0)), 5, colour, cv::FILLED);
    cv::putText(img, sim.agent_name(a), px(t.Position(0.0)) + cv::Point(6, -6), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                colour, 1, cv::LINE_AA);
  }
  if (!cv::imwrite(path, img)) {
    if (error) *error = "cannot write " + path;
    return false;
  }
  return true;
}

}  // namespace ccm::sim
