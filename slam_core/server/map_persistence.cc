#include "slam_core/server/map_persistence.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>

#include "slam_core/server/map_file_records.h"
#include "slam_core/server/stack_file.h"

namespace ccm {
namespace {

using namespace map_file;  // NOLINT: the records are this file's own types

Pose7 ToRecord(const SE3& T) {
  const auto& q = T.rotation();
  const auto& t = T.translation();
  return {q.x(), q.y(), q.z(), q.w(), t.x(), t.y(), t.z()};
}
SE3 FromRecord(const Pose7& p) {
  return SE3(Eigen::Quaterniond(p[3], p[0], p[1], p[2]), Eigen::Vector3d(p[4], p[5], p[6]));
}
bool Finite(const double* x, size_t n) {
  return std::all_of(x, x + n, [](double v) { return std::isfinite(v); });
}
// Saved rotations are unit quaternions (to rounding); anything else was not written by us,
// and a zero or non-finite one would poison every pose computed from it.
bool ValidRecord(const Pose7& p) {
  return Finite(p.data(), p.size()) && std::abs(std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] + p[3] * p[3]) - 1.0) < 1e-6;
}

CameraRecord ToRecord(const CameraIntrinsics& c) {
  return {static_cast<int>(c.type), c.width_px, c.height_px, c.fx, c.fy, c.cx, c.cy, c.distortion};
}

KeyframeRecord ToRecord(const KeyFrame& kf, uint32_t camera, const ServerMap& smap) {
  KeyframeRecord r;
  r.id = kf.id().packed();
  r.stamp_ns = kf.stamp_ns();
  r.camera = camera;
  r.levels = kf.pyramid().num_levels;
  r.scale_factor = kf.pyramid().scale_factor;
  const FrameFeatures& f = kf.features();
  for (const Keypoint& k : f.keypoints) {
    r.kp.insert(r.kp.end(), {k.u, k.v, k.angle_deg, k.response});
    r.kp_level.push_back(static_cast<int8_t>(k.level));
  }
  r.descriptors = f.descriptors;
  for (const MapPointId id : kf.map_points()) r.map_points.push_back(id.packed());
  r.pose = ToRecord(kf.world_from_cam());
  r.parent = kf.parent().packed();
  for (const KeyframeId c : kf.children()) r.children.push_back(c.packed());
  for (const KeyframeId l : kf.loop_edges()) r.loop_edges.push_back(l.packed());
  for (const auto& [n, w] : kf.covisibility()) r.covisibility.emplace_back(n.packed(), w);
  if (const auto info = smap.Info(kf.id())) {
    r.has_info = true;
    r.info = {info->segment.packed(), info->predecessor.packed(), info->parent.packed(), ToRecord(info->pred_from_cam),
              ToRecord(info->parent_from_cam), ToRecord(info->segment_from_cam), info->settled};
  }
  return r;
}

MapRecord ToRecord(const ServerMap& smap, std::map<CameraRecord, uint32_t>* cameras) {
  MapRecord r;
  r.id = smap.id().packed();
  r.generation = smap.generation();
  for (const auto& kf : smap.map().keyframes()) {
    const auto it = cameras->emplace(ToRecord(kf->camera().intrinsics()), static_cast<uint32_t>(cameras->size()));
    r.keyframes.push_back(ToRecord(*kf, it.first->second, smap));
  }
  for (const auto& mp : smap.map().map_points()) {
    PointRecord p;
    p.id = mp->id().packed();
    p.reference = mp->reference_kf().packed();
    const Eigen::Vector3d pos = mp->position(), n = mp->normal();
    p.position = {pos.x(), pos.y(), pos.z()};
    p.normal = {n.x(), n.y(), n.z()};
    p.descriptor = mp->descriptor();
    p.min_distance = mp->min_distance_m();
    p.max_distance = mp->max_distance_m();
    for (const auto& [kf, idx] : mp->observations()) p.observations.emplace_back(kf.packed(), idx);
    r.points.push_back(p);
  }
  for (const auto& [id, a] : smap.anchors()) {
    r.anchors.push_back({id.packed(), a.base.packed(), a.segment.packed(), ToRecord(a.base_from_cam), a.stamp_ns});
  }
  std::sort(r.anchors.begin(), r.anchors.end(), [](const auto& a, const auto& b) { return a.id < b.id; });
  for (const auto& [from, to] : smap.replacements()) r.replaced.emplace_back(from.packed(), to.packed());
  std::sort(r.replaced.begin(), r.replaced.end());
  return r;
}

