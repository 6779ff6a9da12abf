#include "tests/sim/euroc_writer.h"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include <opencv2/imgcodecs.hpp>

namespace ccm::sim {

namespace fs = std::filesystem;

const char* EurocGroundTruthHeader() {
  return "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], q_RS_z [], "
         "v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], b_w_RS_S_x [rad s^-1], "
         "b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], "
         "b_a_RS_S_z [m s^-2]";
}

std::string EurocSensorYaml(const CameraIntrinsics& c, double rate_hz) {
  std::ostringstream y;
  y.precision(12);
  y << "# General sensor definitions.\n"
    << "sensor_type: camera\n"
    << "comment: ccm_sim simulated camera (" << CameraTypeName(c.type) << ")\n\n"
    << "# Sensor extrinsics wrt. the body-frame.\n"
    << "T_BS:\n  cols: 4\n  rows: 4\n"
    << "  data: [1.0, 0.0, 0.0, 0.0,\n         0.0, 1.0, 0.0, 0.0,\n"
    << "         0.0, 0.0, 1.0, 0.0,\n         0.0, 0.0, 0.0, 1.0]\n\n"
    << "# Camera specific definitions.\n"
    << "rate_hz: " << rate_hz << "\n"
    << "resolution: [" << c.width_px << ", " << c.height_px << "]\n"
    << "camera_model: pinhole\n"
    << "intrinsics: [" << c.fx << ", " << c.fy << ", " << c.cx << ", " << c.cy << "] #fu, fv, cu, cv\n"
    << "distortion_model: "
    << (c.type == CameraType::kFisheyeEquidistant ? "equidistant" : "radial-tangential") << "\n"
    << "distortion_coefficients: [";
  for (size_t i = 0; i < c.distortion.size(); ++i) y << (i ? ", " : "") << c.distortion[i];
  y << "]\n";
  return y.str();
}

std::string WriteEurocAgent(const Simulation& sim, int agent, const std::string& out_dir, std::int64_t max_frames,
                            const ProgressFn& progress) {
  const fs::path mav0 = fs::path(out_dir) / sim.agent_name(agent) / "mav0";
  const fs::path cam0 = mav0 / "cam0";
  const fs::path gt_dir = mav0 / "state_groundtruth_estimate0";
  std::error_code ec;
  fs::create_directories(cam0 / "data", ec);
  if (!ec) fs::create_directories(gt_dir, ec);
  if (ec) return "cannot create " + (cam0 / "data").string() + ": " + ec.message();
  const double rate = sim.scenario().agents.at(agent).rate_hz;
  {
    std::ofstream sensor(cam0 / "sensor.yaml");
    sensor << EurocSensorYaml(sim.scenario().camera, rate);
    if (!sensor) return "cannot write " + (cam0 / "sensor.yaml").string();
  }
  std::ofstream images(cam0 / "data.csv");
  std::ofstream gt(gt_dir / "data.csv");
  if (!images || !gt) return "cannot write the CSV files under " + mav0.string();
  images << "#timestamp [ns],filename\n";
  gt << EurocGroundTruthHeader() << "\n";
  std::int64_t n = sim.NumFrames(agent);
  if (max_frames >= 0) n = std::min(n, max_frames);
  char line[512];
  for (std::int64_t i = 0; i < n; ++i) {
    const std::int64_t stamp = sim.StampNs(agent, i);
    const std::string name = std::to_string(stamp) + ".png";
    // Fast PNG compression: writing, not rendering, would otherwise dominate.
    if (!cv::imwrite((cam0 / "data" / name).string(), sim.RenderFrame(agent, i), {cv::IMWRITE_PNG_COMPRESSION, 1}))
      return "cannot write image " + (cam0 / "data" / name).string();
    images << stamp << "," << name << "\n";
    const SE3 pose = sim.WorldFromCam(agent, i);
    const Eigen::Vector3d& p = pose.translation();
    const Eigen::Quaterniond& q = pose.rotation();
    const Eigen::Vector3d v = sim.trajectory(agent).Velocity(sim.TimeS(agent, i));
    std::snprintf(line, sizeof(line), "%lld,%.9f,%.9f,%.9f,%.12f,%.12f,%.12f,%.12f,%.9f,%.9f,%.9f,0,0,0,0,0,0\n",
                  static_cast<long long>(stamp), p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), v.x(), v.y(),
                  v.z());
    gt << line;
    if (progress) progress(i + 1, n);
  }
  images.flush();
  gt.flush();
  if (!images || !gt) return "error while writing the CSV files under " + mav0.string();
  return {};
}

}  // namespace ccm::sim
