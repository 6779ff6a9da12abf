// ccm_agent --ros2-image (issue 32): frames from a ROS 2 camera driver on the robot, read as
// plain DDS with ROS 2's names (topic "rt/<name>", types sensor_msgs::msg::dds_::Image_ and
// CameraInfo_), so the agent needs no ROS. Its own participant on the ROS 2 domain (the
// camera's ROS_DOMAIN_ID, which need not be the team's), no DDS-Security (a ROS 2 driver has
// none of the team's certificates), QoS profiles ccm_ros2_participant / _reader.
//
// The DDS listener only enqueues the message (TypedReader); conversion happens in Next(), on
// the tracking thread that owns this source. A live camera does not wait: the queue keeps the
// newest `queue` images and counts the ones it pushed out (frames_skipped). A stream that
// stalls is reported once per stall and waited for (the map is kept); with end_after_s the
// flight ends after that much silence (a finished bag), otherwise only when *stop is set.
#pragma once

#include <chrono>
#include <memory>
#include <optional>
#include <string>

#include "idl/ros2/ros2_msgsPubSubTypes.h"
#include "runtime_common/dds_session.h"
#include "runtime_common/typed_endpoints.h"
#include "slam_core/io/frame_source.h"

namespace ccm::agent {

struct Ros2CameraOptions {
  std::string image_topic;        ///< ROS 2 name, e.g. /camera/image_raw
  std::string camera_info_topic;  ///< empty: image_topic's namespace + "camera_info" (image_transport's rule)
  int domain_id = 0;
  std::string qos_file;           ///< empty: the default profiles file (DdsSession)
  /// From --calibration: used instead of the camera info (which is then not waited for).
  std::optional<CameraIntrinsics> calibration;
  size_t queue = 2;               ///< images kept while the tracker is busy; older ones are skipped
  double info_wait_s = 10.0;      ///< how long Create waits for the first CameraInfo
  double stall_s = 2.0;           ///< silence reported as a stalled stream
  double end_after_s = 0.0;       ///< > 0: silence after which the flight ends
  const volatile bool* stop = nullptr;  ///< set by the signal handler; ends waits
  std::string Validate() const;
};

/// "/camera/image_raw" -> "/camera/camera_info"; "image" -> "camera_info".
std::string CameraInfoTopicFor(const std::string& image_topic);
/// --ros2-domain not given: $ROS_DOMAIN_ID (ROS 2's variable) if set, else 0 (ROS 2's default).
int DefaultRos2Domain();

class Ros2CameraSource : public FrameSource {
 public:
  /// Joins the domain, subscribes, and (without options.calibration) waits for the camera info.
  /// nullptr and *error when the session or readers cannot be created, the wait ends without a
  /// CameraInfo, or the one received is not a usable calibration.
  static std::unique_ptr<Ros2CameraSource> Create(const Ros2CameraOptions& options, std::string* error);
  ~Ros2CameraSource() override;

  std::optional<Frame> Next() override;
  const CameraIntrinsics& intrinsics() const override { return intrinsics_; }
  int64_t size() const override { return -1; }
  const std::string& error() const override { return error_; }
  bool live() const override { return true; }
  int64_t frames_skipped() const override;

  struct Counters {
    int64_t delivered = 0;          ///< frames returned by Next()
    int64_t skipped = 0;            ///< pushed out of the queue while the tracker was busy
    int64_t lost = 0;               ///< lost on the way (BEST_EFFORT gaps Fast DDS reports)
    int64_t out_of_order = 0;       ///< stamp not after the previous frame's: not delivered
    int64_t stalls = 0;             ///< silences longer than stall_s
  };
  Counters counters() const;
  /// Image publishers matched so far (DDS discovery).
  int image_publishers() const { return images_->matched(); }

 private:
  explicit Ros2CameraSource(const Ros2CameraOptions& options) : options_(options) {}
  bool WaitForCameraInfo(std::string* error);
  void CheckCameraInfoUpdates();
  bool Stopped() const { return options_.stop != nullptr && *options_.stop; }

  using ImageReader = rt::TypedReader<sensor_msgs::msg::dds_::Image_PubSubType>;
  using InfoReader = rt::TypedReader<sensor_msgs::msg::dds_::CameraInfo_PubSubType>;
  const Ros2CameraOptions options_;
  std::string image_dds_topic_, info_dds_topic_;
  std::unique_ptr<rt::DdsSession> session_;  // declared first: destroyed after the readers
  std::unique_ptr<ImageReader> images_;
  std::unique_ptr<InfoReader> infos_;
  CameraIntrinsics intrinsics_;
  std::string error_;
  Counters counters_;
  int64_t last_stamp_ns_ = -1;
  std::chrono::steady_clock::time_point last_image_;
  bool stall_reported_ = false;
  bool info_change_reported_ = false;
};

}  // namespace ccm::agent