// Keyframe and point ids of the maps read before (one set each: the two id spaces overlap);
// an id is in one map only.
struct SeenIds {
  std::set<uint64_t> keyframes, points;
};

std::shared_ptr<ServerMap> FromRecord(const MapRecord& r, const MapOptions& options,
                                      const std::vector<std::shared_ptr<const CameraModel>>& cameras, SeenIds* seen,
                                      std::string* error) {
  auto smap = std::make_shared<ServerMap>(MapId(r.id), options);
  Map& map = smap->map();
  std::map<std::pair<int, double>, std::shared_ptr<const ScalePyramid>> pyramids;
  for (const KeyframeRecord& k : r.keyframes) {
    const size_t n = k.kp_level.size();
    if (k.camera >= cameras.size() || k.kp.size() != 4 * n || k.descriptors.size() != n || k.map_points.size() != n ||
        k.levels < 1 || k.levels > 16 || !(k.scale_factor > 1.0 && k.scale_factor <= 2.0)) {
      *error = "keyframe " + std::to_string(k.id) + " is inconsistent";
      return nullptr;
    }
    if (!KeyframeId(k.id).valid() || !seen->keyframes.insert(k.id).second) {
      *error = "keyframe id " + std::to_string(k.id) + " invalid or repeated";
      return nullptr;
    }
    if (!ValidRecord(k.pose) || (k.has_info && !(ValidRecord(k.info.pred_from_cam) && ValidRecord(k.info.parent_from_cam) &&
                                                 ValidRecord(k.info.segment_from_cam)))) {
      *error = "keyframe " + std::to_string(k.id) + " has a non-finite pose or a rotation that is not a unit quaternion";
      return nullptr;
    }
    // Matching puts keypoints into image grid cells: they must lie in the image (as on the wire).
    const CameraModel& cam = *cameras[k.camera];
    for (size_t i = 0; i < n; ++i) {
      const float* q = &k.kp[4 * i];
      if (!(q[0] >= 0 && q[0] <= cam.width() && q[1] >= 0 && q[1] <= cam.height() && std::isfinite(q[2]) &&
            std::isfinite(q[3]))) {
        *error = "keyframe " + std::to_string(k.id) + ": keypoint " + std::to_string(i) + " outside the image or not finite";
        return nullptr;
      }
    }
    // Out-of-range levels would index the scale pyramid out of bounds.
    if (std::any_of(k.kp_level.begin(), k.kp_level.end(), [&](int8_t l) { return l < 0 || l >= k.levels; })) {
      *error = "keyframe " + std::to_string(k.id) + " has a keypoint level outside its pyramid";
      return nullptr;
    }
    auto features = std::make_shared<FrameFeatures>();
    for (size_t i = 0; i < n; ++i) {
      features->keypoints.push_back({k.kp[4 * i], k.kp[4 * i + 1], k.kp[4 * i + 2], k.kp[4 * i + 3], k.kp_level[i]});
    }
    features->descriptors = k.descriptors;
    auto& pyr = pyramids[{k.levels, k.scale_factor}];
    if (!pyr) pyr = std::make_shared<ScalePyramid>(ScalePyramid::Make(k.levels, k.scale_factor));
    auto kf = std::make_shared<KeyFrame>(KeyframeId(k.id), k.stamp_ns, cameras[k.camera], features, pyr, FromRecord(k.pose));
    for (size_t i = 0; i < n; ++i) kf->SetMapPointAt(i, MapPointId(k.map_points[i]));
    kf->SetParent(KeyframeId(k.parent));
    for (const uint64_t c : k.children) kf->AddChild(KeyframeId(c));
    for (const uint64_t l : k.loop_edges) kf->AddLoopEdge(KeyframeId(l));
    std::map<KeyframeId, int> covis;
    for (const auto& [id, w] : k.covisibility) covis.emplace(KeyframeId(id), w);
    kf->SetCovisibility(std::move(covis));
    map.AddKeyframe(kf);
    if (k.has_info) {
      const InfoRecord& i = k.info;
      smap->SetInfo(kf->id(), {MapId(i.segment), KeyframeId(i.predecessor), KeyframeId(i.parent),
                               FromRecord(i.pred_from_cam), FromRecord(i.parent_from_cam),
                               FromRecord(i.segment_from_cam), i.settled});
    }
  }
  for (const PointRecord& p : r.points) {
    if (!MapPointId(p.id).valid() || !seen->points.insert(p.id).second) {
      *error = "map point id " + std::to_string(p.id) + " invalid or repeated";
      return nullptr;
    }
    if (!Finite(p.position.data(), 3) || !Finite(p.normal.data(), 3) ||
        !(p.min_distance >= 0 && p.max_distance >= p.min_distance && std::isfinite(p.max_distance))) {
      *error = "map point " + std::to_string(p.id) + " has a non-finite position or invalid distances";
      return nullptr;
    }
    auto mp = std::make_shared<MapPoint>(MapPointId(p.id), Eigen::Vector3d(p.position[0], p.position[1], p.position[2]),
                                         KeyframeId(p.reference), p.descriptor);
    mp->SetAppearance(p.descriptor, Eigen::Vector3d(p.normal[0], p.normal[1], p.normal[2]), p.min_distance, p.max_distance);
    for (const auto& [kf_id, idx] : p.observations) {
      // Optimization and matching index the observing keyframe's keypoints with it; an
      // observation by a keyframe that is not in the map is dropped.
      const auto kf = map.keyframe(KeyframeId(kf_id));
      if (!kf) continue;
      if (idx < 0 || static_cast<size_t>(idx) >= kf->num_keypoints()) {
        *error = "map point " + std::to_string(p.id) + " has an observation outside its keyframe's keypoints";
        return nullptr;
      }
      mp->AddObservation(KeyframeId(kf_id), idx);
    }
    map.AddMapPoint(mp);
  }
  for (const AnchorRecord& a : r.anchors) {
    if (!ValidRecord(a.base_from_cam)) {
      *error = "anchor " + std::to_string(a.id) + " has an invalid pose";
      return nullptr;
    }
    smap->AddAnchor(KeyframeId(a.id), {KeyframeId(a.base), FromRecord(a.base_from_cam), a.stamp_ns, MapId(a.segment)});
  }
  for (const auto& [from, to] : r.replaced) smap->RecordReplacement(MapPointId(from), MapPointId(to));
  smap->RestoreGeneration(r.generation);
  return smap;
}

}  // namespace

