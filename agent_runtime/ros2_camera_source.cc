#include "agent_runtime/ros2_camera_source.h"

#include <spdlog/spdlog.h>

#include <cstdlib>
#include <thread>

#include "agent_runtime/ros2_camera_conversion.h"
#include "runtime_common/topics.h"
#include "slam_core/common/stopwatch.h"

namespace ccm::agent {
namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

// How often waits look at *stop and at the clock.
constexpr milliseconds kRos2Poll(100);

bool SameCalibration(const CameraIntrinsics& a, const CameraIntrinsics& b) {
  return a.type == b.type && a.width_px == b.width_px && a.height_px == b.height_px && a.fx == b.fx && a.fy == b.fy &&
         a.cx == b.cx && a.cy == b.cy && a.distortion == b.distortion;
}

}  // namespace

std::string Ros2CameraOptions::Validate() const {
  if (image_topic.empty() || image_topic.find_first_of(" \t~{}") != std::string::npos) {
    return "--ros2-image must name a ROS 2 topic such as /camera/image_raw, got '" + image_topic + "'";
  }
  if (domain_id < 0 || domain_id > 232) return "--ros2-domain must be in 0..232 (ROS 2's domain ids)";
  if (queue < 1 || queue > 1000) return "--ros2-queue must be in 1..1000";
  if (!(info_wait_s > 0)) return "the camera info wait must be > 0 s";
  if (!(stall_s > 0)) return "the stall report period must be > 0 s";
  if (!(end_after_s >= 0)) return "--end-after must be >= 0 (0: wait for ever)";
  return "";
}

std::string CameraInfoTopicFor(const std::string& image_topic) {
  const size_t slash = image_topic.rfind('/');
  return (slash == std::string::npos ? std::string() : image_topic.substr(0, slash + 1)) + "camera_info";
}

int DefaultRos2Domain() {
  const char* env = std::getenv("ROS_DOMAIN_ID");
  if (env == nullptr || *env == '\0') return 0;
  char* end = nullptr;
  const long id = std::strtol(env, &end, 10);
  if (*end != '\0' || id < 0 || id > 232) {
    spdlog::warn("ROS_DOMAIN_ID='{}' is not a domain id (0..232): using 0", env);
    return 0;
  }
  return static_cast<int>(id);
}

std::unique_ptr<Ros2CameraSource> Ros2CameraSource::Create(const Ros2CameraOptions& options, std::string* error) {
  if (const std::string problem = options.Validate(); !problem.empty()) return *error = problem, nullptr;
  std::unique_ptr<Ros2CameraSource> s(new Ros2CameraSource(options));
  const std::string info_topic =
      options.camera_info_topic.empty() ? CameraInfoTopicFor(options.image_topic) : options.camera_info_topic;
  s->image_dds_topic_ = rt::Ros2DdsTopic(options.image_topic);
  s->info_dds_topic_ = rt::Ros2DdsTopic(info_topic);
  rt::SessionOptions session;
  session.domain_id = options.domain_id;
  session.qos_file = options.qos_file;
  session.participant_profile = rt::kProfileRos2Participant;
  session.participant_name = "ccm_camera_input";
  s->session_ = rt::DdsSession::Create(session, error);
  if (!s->session_) return nullptr;
  s->images_ = ImageReader::Create(*s->session_, s->image_dds_topic_, rt::kProfileRos2CameraReader,
                                   {options.queue, rt::OverflowPolicy::kDropOldest, nullptr}, error);
  s->infos_ = InfoReader::Create(*s->session_, s->info_dds_topic_, rt::kProfileRos2CameraReader,
                                 {1, rt::OverflowPolicy::kDropOldest, nullptr}, error);
  if (!s->images_ || !s->infos_) return nullptr;
  spdlog::info("ROS 2 camera: sensor_msgs/Image on {} (DDS topic {}), domain {}", options.image_topic,
               s->image_dds_topic_, options.domain_id);
  if (options.calibration) {
    s->intrinsics_ = *options.calibration;
    spdlog::info("ROS 2 camera: calibration from --calibration (the camera info on {} is not used)", info_topic);
  } else if (!s->WaitForCameraInfo(error)) {
    return nullptr;
  }
  s->last_image_ = Clock::now();
  return s;
}

Ros2CameraSource::~Ros2CameraSource() {
  // The readers go before the session that created them.
  images_.reset();
  infos_.reset();
}

