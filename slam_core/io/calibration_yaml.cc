#include "slam_core/io/calibration_yaml.h"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <vector>

namespace ccm {
namespace {

IoStatus Load(const std::string& path, YAML::Node* root) {
  try {
    *root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    return IoStatus::Error("cannot open " + path);
  } catch (const YAML::Exception& e) {
    return IoStatus::Error(path + ":" + std::to_string(e.mark.line + 1) + ": YAML error: " + e.msg);
  }
  if (!root->IsMap()) return IoStatus::Error(path + ": expected a YAML map at the top level");
  return IoStatus::Ok();
}

// Reads a numeric sequence; `expected` < 0 accepts any length.
IoStatus ReadNumbers(const YAML::Node& node, const std::string& path, const std::string& key,
                     int expected, std::vector<double>* out) {
  out->clear();
  if (!node || !node.IsSequence()) return IoStatus::Error(path + ": '" + key + "' must be a list");
  try {
    for (const YAML::Node& item : node) out->push_back(item.as<double>());
  } catch (const YAML::Exception& e) {
    return IoStatus::Error(path + ":" + std::to_string(e.mark.line + 1) + ": '" + key +
                           "' must contain numbers");
  }
  if (expected >= 0 && static_cast<int>(out->size()) != expected) {
    return IoStatus::Error(path + ": '" + key + "' must have " + std::to_string(expected) +
                           " numbers, has " + std::to_string(out->size()));
  }
  return IoStatus::Ok();
}

IoStatus ParseDistortionModel(const std::string& model, const std::string& path,
                              CameraType* type) {
  if (model == "radial-tangential" || model == "radtan" || model == "plumb_bob") {
    *type = CameraType::kPinholeRadTan;
  } else if (model == "equidistant" || model == "fisheye" || model == "kannala_brandt") {
    *type = CameraType::kFisheyeEquidistant;
  } else {
    return IoStatus::Error(path + ": unsupported distortion_model '" + model +
                           "' (use radial-tangential or equidistant)");
  }
  return IoStatus::Ok();
}

IoStatus ParseEurocIntrinsics(const YAML::Node& root, const std::string& path,
                              CameraIntrinsics* intrinsics) {
  const std::string model = root["camera_model"] ? root["camera_model"].as<std::string>() : "pinhole";
  if (model != "pinhole") {
    return IoStatus::Error(path + ": unsupported camera_model '" + model + "' (only pinhole)");
  }
  std::vector<double> k, res;
  IoStatus status = ReadNumbers(root["intrinsics"], path, "intrinsics", 4, &k);
  if (!status.ok() || !(status = ReadNumbers(root["resolution"], path, "resolution", 2, &res)).ok()) {
    return status;
  }
  *intrinsics = CameraIntrinsics();
  intrinsics->fx = k[0];
  intrinsics->fy = k[1];
  intrinsics->cx = k[2];
  intrinsics->cy = k[3];
  intrinsics->width_px = static_cast<int>(res[0]);
  intrinsics->height_px = static_cast<int>(res[1]);
  const std::string dist_model = root["distortion_model"]
                                     ? root["distortion_model"].as<std::string>()
                                     : "radial-tangential";
  if (!(status = ParseDistortionModel(dist_model, path, &intrinsics->type)).ok()) return status;
  intrinsics->distortion.assign(4, 0.0);
  if (root["distortion_coefficients"]) {
    status = ReadNumbers(root["distortion_coefficients"], path, "distortion_coefficients", -1,
                         &intrinsics->distortion);
  }
  if (!status.ok()) return status;
  return ValidateIntrinsics(*intrinsics, path);
}

IoStatus ParseBodyFromCam(const YAML::Node& root, const std::string& path, SE3* body_from_cam) {
  *body_from_cam = SE3();
  if (!root["T_BS"]) return IoStatus::Ok();
  const YAML::Node t_bs = root["T_BS"];
  std::vector<double> m;
  IoStatus status = ReadNumbers(t_bs.IsMap() ? t_bs["data"] : t_bs, path, "T_BS data", 16, &m);
  if (!status.ok()) return status;
  Eigen::Matrix3d R;
  R << m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10];
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0) {
    return IoStatus::Error(path + ": T_BS rotation is not orthonormal");
  }
  *body_from_cam = SE3(R, Eigen::Vector3d(m[3], m[7], m[11]));
  return IoStatus::Ok();
}