bool MapPersistence::Save(const MapStackSnapshot& snapshot, const std::string& path, std::string* error) {
  StackRecord rec;
  std::map<CameraRecord, uint32_t> cameras;
  std::set<uint64_t> saved_maps;
  for (const auto& m : snapshot.maps) {
    std::shared_lock<WriterPreferringMutex> lock(m->structure_mutex());
    if (m->retired()) continue;
    rec.maps.push_back(ToRecord(*m, &cameras));
    saved_maps.insert(m->id().packed());
  }
  rec.cameras.resize(cameras.size());
  for (const auto& [c, i] : cameras) rec.cameras[i] = c;
  rec.next_map = snapshot.next_map_counter;
  for (const AgentHandler& h : snapshot.handlers) {
    if (!saved_maps.count(h.map.packed())) continue;
    const Sim3& S = h.map_from_segment;
    rec.handlers.push_back({h.agent, h.segment.packed(), h.map.packed(), h.last_keyframe.packed(), S.scale(),
                            {S.rotation().x(), S.rotation().y(), S.rotation().z(), S.rotation().w(), S.translation().x(),
                             S.translation().y(), S.translation().z()},
                            h.scale, h.keyframes});
  }
  for (const ServerEvent& e : snapshot.events) {
    rec.events.push_back({static_cast<int>(e.kind), e.time_s, e.seconds, e.stamp_ns, e.agent, e.map.packed(),
                          e.other_map.packed(), e.query.packed(), e.candidate.packed(), e.keyframes, e.detail});
  }
  std::ostringstream payload;
  {
    cereal::PortableBinaryOutputArchive archive(payload);
    archive(rec);
  }
  return WriteStackFile(path, payload.str(), error);
}