bool Ros2CameraSource::WaitForCameraInfo(std::string* error) {
  const auto start = Clock::now();
  while (SecondsSince(start) < options_.info_wait_s && !Stopped()) {
    auto info = infos_->Pop(kRos2Poll);
    if (!info) continue;
    std::string problem;
    if (!Ros2CameraInfoToIntrinsics(*info, &intrinsics_, &problem)) {
      *error = info_dds_topic_ + ": " + problem;
      return false;
    }
    spdlog::info("ROS 2 camera: calibration from {}: {}x{} {} fx {:.1f} fy {:.1f} cx {:.1f} cy {:.1f}",
                 info_dds_topic_, intrinsics_.width_px, intrinsics_.height_px, CameraTypeName(intrinsics_.type),
                 intrinsics_.fx, intrinsics_.fy, intrinsics_.cx, intrinsics_.cy);
    return true;
  }
  *error = Stopped() ? std::string("stopped while waiting for the camera info")
                     : "no sensor_msgs/CameraInfo on DDS topic " + info_dds_topic_ + " (domain " +
                           std::to_string(options_.domain_id) + ") within " + fmt::format("{:.0f}", options_.info_wait_s) +
                           " s; publishers of it matched: " + std::to_string(infos_->matched()) +
                           ", of the images: " + std::to_string(images_->matched()) +
                           ". Is the camera driver running with this ROS_DOMAIN_ID (--ros2-domain)? Does `ros2 topic "
                           "list` show the topic (--ros2-camera-info)? Or give --calibration FILE.yaml";
  return false;
}

// A driver that republishes its camera info with other values (a new calibration loaded at
// run time): the VO cannot change its camera mid-flight, so say so once and keep the first.
void Ros2CameraSource::CheckCameraInfoUpdates() {
  auto info = infos_->Pop(milliseconds(0));
  if (!info || info_change_reported_ || options_.calibration) return;
  CameraIntrinsics now;
  std::string problem;
  if (Ros2CameraInfoToIntrinsics(*info, &now, &problem) && SameCalibration(now, intrinsics_)) return;
  info_change_reported_ = true;
  spdlog::warn("ROS 2 camera: the camera info on {} changed ({}); the flight keeps the calibration it started with",
               info_dds_topic_, problem.empty() ? "other values" : problem);
}

std::optional<Frame> Ros2CameraSource::Next() {
  while (!Stopped()) {
    auto image = images_->Pop(kRos2Poll);
    if (!image) {
      const double silent_s = SecondsSince(last_image_);
      if (silent_s >= options_.stall_s && !stall_reported_) {
        stall_reported_ = true;
        ++counters_.stalls;
        spdlog::warn("ROS 2 camera: no image on {} for {:.1f} s after {} frames (publishers matched: {}); waiting, "
                     "the map is kept", image_dds_topic_, silent_s, counters_.delivered, images_->matched());
      }
      if (options_.end_after_s > 0 && silent_s >= options_.end_after_s) {
        spdlog::info("ROS 2 camera: no image for {:.1f} s (--end-after): the flight ends", silent_s);
        return std::nullopt;
      }
      continue;
    }
    if (stall_reported_) {
      spdlog::info("ROS 2 camera: images again on {} after {:.1f} s", image_dds_topic_, SecondsSince(last_image_));
      stall_reported_ = false;
    }
    last_image_ = Clock::now();
    CheckCameraInfoUpdates();
    Frame f;
    f.stamp_ns = Ros2StampNs(image->header().stamp());
    std::string problem;
    if (!Ros2ImageToGray(*image, &f.image, &problem)) {
      error_ = image_dds_topic_ + ": " + problem;
      return std::nullopt;
    }
    if (f.image.cols != intrinsics_.width_px || f.image.rows != intrinsics_.height_px) {
      error_ = image_dds_topic_ + ": images are " + std::to_string(f.image.cols) + "x" + std::to_string(f.image.rows) +
               " but the calibration is for " + std::to_string(intrinsics_.width_px) + "x" +
               std::to_string(intrinsics_.height_px) + " (binning or region of interest changed?)";
      return std::nullopt;
    }
    // Tracking needs time to go forward; a bag played again or a clock jump would be taken as
    // a frame from the past.
    if (f.stamp_ns <= last_stamp_ns_) {
      if (counters_.out_of_order++ == 0) {
        spdlog::warn("ROS 2 camera: an image stamped {:.3f} s is not after the previous one ({:.3f} s): skipped "
                     "(and every such image; counted)", f.stamp_ns * 1e-9, last_stamp_ns_ * 1e-9);
      }
      continue;
    }
    last_stamp_ns_ = f.stamp_ns;
    f.source_name = options_.image_topic + ":" + std::to_string(counters_.delivered++);
    return f;
  }
  return std::nullopt;
}

int64_t Ros2CameraSource::frames_skipped() const { return static_cast<int64_t>(images_->counters().queue_dropped); }

Ros2CameraSource::Counters Ros2CameraSource::counters() const {
  Counters c = counters_;
  c.skipped = frames_skipped();
  c.lost = static_cast<int64_t>(images_->counters().samples_lost);
  return c;
}

}  // namespace ccm::agent
