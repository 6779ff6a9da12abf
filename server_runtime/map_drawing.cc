#include "server_runtime/map_drawing.h"

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace ccm::report {
namespace {

const cv::Scalar kAgentColours[] = {{40, 40, 220}, {40, 170, 40}, {220, 110, 30}, {180, 40, 180},
                                    {30, 170, 200}, {120, 120, 0}, {0, 120, 240}, {200, 0, 90}};
cv::Scalar AgentColour(size_t i) { return kAgentColours[i % (sizeof(kAgentColours) / sizeof(kAgentColours[0]))]; }

// World -> 2D, seen from above: u, v span the ground plane with u x v = up.
struct Projection {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX(), v = Eigen::Vector3d::UnitY();
  Eigen::Vector2d operator()(const Eigen::Vector3d& p) const { return {u.dot(p - mean), v.dot(p - mean)}; }
};

// `cameras`: keyframe poses in the view frame. A level camera's image y axis points down, so
// the mean of -y over the keyframes is up; if the cameras disagree (looking down, rolling),
// the keyframe centres' least-spread axis is.
Projection FitProjection(const std::vector<SE3>& cameras, const std::vector<Eigen::Vector3d>& fallback_points) {
  Projection pr;
  std::vector<Eigen::Vector3d> pts;
  Eigen::Vector3d up_sum = Eigen::Vector3d::Zero();
  for (const SE3& c : cameras) {
    pts.push_back(c.translation());
    up_sum -= c.rotation() * Eigen::Vector3d::UnitY();
  }
  if (pts.empty()) pts = fallback_points;
  if (pts.empty()) return pr;
  for (const auto& p : pts) pr.mean += p;
  pr.mean /= static_cast<double>(pts.size());
  Eigen::Vector3d up;
  if (!cameras.empty() && up_sum.norm() >= 0.5 * static_cast<double>(cameras.size())) {
    up = up_sum.normalized();
  } else {
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
    for (const auto& p : pts) cov += (p - pr.mean) * (p - pr.mean).transpose();
    up = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
  }
  // u: the frame axis closest to the ground plane, so a z-up world keeps x to the right.
  int best = 0;
  for (int k = 1; k < 3; ++k) {
    if (std::abs(up[k]) < std::abs(up[best])) best = k;
  }
  const Eigen::Vector3d axis = Eigen::Vector3d::Unit(best);
  pr.u = (axis - axis.dot(up) * up).normalized();
  pr.v = up.cross(pr.u);
  return pr;
}

std::string AgentName(const RunResult& result, AgentId id) {
  for (const auto& a : result.agents) {
    if (a.id == id) return a.name;
  }
  return "agent" + std::to_string(id);
}

std::string Format(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, value);
  return buf;
}

void Text(cv::Mat* img, const std::string& s, cv::Point at, const cv::Scalar& colour, int thickness = 1) {
  cv::putText(*img, s, at, cv::FONT_HERSHEY_SIMPLEX, 0.6, colour, thickness, cv::LINE_AA);
}

// One map's panel: points, each agent's keyframe path (ground truth light, where scored).
cv::Mat DrawPanel(const MapScore& ms, const RunResult& result, const MapStackSnapshot& maps, bool largest,
                  int size_px) {
  const Sim3 to_view = ms.scored ? ms.gt_from_map : Sim3();
  std::vector<std::vector<Eigen::Vector3d>> trajs, gts;
  std::vector<SE3> cameras;
  for (const AgentInMap& part : ms.agents) {
    std::vector<Eigen::Vector3d> t, g;
    int64_t first_ns = INT64_MAX, last_ns = INT64_MIN;
    for (const AgentRunResult& a : result.agents) {
      if (a.id != part.id) continue;
      for (const auto& k : a.server_keyframes) {
        if (k.map != ms.summary.id) continue;
        cameras.push_back(to_view.TransformPose(k.world_from_cam));
        t.push_back(cameras.back().translation());
        first_ns = std::min(first_ns, k.stamp_ns);
        last_ns = std::max(last_ns, k.stamp_ns);
      }
      for (const auto& p : a.ground_truth) {
        if (ms.scored && p.stamp_ns >= first_ns && p.stamp_ns <= last_ns) g.push_back(p.world_from_cam.translation());
      }
    }
    trajs.push_back(t);
    gts.push_back(g);
  }
  std::vector<Eigen::Vector3d> points;
  if (const auto smap = maps.Map(ms.summary.id)) {
    for (const auto& mp : smap->map().map_points()) points.push_back(to_view * mp->position());
  }
  const Projection proj = FitProjection(cameras, points);
  Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
  for (const SE3& c : cameras) {
    lo = lo.cwiseMin(proj(c.translation()));
    hi = hi.cwiseMax(proj(c.translation()));
  }
  for (const auto& p : cameras.empty() ? points : std::vector<Eigen::Vector3d>{}) {
    lo = lo.cwiseMin(proj(p));
    hi = hi.cwiseMax(proj(p));
  }
  if (!(hi.x() >= lo.x())) lo = Eigen::Vector2d(-1, -1), hi = Eigen::Vector2d(1, 1);
  const Eigen::Vector2d margin = 0.15 * (hi - lo) + Eigen::Vector2d(0.5, 0.5);
  lo -= margin;
  hi += margin;
  const double scale = (size_px - 1) / std::max(hi.x() - lo.x(), hi.y() - lo.y());
  auto px = [&](const Eigen::Vector3d& p) {
    const Eigen::Vector2d q = proj(p);
    return cv::Point(static_cast<int>((q.x() - lo.x()) * scale), static_cast<int>(size_px - 1 - (q.y() - lo.y()) * scale));
  };
  cv::Mat img(size_px, size_px, CV_8UC3, cv::Scalar(255, 255, 255));
  for (const auto& p : points) {
    const cv::Point q = px(p);
    if (q.inside(cv::Rect(0, 0, size_px, size_px))) img.at<cv::Vec3b>(q) = cv::Vec3b(170, 170, 170);
  }
  for (size_t i = 0; i < trajs.size(); ++i) {
    const cv::Scalar c = AgentColour(ms.agents[i].id);
    const cv::Scalar light = (c + cv::Scalar(255, 255, 255) * 2) / 3;
    for (size_t k = 1; k < gts[i].size(); ++k) cv::line(img, px(gts[i][k - 1]), px(gts[i][k]), light, 1, cv::LINE_AA);
    for (size_t k = 1; k < trajs[i].size(); ++k) cv::line(img, px(trajs[i][k - 1]), px(trajs[i][k]), c, 2, cv::LINE_AA);
    Text(&img, AgentName(result, ms.agents[i].id) + ": " + std::to_string(ms.agents[i].keyframes) + " keyframes",
         {20, 60 + 26 * static_cast<int>(i)}, c, 2);
  }
  char line[240];
  std::snprintf(line, sizeof(line), "map %llu%s: %zu keyframes, %zu points%s",
                static_cast<unsigned long long>(ms.summary.id.counter()), largest ? " (largest)" : "",
                ms.summary.keyframes + ms.summary.anchored, points.size(),
                ms.scored ? " (ground-truth frame)" : " (map frame)");
  Text(&img, line, {20, 30}, {0, 0, 0}, 2);
  if (ms.scored) {
    std::string s = "joint ATE " + Format("%.3f", ms.joint_ate_m.rmse) + " m (" + Format("%.2f", ms.joint_ate_percent) +
                    "% of " + Format(ms.path_m < 10 ? "%.1f" : "%.0f", ms.path_m) + " m)";
    if (ms.scale_ratio > 0) s += ", agents' scale ratio " + Format("%.3f", ms.scale_ratio);
    Text(&img, s + "; light: ground truth", {20, size_px - 20}, {0, 0, 0});
  }
  // A scale bar of a round length near a fifth of the panel (m when scored, else map units).
  const double target = 0.2 * (size_px - 1) / scale;
  const double decade = std::pow(10.0, std::floor(std::log10(target)));
  const double bar_len = 5 * decade <= target ? 5 * decade : (2 * decade <= target ? 2 * decade : decade);
  const int bar = static_cast<int>(bar_len * scale);
  const std::string bar_text = Format("%g", bar_len) + (ms.scored ? " m" : " units");
  int baseline = 0;
  const int text_w = cv::getTextSize(bar_text, cv::FONT_HERSHEY_SIMPLEX, 0.6, 1, &baseline).width;
  cv::line(img, {size_px - 30 - bar, size_px - 50}, {size_px - 30, size_px - 50}, {0, 0, 0}, 3);
  Text(&img, bar_text, {size_px - 30 - std::max(bar, text_w), size_px - 60}, {0, 0, 0});
  cv::rectangle(img, cv::Rect(0, 0, size_px, size_px), {120, 120, 120}, 1);
  return img;
}

}  // namespace

