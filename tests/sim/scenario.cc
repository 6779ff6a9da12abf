#include "tests/sim/scenario.h"
#include "slam_core/geometry/camera_presets.h"

#include <set>

namespace ccm::sim {

CameraIntrinsics EurocCamera() { return EurocCam0Intrinsics(); }

CameraIntrinsics FisheyeCamera() {
  CameraIntrinsics c;
  c.type = CameraType::kFisheyeEquidistant;
  c.width_px = 752;
  c.height_px = 480;
  c.fx = 300.0;
  c.fy = 300.0;
  c.cx = 375.5;
  c.cy = 239.5;
  c.distortion = {0.0034823894, 0.0007150348, -0.0020532361, 0.0002029343};
  return c;
}

std::string Scenario::Validate() const {
  if (name.empty()) return "name must not be empty";
  if (std::string e = world.Validate(); !e.empty()) return "world: " + e;
  if (std::string e = ValidateIntrinsics(camera); !e.empty()) return "camera: " + e;
  if (std::string e = render.Validate(); !e.empty()) return "render: " + e;
  if (!(exposure_variation >= 0.0 && exposure_variation < 0.9)) return "exposure.variation must be in [0, 0.9)";
  if (!(exposure_period_s > 0.1)) return "exposure.period_s must be > 0.1";
  if (start_stamp_ns < 0) return "start_stamp_ns must be >= 0";
  if (agents.empty()) return "no agents";
  std::set<std::string> names;
  for (size_t i = 0; i < agents.size(); ++i) {
    const AgentSpec& a = agents[i];
    const std::string where = "agents[" + std::to_string(i) + "] ('" + a.name + "')";
    if (a.name.empty() || a.name.find_first_of("/\\ .") != std::string::npos)
      return where + ": name must be non-empty without '/', '\\', '.', or spaces (it is a folder name)";
    if (!names.insert(a.name).second) return where + ": duplicate agent name";
    if (!(a.rate_hz > 0.0 && a.rate_hz <= 1000.0)) return where + ": rate_hz must be in (0, 1000]";
    if (std::string e = a.trajectory.Validate(); !e.empty()) return where + ": " + e;
  }
  return {};
}

}  // namespace ccm::sim
