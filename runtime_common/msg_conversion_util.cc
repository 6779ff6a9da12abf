#include "runtime_common/msg_conversion_util.h"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "runtime_common/msg_conversion.h"

namespace ccm::conv {
namespace {

bool SameIntrinsics(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  return a.type == b.type && a.width_px == b.width_px && a.height_px == b.height_px && a.fx == b.fx &&
         a.fy == b.fy && a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

// Beyond ValidateIntrinsics: values a real calibration never has, which would make every
// projection downstream compute with huge numbers.
std::string CheckCameraSanity(const CameraIntrinsics& c) {
  if (c.fx > kMaxFocalLengthPx || c.fy > kMaxFocalLengthPx) return "focal length beyond 1e5 px";
  if (c.cx < -c.width_px || c.cx > 2.0 * c.width_px || c.cy < -c.height_px || c.cy > 2.0 * c.height_px) {
    return "principal point far outside the image";
  }
  for (double d : c.distortion) {
    if (std::abs(d) > kMaxDistortionCoefficient) return "distortion coefficient beyond 1e4";
  }
  return "";
}

}  // namespace

std::shared_ptr<const CameraModel> CameraCache::Get(const CameraIntrinsics& intrinsics, std::string* error) {
  ++clock_;
  for (Entry& e : entries_) {
    if (SameIntrinsics(e.intrinsics, intrinsics)) {
      e.last_use = clock_;
      return e.model;
    }
  }
  std::shared_ptr<const CameraModel> model(MakeCamera(intrinsics));
  if (!model) {
    if (error != nullptr) *error = ValidateIntrinsics(intrinsics);
    return nullptr;
  }
  if (entries_.size() >= capacity_) {
    entries_.erase(std::min_element(entries_.begin(), entries_.end(),
                                    [](const Entry& a, const Entry& b) { return a.last_use < b.last_use; }));
  }
  entries_.push_back({intrinsics, model, clock_});
  return model;
}

std::string ReasonKind(const std::string& reason) {
  std::string out;
  out.reserve(reason.size());
  for (size_t i = 0; i < reason.size(); ++i) {
    const bool digit = std::isdigit(static_cast<unsigned char>(reason[i])) != 0;
    if (!digit) {
      out += reason[i];
    } else if (i == 0 || !std::isdigit(static_cast<unsigned char>(reason[i - 1]))) {
      out += '#';
    }
  }
  return out;
}

std::string VersionMismatch(unsigned version) {
  return "protocol version " + std::to_string(version) + ", expected " + std::to_string(msg::kProtocolVersion);
}

std::string IdText(std::uint64_t packed) {
  const KeyframeId id(packed);  // the same packing for every id type
  return std::to_string(id.agent()) + ":" + std::to_string(id.counter());
}

msg::Pose PoseToMsg(const SE3& pose) {
  msg::Pose p;
  const Eigen::Vector3d& t = pose.translation();
  const Eigen::Quaterniond& q = pose.rotation();
  p.tx(t.x()); p.ty(t.y()); p.tz(t.z());
  p.qx(q.x()); p.qy(q.y()); p.qz(q.z()); p.qw(q.w());
  return p;
}

std::string PoseFromMsg(const msg::Pose& p, const char* what, SE3* out) {
  const Eigen::Vector3d t(p.tx(), p.ty(), p.tz());
  const Eigen::Quaterniond q(p.qw(), p.qx(), p.qy(), p.qz());
  if (!t.allFinite() || !q.coeffs().allFinite()) return std::string(what) + ": non-finite value";
  if (t.cwiseAbs().maxCoeff() > kLimits.max_abs_coordinate_m) return std::string(what) + ": translation beyond 1e6 m";
  if (std::abs(q.norm() - 1.0) > kQuaternionNormTolerance) return std::string(what) + ": quaternion is not a unit quaternion";
  *out = SE3(q.normalized(), t);
  return "";
}

std::string PositionFromMsg(float x, float y, float z, Eigen::Vector3d* out) {
  *out = Eigen::Vector3d(x, y, z);
  if (!out->allFinite()) return "position: non-finite value";
  if (out->cwiseAbs().maxCoeff() > kLimits.max_abs_coordinate_m) return "position beyond 1e6 m";
  return "";
}

msg::CameraInfo CameraToMsg(const CameraIntrinsics& c) {
  msg::CameraInfo m;
  m.model(static_cast<std::uint8_t>(c.type));
  m.width_px(static_cast<std::uint16_t>(std::clamp(c.width_px, 0, 65535)));
  m.height_px(static_cast<std::uint16_t>(std::clamp(c.height_px, 0, 65535)));
  m.fx(static_cast<float>(c.fx)); m.fy(static_cast<float>(c.fy));
  m.cx(static_cast<float>(c.cx)); m.cy(static_cast<float>(c.cy));
  for (size_t i = 0; i < c.distortion.size() && i < 8; ++i) m.distortion().push_back(static_cast<float>(c.distortion[i]));
  return m;
}

std::string CameraFromMsg(const msg::CameraInfo& m, CameraCache* cameras, std::shared_ptr<const CameraModel>* out) {
  CameraIntrinsics c;
  if (m.model() > 1) return "camera: unknown model " + std::to_string(m.model());
  if (m.distortion().size() > 8) return "camera: " + Str(m.distortion().size()) + " distortion coefficients";
  c.type = static_cast<CameraType>(m.model());
  c.width_px = m.width_px();
  c.height_px = m.height_px();
  c.fx = m.fx(); c.fy = m.fy(); c.cx = m.cx(); c.cy = m.cy();
  c.distortion.assign(m.distortion().begin(), m.distortion().end());
  if (std::string e = ValidateIntrinsics(c); !e.empty()) return "camera: " + e;
  if (std::string e = CheckCameraSanity(c); !e.empty()) return "camera: " + e;
  std::string e;
  *out = cameras != nullptr ? cameras->Get(c, &e) : std::shared_ptr<const CameraModel>(MakeCamera(c));
  if (!*out) return "camera: " + (e.empty() ? std::string("unusable calibration") : e);
  return "";
}

std::string CheckPyramid(int levels, double scale_factor) {
  if (levels < 1 || levels > 16) return "pyramid levels " + std::to_string(levels) + " not in 1..16";
  if (!(scale_factor > 1.0 && scale_factor <= 2.0)) return "pyramid scale factor not in (1, 2]";
  return "";
}

msg::OrbDescriptor DescriptorToMsg(const OrbDescriptor& d) {
  msg::OrbDescriptor m;
  std::copy(d.begin(), d.end(), m.data().begin());
  return m;
}

OrbDescriptor DescriptorFromMsg(const msg::OrbDescriptor& m) {
  OrbDescriptor d;
  std::copy(m.data().begin(), m.data().end(), d.begin());
  return d;
}

namespace {

// Fixed-point keypoint fields (idl Keypoint). Positions a hair outside the image (ORB keeps
// keypoints up to half a pixel out) clamp to its border.
std::uint16_t EighthPx(float px) {
  if (!std::isfinite(px)) return 0;
  return static_cast<std::uint16_t>(std::lround(std::clamp(px, 0.0f, 8191.875f) * 8.0f));
}

std::uint8_t Angle256(float deg) {
  if (!std::isfinite(deg)) return 0;
  const double turns = deg / 360.0 - std::floor(deg / 360.0);  // [0, 1)
  return static_cast<std::uint8_t>(static_cast<int>(std::lround(turns * 256.0)) & 0xFF);
}

}  // namespace

void FeaturesToMsg(const FrameFeatures& f, size_t count, std::vector<msg::Keypoint>* keypoints,
                   std::vector<msg::OrbDescriptor>* descriptors) {
  count = std::min({count, f.keypoints.size(), f.descriptors.size()});
  keypoints->resize(count);
  descriptors->resize(count);
  for (size_t i = 0; i < count; ++i) {
    const Keypoint& k = f.keypoints[i];
    msg::Keypoint& m = (*keypoints)[i];
    m.x_eighth_px(EighthPx(k.u));
    m.y_eighth_px(EighthPx(k.v));
    m.angle_256(Angle256(k.angle_deg));
    m.octave(static_cast<std::uint8_t>(std::clamp(k.level, 0, 255)));
    (*descriptors)[i] = DescriptorToMsg(f.descriptors[i]);
  }
}

std::string FeaturesFromMsg(const std::vector<msg::Keypoint>& keypoints,
                            const std::vector<msg::OrbDescriptor>& descriptors, const CameraModel& camera,
                            int pyramid_levels, std::shared_ptr<const FrameFeatures>* out) {
  if (keypoints.size() != descriptors.size()) {
    return Str(keypoints.size()) + " keypoints but " + Str(descriptors.size()) + " descriptors";
  }
  if (keypoints.size() > msg::kMaxKeypoints) return Str(keypoints.size()) + " keypoints (limit 4000)";
  const float w = static_cast<float>(camera.width()), h = static_cast<float>(camera.height());
  auto f = std::make_shared<FrameFeatures>();
  f->keypoints.resize(keypoints.size());
  f->descriptors.resize(descriptors.size());
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const msg::Keypoint& m = keypoints[i];
    const float x = m.x_eighth_px() / 8.0f, y = m.y_eighth_px() / 8.0f;
    if (x > w || y > h) return "keypoint " + Str(i) + " outside the image";
    if (m.octave() >= pyramid_levels) {
      return "keypoint " + Str(i) + ": octave " + std::to_string(m.octave()) + " not below pyramid levels " +
             std::to_string(pyramid_levels);
    }
    f->keypoints[i] = Keypoint{x, y, m.angle_256() * (360.0f / 256.0f), 0.0f, m.octave()};
    f->descriptors[i] = DescriptorFromMsg(descriptors[i]);
  }
  *out = std::move(f);
  return "";
}

}  // namespace ccm::conv