bool WriteMapPly(const std::string& path, const MapStackSnapshot& maps, MapId map_id, std::string* error) {
  const auto smap = maps.Map(map_id);
  std::vector<Eigen::Vector3d> points;
  std::vector<std::pair<Eigen::Vector3d, AgentId>> cams;
  if (smap) {
    for (const auto& mp : smap->map().map_points()) points.push_back(mp->position());
    for (const auto& kf : smap->map().keyframes()) cams.emplace_back(kf->camera_center(), kf->agent());
  }
  std::ofstream out(path);
  out << "ply\nformat ascii 1.0\ncomment ccm_replay map " << map_id.counter() << ": points grey, keyframes per agent\n"
      << "element vertex " << points.size() + cams.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
  for (const auto& p : points) out << p.x() << ' ' << p.y() << ' ' << p.z() << " 160 160 160\n";
  for (const auto& [c, agent] : cams) {
    const cv::Scalar col = AgentColour(agent);
    out << c.x() << ' ' << c.y() << ' ' << c.z() << ' ' << static_cast<int>(col[2]) << ' ' << static_cast<int>(col[1])
        << ' ' << static_cast<int>(col[0]) << "\n";
  }
  if (!out) {
    *error = "cannot write " + path;
    return false;
  }
  return true;
}

bool WriteMapTopView(const std::string& path, const RunResult& result, const RunEvaluation& ev,
                     const MapStackSnapshot& maps, std::string* error, int panel_px) {
  const int n = static_cast<int>(ev.map_scores.size());
  if (panel_px <= 0) panel_px = n <= 1 ? 1200 : 800;
  // Two maps side by side, up to four in a square, more three to a row.
  const int cols = n <= 2 ? std::max(n, 1) : (n <= 4 ? 2 : 3);
  const int rows = std::max(1, (n + cols - 1) / cols);
  cv::Mat img(rows * panel_px, cols * panel_px, CV_8UC3, cv::Scalar(255, 255, 255));
  for (int i = 0; i < n; ++i) {
    const MapScore& ms = ev.map_scores[i];
    DrawPanel(ms, result, maps, ms.summary.id == ev.final_map, panel_px)
        .copyTo(img(cv::Rect((i % cols) * panel_px, (i / cols) * panel_px, panel_px, panel_px)));
  }
  if (n == 0) Text(&img, "no map", {20, 30}, {0, 0, 0}, 2);
  if (!cv::imwrite(path, img)) {
    *error = "cannot write " + path;
    return false;
  }
  return true;
}

}  // namespace ccm::report