namespace {

std::optional<RestoredStack> Decode(const std::string& path, const std::string& bytes, const MapOptions& map_options,
                                       std::string* error) {
  StackRecord rec;
  try {
    std::istringstream payload(bytes);
    cereal::PortableBinaryInputArchive archive(payload);
    archive(rec);
  } catch (const std::exception& e) {
    *error = path + ": cannot decode: " + e.what();
    return std::nullopt;
  }
  std::vector<std::shared_ptr<const CameraModel>> cameras;
  for (const CameraRecord& c : rec.cameras) {
    CameraIntrinsics in;
    in.type = static_cast<CameraType>(c.type);
    in.width_px = c.width;
    in.height_px = c.height;
    in.fx = c.fx, in.fy = c.fy, in.cx = c.cx, in.cy = c.cy;
    in.distortion = c.distortion;
    std::shared_ptr<const CameraModel> cam(MakeCamera(in));
    if (!cam) {
      *error = path + ": invalid camera: " + ValidateIntrinsics(in);
      return std::nullopt;
    }
    cameras.push_back(cam);
  }
  RestoredStack out;
  out.stack = std::make_shared<MapStack>(map_options);
  std::set<uint64_t> maps;
  SeenIds seen_ids;
  if (rec.next_map > MapId::kCounterMask) {
    *error = path + ": next map counter beyond the id space";
    return std::nullopt;
  }
  for (const MapRecord& m : rec.maps) {
    // New maps get MapId::Make(0, next_map++): a map outside that range, or twice in the
    // file, would collide with one created later.
    const MapId id(m.id);
    if (id.agent() != kServerAgent || !id.valid() || id.counter() >= rec.next_map || maps.count(m.id)) {
      *error = path + ": map id " + std::to_string(m.id) + " repeated or outside the server's map ids";
      return std::nullopt;
    }
    auto smap = FromRecord(m, map_options, cameras, &seen_ids, error);
    if (!smap) {
      *error = path + ": " + *error;
      return std::nullopt;
    }
    maps.insert(smap->id().packed());
    out.stack->RestoreMap(std::move(smap));
  }
  for (const HandlerRecord& h : rec.handlers) {
    AgentHandler a;
    a.agent = h.agent;
    a.segment = MapId(h.segment);
    a.map = MapId(h.map);
    a.last_keyframe = KeyframeId(h.last_keyframe);
    a.map_from_segment = Sim3(h.s, Eigen::Quaterniond(h.sim[3], h.sim[0], h.sim[1], h.sim[2]),
                              Eigen::Vector3d(h.sim[4], h.sim[5], h.sim[6]));
    a.scale = h.scale;
    a.keyframes = h.keyframes;
    if (!Finite(h.sim.data(), h.sim.size()) || !(h.s > 0 && std::isfinite(h.s)) || !(h.scale > 0 && std::isfinite(h.scale)) ||
        !ValidRecord(h.sim)) {
      *error = path + ": handler of agent " + std::to_string(h.agent) + " has an invalid Sim(3) or scale";
      return std::nullopt;
    }
    if (!maps.count(a.map.packed())) {
      *error = path + ": handler of agent " + std::to_string(h.agent) + " points to a missing map";
      return std::nullopt;
    }
    out.stack->RestoreHandler(a);
  }
  out.stack->set_next_map_counter(rec.next_map);
  for (const EventRecord& e : rec.events) {
    if (e.kind < 0 || e.kind > static_cast<int>(ServerEvent::Kind::kGlobalBa)) {
      *error = path + ": event kind " + std::to_string(e.kind) + " unknown";
      return std::nullopt;
    }
    ServerEvent ev;
    ev.kind = static_cast<ServerEvent::Kind>(e.kind);
    ev.time_s = e.time_s;
    ev.seconds = e.seconds;
    ev.stamp_ns = e.stamp_ns;
    ev.agent = e.agent;
    ev.map = MapId(e.map);
    ev.other_map = MapId(e.other_map);
    ev.query = KeyframeId(e.query);
    ev.candidate = KeyframeId(e.candidate);
    ev.keyframes = e.keyframes;
    ev.detail = e.detail;
    out.events.push_back(ev);
  }
  return out;
}

std::optional<RestoredStack> LoadOne(const std::string& path, const MapOptions& map_options, std::string* error) {
  const auto bytes = ReadStackFile(path, error);
  if (!bytes) return std::nullopt;
  return Decode(path, *bytes, map_options, error);
}

}  // namespace

std::optional<RestoredStack> MapPersistence::Load(const std::string& path, const MapOptions& map_options,
                                                  std::string* error, std::string* warning) {
  auto newest = LoadOne(path, map_options, error);
  if (newest) return newest;
  const std::string prev = PreviousGeneration(path);
  std::error_code ec;
  if (!std::filesystem::exists(prev, ec)) return std::nullopt;
  std::string prev_error;
  auto previous = LoadOne(prev, map_options, &prev_error);
  if (!previous) {
    *error += "; the previous generation too: " + prev_error;
    return std::nullopt;
  }
  if (warning) *warning = *error + "; loaded the previous generation " + prev + " instead";
  return previous;
}

bool SaveBackend(const ServerBackend& backend, const std::string& path, std::string* error) {
  return MapPersistence::Save(backend.Snapshot(), path, error);
}

std::unique_ptr<ServerBackend> LoadBackend(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                                           ServerOptions options, std::string* error, std::string* warning) {
  auto restored = MapPersistence::Load(path, options.map, error, warning);
  if (!restored) return nullptr;
  return std::make_unique<ServerBackend>(std::move(vocabulary), std::move(options), std::move(*restored));
}

}  // namespace ccm
