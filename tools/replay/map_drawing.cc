#include "tools/replay/map_drawing.h"

#include <fstream>

#include <Eigen/Eigenvalues>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace ccm::replay {
namespace {

const cv::Scalar kAgentColours[] = {{40, 40, 220}, {40, 170, 40}, {220, 110, 30}, {180, 40, 180},
                                    {30, 170, 200}, {120, 120, 0}, {0, 120, 240}, {200, 0, 90}};
cv::Scalar AgentColour(size_t i) { return kAgentColours[i % (sizeof(kAgentColours) / sizeof(kAgentColours[0]))]; }

// World -> 2D: the two principal axes of the keyframe centres.
struct Projection {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d u = Eigen::Vector3d::UnitX(), v = Eigen::Vector3d::UnitY();
  Eigen::Vector2d operator()(const Eigen::Vector3d& p) const { return {u.dot(p - mean), v.dot(p - mean)}; }
};

Projection FitProjection(const std::vector<Eigen::Vector3d>& pts, bool z_up) {
  Projection pr;
  if (pts.empty()) return pr;
  for (const auto& p : pts) pr.mean += p;
  pr.mean /= static_cast<double>(pts.size());
  if (z_up) return pr;  // ground-truth frame of the simulator / EuRoC: look from above
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : pts) cov += (p - pr.mean) * (p - pr.mean).transpose();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  pr.u = es.eigenvectors().col(2);
  pr.v = es.eigenvectors().col(1);
  return pr;
}

}  // namespace

bool WriteMapPly(const std::string& path, const ServerBackend& backend, MapId map_id, std::string* error) {
  const auto smap = backend.stack().GetMap(map_id);
  std::vector<Eigen::Vector3d> points;
  std::vector<std::pair<Eigen::Vector3d, AgentId>> cams;
  if (smap) {
    for (const auto& mp : smap->map().map_points()) points.push_back(mp->position());
    for (const auto& kf : smap->map().keyframes()) cams.emplace_back(kf->camera_center(), kf->agent());
  }
  std::ofstream out(path);
  out << "ply\nformat ascii 1.0\ncomment ccm_replay fused map: points grey, keyframes per agent\n"
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

bool WriteMapTopView(const std::string& path, const ReplayResult& result, const ReplayEvaluation& ev,
                     const ServerBackend& backend, std::string* error, int size_px) {
  const bool aligned = ev.has_ground_truth && ev.collaborative_ate_m.count > 0;
  const Sim3 to_view = aligned ? ev.gt_from_map : Sim3();
  std::vector<std::vector<Eigen::Vector3d>> trajs, gts;
  std::vector<Eigen::Vector3d> all;
  for (const ReplayAgentResult& a : result.agents) {
    std::vector<Eigen::Vector3d> t, g;
    for (const auto& k : a.server_keyframes) {
      if (k.map == ev.final_map) t.push_back(to_view * k.world_from_cam.translation());
    }
    if (aligned) {
      for (const auto& p : a.ground_truth) g.push_back(p.world_from_cam.translation());
    }
    all.insert(all.end(), t.begin(), t.end());
    trajs.push_back(t);
    gts.push_back(g);
  }
  std::vector<Eigen::Vector3d> points;
  if (const auto smap = backend.stack().GetMap(ev.final_map)) {
    for (const auto& mp : smap->map().map_points()) points.push_back(to_view * mp->position());
  }
  const Projection proj = FitProjection(all.empty() ? points : all, aligned);
  Eigen::Vector2d lo(1e30, 1e30), hi(-1e30, -1e30);
  for (const auto& p : all.empty() ? points : all) {
    const Eigen::Vector2d q = proj(p);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  if (!(hi.x() > lo.x())) lo = Eigen::Vector2d(-1, -1), hi = Eigen::Vector2d(1, 1);
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
    const cv::Scalar c = AgentColour(result.agents[i].id);
    const cv::Scalar light = (c + cv::Scalar(255, 255, 255) * 2) / 3;
    for (size_t k = 1; k < gts[i].size(); ++k) cv::line(img, px(gts[i][k - 1]), px(gts[i][k]), light, 1, cv::LINE_AA);
    for (size_t k = 1; k < trajs[i].size(); ++k) cv::line(img, px(trajs[i][k - 1]), px(trajs[i][k]), c, 2, cv::LINE_AA);
    cv::putText(img, result.agents[i].name + (aligned ? " (light: ground truth)" : ""), {20, 40 + 28 * static_cast<int>(i)},
                cv::FONT_HERSHEY_SIMPLEX, 0.7, c, 2, cv::LINE_AA);
  }
  char title[200];
  std::snprintf(title, sizeof(title), "map %llu: %zu points%s", static_cast<unsigned long long>(ev.final_map.counter()),
                points.size(), aligned ? "" : " (map frame, principal axes)");
  cv::putText(img, title, {20, size_px - 50}, cv::FONT_HERSHEY_SIMPLEX, 0.7, {0, 0, 0}, 1, cv::LINE_AA);
  if (aligned) {
    std::snprintf(title, sizeof(title), "collaborative ATE %.3f m (%.3f%% of %.0f m)", ev.collaborative_ate_m.rmse,
                  ev.collaborative_ate_percent, ev.joint_path_m);
    cv::putText(img, title, {20, size_px - 20}, cv::FONT_HERSHEY_SIMPLEX, 0.7, {0, 0, 0}, 1, cv::LINE_AA);
  }
  // 1 m (aligned) / 1 map unit scale bar.
  const int bar = static_cast<int>(scale);
  cv::line(img, {size_px - 40 - bar, size_px - 30}, {size_px - 40, size_px - 30}, {0, 0, 0}, 3);
  cv::putText(img, aligned ? "1 m" : "1 unit", {size_px - 40 - bar, size_px - 40}, cv::FONT_HERSHEY_SIMPLEX, 0.6,
              {0, 0, 0}, 1, cv::LINE_AA);
  if (!cv::imwrite(path, img)) {
    *error = "cannot write " + path;
    return false;
  }
  return true;
}

}  // namespace ccm::replay