// Flat keys, optionally with the ORB-SLAM "Camera." prefix.
YAML::Node Flat(const YAML::Node& root, const std::string& key) {
  if (root[key]) return root[key];
  return root["Camera." + key];
}

IoStatus ParseFlatIntrinsics(const YAML::Node& root, const std::string& path,
                             CameraIntrinsics* intrinsics) {
  *intrinsics = CameraIntrinsics();
  double* targets[] = {&intrinsics->fx, &intrinsics->fy, &intrinsics->cx, &intrinsics->cy};
  const char* names[] = {"fx", "fy", "cx", "cy"};
  try {
    for (int i = 0; i < 4; ++i) {
      if (!Flat(root, names[i])) return IoStatus::Error(path + ": missing key '" + names[i] + "'");
      *targets[i] = Flat(root, names[i]).as<double>();
    }
    if (!Flat(root, "width") || !Flat(root, "height")) {
      return IoStatus::Error(path + ": missing key 'width' or 'height'");
    }
    intrinsics->width_px = Flat(root, "width").as<int>();
    intrinsics->height_px = Flat(root, "height").as<int>();
    const std::string model = root["distortion_model"] ? root["distortion_model"].as<std::string>()
                                                        : "radial-tangential";
    IoStatus status = ParseDistortionModel(model, path, &intrinsics->type);
    if (!status.ok()) return status;
    if (root["distortion"]) {
      return ReadNumbers(root["distortion"], path, "distortion", -1, &intrinsics->distortion);
    }
    intrinsics->distortion.assign(4, 0.0);
    const char* coeffs[] = {"k1", "k2", "p1", "p2", "k3"};
    for (int i = 0; i < 5; ++i) {
      if (Flat(root, coeffs[i])) {
        if (i == 4) intrinsics->distortion.push_back(0.0);
        intrinsics->distortion[i] = Flat(root, coeffs[i]).as<double>();
      }
    }
  } catch (const YAML::Exception& e) {
    return IoStatus::Error(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  return IoStatus::Ok();
}

}  // namespace

IoStatus ValidateIntrinsics(const CameraIntrinsics& k, const std::string& what) {
  if (!(k.fx > 0 && k.fy > 0 && std::isfinite(k.cx) && std::isfinite(k.cy))) {
    return IoStatus::Error(what + ": focal lengths must be positive");
  }
  if (k.width_px <= 0 || k.height_px <= 0) {
    return IoStatus::Error(what + ": image size must be positive");
  }
  const size_t n = k.distortion.size();
  if (k.type == CameraType::kPinholeRadTan && n != 4 && n != 5) {
    return IoStatus::Error(what + ": radial-tangential needs 4 or 5 coefficients, has " +
                           std::to_string(n));
  }
  if (k.type == CameraType::kFisheyeEquidistant && n != 4) {
    return IoStatus::Error(what + ": equidistant needs 4 coefficients, has " + std::to_string(n));
  }
  return IoStatus::Ok();
}

IoStatus ReadEurocSensorYaml(const std::string& path, EurocCameraCalibration* calibration) {
  YAML::Node root;
  IoStatus status = Load(path, &root);
  if (!status.ok()) return status;
  try {
    if (!(status = ParseEurocIntrinsics(root, path, &calibration->intrinsics)).ok()) return status;
    if (!(status = ParseBodyFromCam(root, path, &calibration->body_from_cam)).ok()) return status;
    calibration->rate_hz = root["rate_hz"] ? root["rate_hz"].as<double>() : 0.0;
  } catch (const YAML::Exception& e) {
    return IoStatus::Error(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  return IoStatus::Ok();
}

IoStatus ReadCalibrationYaml(const std::string& path, CameraIntrinsics* intrinsics) {
  YAML::Node root;
  IoStatus status = Load(path, &root);
  if (!status.ok()) return status;
  if (root["intrinsics"]) {
    try {
      return ParseEurocIntrinsics(root, path, intrinsics);
    } catch (const YAML::Exception& e) {
      return IoStatus::Error(path + ":" + std::to_string(e.mark.line + 1) + ": " + e.msg);
    }
  }
  if (!(status = ParseFlatIntrinsics(root, path, intrinsics)).ok()) return status;
  return ValidateIntrinsics(*intrinsics, path);
}

}  // namespace ccm
