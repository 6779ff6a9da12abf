#include "tools/replay/batch_recording.h"

#include <chrono>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>

#include <cereal/archives/portable_binary.hpp>
#include <cereal/types/array.hpp>
#include <cereal/types/string.hpp>
#include <cereal/types/utility.hpp>
#include <cereal/types/vector.hpp>

#include "server_runtime/backend_runner.h"
#include "slam_core/common/checksum.h"

namespace ccm::replay {
namespace {

constexpr char kMagic[8] = {'C', 'C', 'M', 'R', 'E', 'C', 'R', 'D'};
constexpr uint32_t kVersion = 3;  // 2: anchor-only keyframes; 3: VO segments, relocalizations
using Pose7 = std::array<double, 7>;

Pose7 P(const SE3& T) {
  return {T.rotation().x(), T.rotation().y(), T.rotation().z(), T.rotation().w(),
          T.translation().x(), T.translation().y(), T.translation().z()};
}
SE3 P(const Pose7& p) { return SE3(Eigen::Quaterniond(p[3], p[0], p[1], p[2]), Eigen::Vector3d(p[4], p[5], p[6])); }
std::array<double, 3> V(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
Eigen::Vector3d V(const std::array<double, 3>& v) { return {v[0], v[1], v[2]}; }

struct TrajRec {
  std::vector<int64_t> stamps;
  std::vector<Pose7> poses;
  template <class A> void serialize(A& a) { a(stamps, poses); }
};
TrajRec T(const Trajectory& t) {
  TrajRec r;
  for (const auto& p : t) r.stamps.push_back(p.stamp_ns), r.poses.push_back(P(p.world_from_cam));
  return r;
}
Trajectory T(const TrajRec& r) {
  Trajectory t;
  for (size_t i = 0; i < r.stamps.size() && i < r.poses.size(); ++i) t.push_back({r.stamps[i], P(r.poses[i])});
  return t;
}

struct AgentRec {
  std::string name;
  uint16_t id = 0;
  int64_t frames = 0, tracked = 0, kfs = 0;
  int segments = 0;
  int64_t relocalizations = 0;
  TrajRec gt, vo;
  std::vector<std::pair<uint64_t, TrajRec>> vo_segments;
  template <class A> void serialize(A& a) { a(name, id, frames, tracked, kfs, segments, relocalizations, gt, vo, vo_segments); }
};

struct CamRec {
  int type = 0, w = 0, h = 0;
  double fx = 0, fy = 0, cx = 0, cy = 0;
  std::vector<double> dist;
  template <class A> void serialize(A& a) { a(type, w, h, fx, fy, cx, cy, dist); }
};

struct KfRec {
  uint64_t id = 0, segment = 0, pred = 0, parent = 0;
  int64_t stamp = 0;
  uint32_t camera = 0;
  int levels = 8;
  double scale_factor = 1.2;
  std::vector<float> kp;
  std::vector<int8_t> level;
  std::vector<std::array<uint8_t, 32>> desc;
  std::vector<std::pair<int, uint64_t>> links;
  Pose7 pred_from_cam{}, parent_from_cam{}, segment_from_cam{};
  bool anchor_only = false;
  template <class A>
  void serialize(A& a) {
    a(id, segment, pred, parent, stamp, camera, levels, scale_factor, kp, level, desc, links, pred_from_cam,
      parent_from_cam, segment_from_cam, anchor_only);
  }
};

struct MpRec {
  uint64_t id = 0, segment = 0, ref = 0;
  std::array<double, 3> pos{};
  std::array<uint8_t, 32> desc{};
  std::vector<std::pair<uint64_t, int>> obs;
  template <class A> void serialize(A& a) { a(id, segment, ref, pos, desc, obs); }
};

struct KfUpdRec {
  uint64_t id = 0, segment = 0, pred = 0, parent = 0;
  Pose7 pred_from_cam{}, parent_from_cam{};
  template <class A> void serialize(A& a) { a(id, segment, pred, parent, pred_from_cam, parent_from_cam); }
};

struct MpUpdRec {
  uint64_t id = 0, ref = 0;
  std::array<double, 3> pos{};
  template <class A> void serialize(A& a) { a(id, ref, pos); }
};

struct BatchRec {
  uint16_t agent = 0;
  uint64_t segment = 0, ref = 0;
  int64_t stamp = 0;
  std::vector<KfRec> kfs;
  std::vector<MpRec> mps;
  std::vector<KfUpdRec> kf_updates;
  std::vector<MpUpdRec> mp_updates;
  template <class A> void serialize(A& a) { a(agent, segment, ref, stamp, kfs, mps, kf_updates, mp_updates); }
};

struct FileRec {
  std::vector<AgentRec> agents;
  std::vector<CamRec> cameras;
  std::vector<BatchRec> batches;
  template <class A> void serialize(A& a) { a(agents, cameras, batches); }
};

KfRec ToRec(const KeyframeData& k, uint32_t camera) {
  KfRec r;
  r.id = k.id.packed();
  r.segment = k.segment.packed();
  r.pred = k.predecessor.packed();
  r.parent = k.parent.packed();
  r.stamp = k.stamp_ns;
  r.camera = camera;
  r.levels = k.pyramid_levels;
  r.scale_factor = k.pyramid_scale_factor;
  for (const Keypoint& p : k.features->keypoints) {
    r.kp.insert(r.kp.end(), {p.u, p.v, p.angle_deg, p.response});
    r.level.push_back(static_cast<int8_t>(p.level));
  }
  r.desc = k.features->descriptors;
  for (const auto& [i, mp] : k.point_links) r.links.emplace_back(i, mp.packed());
  r.pred_from_cam = P(k.pred_from_cam);
  r.parent_from_cam = P(k.parent_from_cam);
  r.segment_from_cam = P(k.segment_from_cam);
  r.anchor_only = k.anchor_only;
  return r;
}

}  // namespace

void RecordAgents(const RunResult& result, Recording* recording) {
  for (const AgentRunResult& a : result.agents) {
    recording->agents.push_back({a.name, a.id, a.frames, a.frames_tracked, a.keyframes_created, a.segments,
                                 a.relocalizations, a.ground_truth, a.vo_keyframes, a.vo_segments});
  }
}

bool SaveRecording(const Recording& rec, const std::string& path, std::string* error) {
  FileRec f;
  for (const RecordedAgent& a : rec.agents) {
    AgentRec r{a.name, a.id, a.frames, a.frames_tracked, a.keyframes_created, a.segments, a.relocalizations,
               T(a.ground_truth), T(a.vo_keyframes), {}};
    for (const auto& [segment, t] : a.vo_segments) r.vo_segments.emplace_back(segment.packed(), T(t));
    f.agents.push_back(std::move(r));
  }
  std::map<const CameraModel*, uint32_t> cams;
  for (const AgentBatch& b : rec.batches) {
    BatchRec br{b.agent, b.segment.packed(), b.reference_kf.packed(), b.stamp_ns, {}, {}, {}, {}};
    for (const KeyframeData& k : b.keyframes) {
      const auto it = cams.emplace(k.camera.get(), static_cast<uint32_t>(cams.size()));
      if (it.second) {
        const CameraIntrinsics& c = k.camera->intrinsics();
        f.cameras.push_back({static_cast<int>(c.type), c.width_px, c.height_px, c.fx, c.fy, c.cx, c.cy, c.distortion});
      }
      br.kfs.push_back(ToRec(k, it.first->second));
    }
    for (const MapPointData& m : b.map_points) {
      MpRec r{m.id.packed(), m.segment.packed(), m.reference_kf.packed(), V(m.position_ref), m.descriptor, {}};
      for (const auto& [kf, i] : m.observations) r.obs.emplace_back(kf.packed(), i);
      br.mps.push_back(r);
    }
    for (const KeyframePoseUpdate& u : b.keyframe_updates) {
      br.kf_updates.push_back({u.id.packed(), u.segment.packed(), u.predecessor.packed(), u.parent.packed(),
                               P(u.pred_from_cam), P(u.parent_from_cam)});
    }
    for (const MapPointPositionUpdate& u : b.map_point_updates) {
      br.mp_updates.push_back({u.id.packed(), u.reference_kf.packed(), V(u.position_ref)});
    }
    f.batches.push_back(std::move(br));
  }
  std::ostringstream os;
  {
    cereal::PortableBinaryOutputArchive ar(os);
    ar(f);
  }
  const std::string payload = os.str();
  const uint64_t size = payload.size();
  const uint64_t sum = Fnv1a64(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
  std::ofstream out(path + ".tmp", std::ios::binary | std::ios::trunc);
  out.write(kMagic, 8);
  out.write(reinterpret_cast<const char*>(&kVersion), 4);
  out.write(reinterpret_cast<const char*>(&size), 8);
  out.write(payload.data(), static_cast<std::streamsize>(size));
  out.write(reinterpret_cast<const char*>(&sum), 8);
  out.close();
  if (!out || std::rename((path + ".tmp").c_str(), path.c_str()) != 0) {
    *error = "cannot write " + path;
    return false;
  }
  return true;
}

std::optional<Recording> LoadRecording(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  uint32_t version = 0;
  uint64_t size = 0, sum = 0;
  if (data.size() < 28 || std::memcmp(data.data(), kMagic, 8) != 0) {
    *error = path + ": missing or not a ccm_replay recording";
    return std::nullopt;
  }
  std::memcpy(&version, data.data() + 8, 4);
  std::memcpy(&size, data.data() + 12, 8);
  if (version != kVersion || data.size() != 28 + size) {
    *error = path + ": unsupported version or truncated";
    return std::nullopt;
  }
  std::memcpy(&sum, data.data() + 20 + size, 8);
  if (Fnv1a64(reinterpret_cast<const uint8_t*>(data.data() + 20), size) != sum) {
    *error = path + ": checksum mismatch: file corrupted";
    return std::nullopt;
  }
  FileRec f;
  try {
    std::istringstream is(data.substr(20, size));
    cereal::PortableBinaryInputArchive ar(is);
    ar(f);
  } catch (const std::exception& e) {
    *error = path + ": cannot decode: " + e.what();
    return std::nullopt;
  }
  Recording rec;
  for (const AgentRec& a : f.agents) {
    RecordedAgent r{a.name, a.id, a.frames, a.tracked, a.kfs, a.segments, a.relocalizations, T(a.gt), T(a.vo), {}};
    for (const auto& [segment, t] : a.vo_segments) r.vo_segments[MapId(segment)] = T(t);
    rec.agents.push_back(std::move(r));
  }
  std::vector<std::shared_ptr<const CameraModel>> cams;
  for (const CamRec& c : f.cameras) {
    CameraIntrinsics in;
    in.type = static_cast<CameraType>(c.type);
    in.width_px = c.w, in.height_px = c.h, in.fx = c.fx, in.fy = c.fy, in.cx = c.cx, in.cy = c.cy;
    in.distortion = c.dist;
    cams.emplace_back(MakeCamera(in));
    if (!cams.back()) {
      *error = path + ": invalid camera";
      return std::nullopt;
    }
  }
  for (const BatchRec& br : f.batches) {
    AgentBatch b;
    b.agent = br.agent;
    b.segment = MapId(br.segment);
    b.reference_kf = KeyframeId(br.ref);
    b.stamp_ns = br.stamp;
    for (const KfRec& r : br.kfs) {
      KeyframeData k;
      k.id = KeyframeId(r.id);
      k.segment = MapId(r.segment);
      k.stamp_ns = r.stamp;
      if (r.camera >= cams.size() || r.kp.size() != 4 * r.level.size() || r.desc.size() != r.level.size()) {
        *error = path + ": inconsistent keyframe";
        return std::nullopt;
      }
      k.camera = cams[r.camera];
      k.pyramid_levels = r.levels;
      k.pyramid_scale_factor = r.scale_factor;
      auto feat = std::make_shared<FrameFeatures>();
      for (size_t i = 0; i < r.level.size(); ++i) {
        feat->keypoints.push_back({r.kp[4 * i], r.kp[4 * i + 1], r.kp[4 * i + 2], r.kp[4 * i + 3], r.level[i]});
      }
      feat->descriptors = r.desc;
      k.features = feat;
      for (const auto& [i, mp] : r.links) k.point_links.emplace_back(i, MapPointId(mp));
      k.predecessor = KeyframeId(r.pred);
      k.parent = KeyframeId(r.parent);
      k.pred_from_cam = P(r.pred_from_cam);
      k.parent_from_cam = P(r.parent_from_cam);
      k.segment_from_cam = P(r.segment_from_cam);
      k.anchor_only = r.anchor_only;
      b.keyframes.push_back(std::move(k));
    }
    for (const MpRec& r : br.mps) {
      MapPointData m{MapPointId(r.id), MapId(r.segment), KeyframeId(r.ref), V(r.pos), r.desc, {}};
      for (const auto& [kf, i] : r.obs) m.observations.emplace_back(KeyframeId(kf), i);
      b.map_points.push_back(std::move(m));
    }
    for (const KfUpdRec& r : br.kf_updates) {
      b.keyframe_updates.push_back({KeyframeId(r.id), MapId(r.segment), KeyframeId(r.pred), P(r.pred_from_cam),
                                    KeyframeId(r.parent), P(r.parent_from_cam)});
    }
    for (const MpUpdRec& r : br.mp_updates) b.map_point_updates.push_back({MapPointId(r.id), KeyframeId(r.ref), V(r.pos)});
    rec.batches.push_back(std::move(b));
  }
  return rec;
}

RunResult ResultFromBackend(const Recording& rec, const ServerBackend& backend) {
  RunResult result;
  const MapStackSnapshot maps = backend.Snapshot();
  for (const RecordedAgent& a : rec.agents) {
    AgentRunResult r;
    r.name = a.name;
    r.id = a.id;
    r.frames = a.frames;
    r.frames_tracked = a.frames_tracked;
    r.keyframes_created = a.keyframes_created;
    r.segments = a.segments;
    r.ground_truth = a.ground_truth;
    r.vo_keyframes = a.vo_keyframes;
    r.vo_segments = a.vo_segments;
    r.relocalizations = a.relocalizations;
    r.server_keyframes = maps.AgentTrajectory(a.id);
    r.revisit_links = maps.AgentRevisitLinks(a.id, report::kRevisitLinkGapNs, report::kRevisitLinkMinPoints);
    result.agents.push_back(std::move(r));
  }
  result.events = maps.events;
  result.maps = maps.Summaries();
  result.stats = backend.Status().stats;
  return result;
}

RunResult PlayRecording(const Recording& rec, ServerBackend* backend, const PlayOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t last = std::min(o.last, rec.batches.size());
  {
    std::unique_ptr<server::BackendRunner> runner;
    if (o.threaded) runner = std::make_unique<server::BackendRunner>(backend);
    for (size_t i = o.first; i < last; ++i) {
      backend->Submit(rec.batches[i]);
      if (!o.threaded) {
        backend->ProcessAllQueued();
      } else if (o.threaded_window > 0 && (i + 1 - o.first) % o.threaded_window == 0) {
        backend->WaitUntilIdle();
      }
    }
    if (o.threaded) backend->WaitUntilIdle();
    if (o.final_global_ba) {
      backend->ScheduleFinish();
      if (o.threaded) {
        backend->WaitUntilIdle();
      } else {
        backend->ProcessAllQueued();
      }
    }
  }
  RunResult result = ResultFromBackend(rec, *backend);
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return result;
}

}  // namespace ccm::replay
