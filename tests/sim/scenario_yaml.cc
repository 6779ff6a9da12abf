// YAML -> Scenario. Every key is checked: unknown keys, wrong types and out-of-range
// values are reported with their path (e.g. "agents[1].waypoints[3]").
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <yaml-cpp/yaml.h>

#include "tests/sim/scenario.h"
#include "tests/sim/scene_generator.h"

namespace ccm::sim {

namespace {

struct ParseError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

void CheckKeys(const YAML::Node& node, const std::string& path, const std::set<std::string>& allowed) {
  if (!node.IsMap()) throw ParseError(path + ": expected a mapping");
  for (const auto& kv : node) {
    const std::string key = kv.first.as<std::string>();
    if (!allowed.count(key)) {
      std::string list;
      for (const auto& a : allowed) list += (list.empty() ? "" : ", ") + a;
      throw ParseError(path + ": unknown key '" + key + "' (allowed: " + list + ")");
    }
  }
}

template <typename T>
T Get(const YAML::Node& node, const std::string& key, const std::string& path, const T& fallback) {
  const YAML::Node v = node[key];
  if (!v) return fallback;
  try {
    return v.as<T>();
  } catch (const YAML::Exception&) {
    throw ParseError(path + "." + key + ": wrong type");
  }
}

template <typename T>
T Require(const YAML::Node& node, const std::string& key, const std::string& path) {
  if (!node[key]) throw ParseError(path + ": missing required key '" + key + "'");
  return Get<T>(node, key, path, T());
}

std::vector<double> Numbers(const YAML::Node& node, const std::string& path, size_t min_n, size_t max_n) {
  if (!node.IsSequence()) throw ParseError(path + ": expected a list of numbers");
  std::vector<double> out;
  try {
    for (const auto& x : node) out.push_back(x.as<double>());
  } catch (const YAML::Exception&) {
    throw ParseError(path + ": expected numbers");
  }
  if (out.size() < min_n || out.size() > max_n)
    throw ParseError(path + ": expected " + std::to_string(min_n) +
                     (min_n == max_n ? "" : "-" + std::to_string(max_n)) + " numbers, got " +
                     std::to_string(out.size()));
  return out;
}

TextureStyle Style(const YAML::Node& node, const std::string& key, const std::string& path, TextureStyle fallback) {
  if (!node[key]) return fallback;
  TextureStyle s;
  const std::string name = Get<std::string>(node, key, path, "");
  if (!ParseTextureStyle(name, &s))
    throw ParseError(path + "." + key + ": unknown texture style '" + name + "' (rich, mixed, weak, flat)");
  return s;
}

CameraIntrinsics ParseCamera(const YAML::Node& n, const std::string& path) {
  CheckKeys(n, path, {"model", "width", "height", "fx", "fy", "cx", "cy", "distortion"});
  const std::string model = Get<std::string>(n, "model", path, "pinhole-radtan");
  CameraIntrinsics c = model == "fisheye-equidistant" ? FisheyeCamera() : EurocCamera();
  if (model != "pinhole-radtan" && model != "fisheye-equidistant")
    throw ParseError(path + ".model: unknown camera model '" + model + "' (pinhole-radtan, fisheye-equidistant)");
  c.width_px = Get<int>(n, "width", path, c.width_px);
  c.height_px = Get<int>(n, "height", path, c.height_px);
  c.fx = Get<double>(n, "fx", path, c.fx);
  c.fy = Get<double>(n, "fy", path, c.fy);
  c.cx = Get<double>(n, "cx", path, c.cx);
  c.cy = Get<double>(n, "cy", path, c.cy);
  if (n["distortion"]) c.distortion = Numbers(n["distortion"], path + ".distortion", 0, 5);
  return c;
}

ObjectSpec ParseObject(const YAML::Node& n, const std::string& path) {
  ObjectSpec o;
  const std::string type = Require<std::string>(n, "type", path);
  o.name = Get<std::string>(n, "name", path, "");
  o.style = Style(n, "style", path, TextureStyle::kMixed);
  o.grey = Get<float>(n, "grey", path, 128.0f);
  o.share_key = Get<std::string>(n, "share", path, "");
  if (type == "room") {
    CheckKeys(n, path, {"type", "name", "min", "max", "style", "floor", "ceiling", "walls", "grey", "share"});
    const auto a = Numbers(n["min"], path + ".min", 3, 3), b = Numbers(n["max"], path + ".max", 3, 3);
    o.kind = ObjectKind::kRoom;
    o.min = Eigen::Vector3d(a[0], a[1], a[2]);
    o.max = Eigen::Vector3d(b[0], b[1], b[2]);
    o.room_styles = {Style(n, "floor", path, o.style), Style(n, "ceiling", path, o.style),
                     Style(n, "walls", path, o.style)};
  } else if (type == "box" || type == "pillar") {
    CheckKeys(n, path, {"type", "name", "center", "size", "base_z", "yaw_deg", "style", "grey", "share"});
    const auto c = Numbers(n["center"], path + ".center", 2, 2), s = Numbers(n["size"], path + ".size", 3, 3);
    const double z0 = Get<double>(n, "base_z", path, 0.0);
    o.kind = type == "box" ? ObjectKind::kBox : ObjectKind::kPillar;
    o.min = Eigen::Vector3d(c[0] - 0.5 * s[0], c[1] - 0.5 * s[1], z0);
    o.max = Eigen::Vector3d(c[0] + 0.5 * s[0], c[1] + 0.5 * s[1], z0 + s[2]);
    o.yaw_deg = Get<double>(n, "yaw_deg", path, 0.0);
  } else if (type == "panel") {
    CheckKeys(n, path, {"type", "name", "center", "normal", "size", "style", "grey", "share"});
    const auto c = Numbers(n["center"], path + ".center", 3, 3), nn = Numbers(n["normal"], path + ".normal", 3, 3);
    const auto s = Numbers(n["size"], path + ".size", 2, 2);
    o.kind = ObjectKind::kPanel;
    o.min = Eigen::Vector3d(c[0], c[1], c[2]);
    o.normal = Eigen::Vector3d(nn[0], nn[1], nn[2]);
    o.max = Eigen::Vector3d(s[0], s[1], 0.0);
  } else {
    throw ParseError(path + ".type: unknown object type '" + type + "' (room, box, pillar, panel)");
  }
  return o;
}

AgentSpec ParseAgent(const YAML::Node& n, const std::string& path) {
  CheckKeys(n, path, {"name", "rate_hz", "duration_s", "loop", "speed_mps", "speed_period_s", "pitch_deg",
                      "wobble_deg", "look_ahead_m", "waypoints"});
  AgentSpec a;
  TrajectorySpec& t = a.trajectory;
  a.name = Require<std::string>(n, "name", path);
  a.rate_hz = Get<double>(n, "rate_hz", path, a.rate_hz);
  t.duration_s = Require<double>(n, "duration_s", path);
  t.loop = Get<bool>(n, "loop", path, t.loop);
  if (n["speed_mps"]) {
    const auto v = Numbers(n["speed_mps"], path + ".speed_mps", 2, 2);
    t.min_speed_mps = v[0];
    t.max_speed_mps = v[1];
  }
  t.speed_period_s = Get<double>(n, "speed_period_s", path, t.speed_period_s);
  t.pitch_deg = Get<double>(n, "pitch_deg", path, t.pitch_deg);
  t.wobble_deg = Get<double>(n, "wobble_deg", path, t.wobble_deg);
  t.look_ahead_m = Get<double>(n, "look_ahead_m", path, t.look_ahead_m);
  const YAML::Node wps = n["waypoints"];
  if (!wps || !wps.IsSequence()) throw ParseError(path + ".waypoints: expected a list of [x, y, z(, yaw_offset_deg)]");
  for (size_t i = 0; i < wps.size(); ++i) {
    const auto w = Numbers(wps[i], path + ".waypoints[" + std::to_string(i) + "]", 3, 4);
    Waypoint wp;
    wp.position_m = Eigen::Vector3d(w[0], w[1], w[2]);
    wp.yaw_offset_deg = w.size() == 4 ? w[3] : 0.0;
    t.waypoints.push_back(wp);
  }
  return a;
}

void ParseRender(const YAML::Node& n, const std::string& path, RenderOptions* r) {
  CheckKeys(n, path, {"read_noise_dn", "shot_noise_gain", "vignetting", "lod_bias", "anisotropy",
                      "motion_blur_samples", "exposure_time_s"});
  r->read_noise_dn = Get<double>(n, "read_noise_dn", path, r->read_noise_dn);
  r->shot_noise_gain = Get<double>(n, "shot_noise_gain", path, r->shot_noise_gain);
  r->vignetting = Get<double>(n, "vignetting", path, r->vignetting);
  r->lod_bias = Get<double>(n, "lod_bias", path, r->lod_bias);
  r->anisotropy = Get<double>(n, "anisotropy", path, r->anisotropy);
  r->motion_blur_samples = Get<int>(n, "motion_blur_samples", path, r->motion_blur_samples);
  r->exposure_time_s = Get<double>(n, "exposure_time_s", path, r->exposure_time_s);
}

Scenario ParseRoot(const YAML::Node& root) {
  CheckKeys(root, "scenario", {"name", "description", "seed", "start_stamp_ns", "texel_m", "background_grey",
                               "camera", "render", "exposure", "objects", "agents"});
  Scenario s;
  s.name = Require<std::string>(root, "name", "scenario");
  s.description = Get<std::string>(root, "description", "scenario", "");
  s.seed = Get<std::uint64_t>(root, "seed", "scenario", s.seed);
  s.start_stamp_ns = Get<std::int64_t>(root, "start_stamp_ns", "scenario", s.start_stamp_ns);
  s.world.texel_m = Get<double>(root, "texel_m", "scenario", s.world.texel_m);
  s.world.background_grey = Get<float>(root, "background_grey", "scenario", s.world.background_grey);
  s.camera = root["camera"] ? ParseCamera(root["camera"], "camera") : EurocCamera();
  if (root["render"]) ParseRender(root["render"], "render", &s.render);
  if (const YAML::Node e = root["exposure"]) {
    CheckKeys(e, "exposure", {"variation", "period_s"});
    s.exposure_variation = Get<double>(e, "variation", "exposure", s.exposure_variation);
    s.exposure_period_s = Get<double>(e, "period_s", "exposure", s.exposure_period_s);
  }
  const YAML::Node objects = root["objects"];
  if (!objects || !objects.IsSequence()) throw ParseError("scenario: 'objects' must be a list");
  for (size_t i = 0; i < objects.size(); ++i)
    s.world.objects.push_back(ParseObject(objects[i], "objects[" + std::to_string(i) + "]"));
  const YAML::Node agents = root["agents"];
  if (!agents || !agents.IsSequence()) throw ParseError("scenario: 'agents' must be a list");
  for (size_t i = 0; i < agents.size(); ++i)
    s.agents.push_back(ParseAgent(agents[i], "agents[" + std::to_string(i) + "]"));
  return s;
}

}  // namespace

std::optional<Scenario> ParseScenarioYaml(const std::string& text, const std::string& origin, std::string* error) {
  try {
    Scenario s = ParseRoot(YAML::Load(text));
    const std::string problem = s.Validate();
    if (!problem.empty()) throw ParseError(problem);
    return s;
  } catch (const ParseError& e) {
    if (error) *error = origin + ": " + e.what();
  } catch (const YAML::Exception& e) {
    if (error) *error = origin + ": YAML syntax error: " + e.what();
  }
  return std::nullopt;
}

std::optional<Scenario> LoadScenario(const std::string& name_or_path, std::string* error) {
  if (const auto text = BuiltinScenarioYaml(name_or_path)) return ParseScenarioYaml(*text, name_or_path, error);
  if (const auto text = GeneratedScenarioYaml(name_or_path)) return ParseScenarioYaml(*text, name_or_path, error);
  std::ifstream in(name_or_path);
  if (!in) {
    std::string names;
    for (const auto& [n, d] : BuiltinScenarios()) names += (names.empty() ? "" : ", ") + n;
    if (error) {
      *error = "'" + name_or_path + "' is neither a built-in scenario (" + names +
               "), a generated one (gen:SEED) nor a readable file";
    }
    return std::nullopt;
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return ParseScenarioYaml(ss.str(), name_or_path, error);
}

}  // namespace ccm::sim
