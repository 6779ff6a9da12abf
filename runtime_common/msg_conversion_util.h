// Building blocks shared by the conversion functions (msg_conversion.h): field conversions
// and checks. Internal to ccm_msg_conversion. Every Check / *FromMsg returns an empty string
// when the field is fine, else what is wrong (without the message kind, which the caller
// puts in front).
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "idl/ccm_msgs.h"
#include "slam_core/common/ids.h"
#include "slam_core/exchange/agent_data.h"
#include "slam_core/feature/orb_types.h"
#include "slam_core/geometry/camera.h"
#include "slam_core/geometry/se3.h"

namespace ccm::conv {

class CameraCache;

/// Limits of the exchange validators, the same as the IDL bounds.
inline const AgentDataLimits kLimits{msg::kMaxKeypoints, msg::kMaxObservations, 1e6};

/// A count as text, for rejection messages.
inline std::string Str(size_t v) { return std::to_string(v); }

/// Sets *error to "<kind>: <what>" and returns nullopt.
template <typename T>
std::optional<T> Reject(std::string* error, const char* kind, const std::string& what) {
  if (error != nullptr) *error = std::string(kind) + ": " + what;
  return std::nullopt;
}

std::string VersionMismatch(unsigned version);
std::string IdText(std::uint64_t packed);

/// An id that must be valid and belong to `agent`.
template <typename IdT>
std::string OwnIdFromMsg(std::uint64_t packed, AgentId agent, const char* what, IdT* out) {
  *out = IdT(packed);
  if (!out->valid()) return std::string(what) + " id " + IdText(packed) + " is invalid";
  if (out->agent() != agent) {
    return std::string(what) + " id " + IdText(packed) + " belongs to agent " + std::to_string(out->agent()) +
           ", not to sender " + std::to_string(agent);
  }
  return "";
}

/// An id of any agent, 0 meaning none (Invalid) unless `required`.
template <typename IdT>
std::string AnyIdFromMsg(std::uint64_t packed, const char* what, bool required, IdT* out) {
  *out = IdT(packed);
  if (packed == 0 && !required) return "";
  if (!out->valid()) return std::string(what) + " id " + IdText(packed) + " is invalid";
  return "";
}

msg::Pose PoseToMsg(const SE3& pose);
/// Finite, translation within kLimits, |q| within kQuaternionNormTolerance of 1 (normalized).
std::string PoseFromMsg(const msg::Pose& p, const char* what, SE3* out);

/// Finite and within kLimits.
std::string PositionFromMsg(float x, float y, float z, Eigen::Vector3d* out);

msg::CameraInfo CameraToMsg(const CameraIntrinsics& intrinsics);
/// Model, intrinsics (ValidateIntrinsics) and the sanity bounds; the shared model from
/// `cameras` (or a new one when it is null).
std::string CameraFromMsg(const msg::CameraInfo& c, CameraCache* cameras, std::shared_ptr<const CameraModel>* out);

/// Pyramid levels 1..16 and scale factor in (1, 2], as the exchange validators demand.
std::string CheckPyramid(int levels, double scale_factor);

msg::OrbDescriptor DescriptorToMsg(const OrbDescriptor& d);
OrbDescriptor DescriptorFromMsg(const msg::OrbDescriptor& d);

/// The first `count` features.
void FeaturesToMsg(const FrameFeatures& f, size_t count, std::vector<msg::Keypoint>* keypoints,
                   std::vector<msg::OrbDescriptor>* descriptors);
/// Counts (equal, within kMaxKeypoints), every keypoint inside the image, octave below
/// `pyramid_levels`. Positions come back to 1/16 px, angles to 0.7 deg, responses as 0.
std::string FeaturesFromMsg(const std::vector<msg::Keypoint>& keypoints,
                            const std::vector<msg::OrbDescriptor>& descriptors, const CameraModel& camera,
                            int pyramid_levels, std::shared_ptr<const FrameFeatures>* out);

}  // namespace ccm::conv
