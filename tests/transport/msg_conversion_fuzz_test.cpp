// Fuzz test of the conversion layer: 100,000 mutated or truncated messages built from real
// data (agent 1's VO on 100 simulator frames of hall3, and the server's replies to it) go
// through FromMsg; every accepted agent message is submitted to a ServerBackend that already
// holds the real data. No crash, every message accounted for, and nothing FromMsg accepted
// fails the back-end's own validation. Deterministic seed. Run under sanitizers by
// deploy/run-sanitizer-tests.sh.
#include <gtest/gtest.h>

#include <iostream>
#include <map>

#include "idl/ccm_msgsPubSubTypes.h"
#include "runtime_common/msg_conversion.h"
#include "tests/slam_core/server/server_test_util.h"
#include "tests/transport/conversion_test_data.h"
#include "tests/transport/msg_fuzz_mutations.h"
#include "tests/transport/msg_mutator.h"

namespace ccm {
namespace {

using testing::MsgMutator;
using testing::Mutate;
using testing::MutateServer;
constexpr AgentId kAgent = 1;

struct BaseMessages {
  std::vector<msg::KeyframeFull> keyframes;
  std::vector<msg::MapPointBatch> map_points;  // one point each
  std::vector<msg::KeyframeUpdate> keyframe_updates;
  std::vector<msg::MapPointUpdateBatch> map_point_updates;  // one update each
  std::vector<msg::ServerToAgent> server;
};

// Agent messages of every batch, as the agent's comm module would send them.
void AddAgentMessages(const AgentBatch& b, BaseMessages* out) {
  for (const auto& kf : b.keyframes) out->keyframes.push_back(conv::ToMsg(kf, b.reference_kf));
  for (const auto& mp : b.map_points) {
    out->map_points.push_back(conv::PointBatch(mp.id.agent(), mp.segment));
    out->map_points.back().points().push_back(conv::ToMsg(mp));
  }
  for (const auto& u : b.keyframe_updates) out->keyframe_updates.push_back(conv::ToMsg(u));
  for (const auto& u : b.map_point_updates) {
    out->map_point_updates.push_back(conv::PointUpdateBatch(u.id.agent(), b.segment));
    out->map_point_updates.back().updates().push_back(conv::ToMsg(u));
  }
}

// Mutates one random field of a keyframe.
void MutateKeyframe(MsgMutator& z, msg::KeyframeFull* m) {
  msg::CameraInfo& cam = m->camera();
  msg::Keypoint* kp = m->keypoints().empty() ? nullptr : &m->keypoints()[z.Index(m->keypoints().size())];
  switch (z.rng()() % 17) {
    case 0: m->protocol_version(z.Version()); break;
    case 1: m->agent_id(z.OtherAgent(m->agent_id())); break;
    case 2: m->id(z.Id(m->id())); break;
    case 3: m->segment_id(z.Id(m->segment_id())); break;
    case 4: m->stamp_ns(z.Integer(m->stamp_ns())); break;
    case 5: cam.model(z.Integer(cam.model())); cam.width_px(z.Chance(0.5) ? z.Integer(cam.width_px()) : cam.width_px()); break;
    case 6: cam.fx(z.Realf(cam.fx())); cam.cy(z.Chance(0.3) ? z.Realf(cam.cy()) : cam.cy()); break;
    case 7: if (!cam.distortion().empty() && z.Chance(0.5)) cam.distortion()[0] = z.Realf(cam.distortion()[0]); else z.Resize(&cam.distortion()); break;
    case 8: m->pyramid_levels(z.Integer(m->pyramid_levels())); break;
    case 9: m->pyramid_scale_factor(z.Realf(m->pyramid_scale_factor())); break;
    case 10:
      if (!kp) break;
      switch (z.rng()() % 4) {
        case 0: kp->x_eighth_px(z.Integer(kp->x_eighth_px())); break;
        case 1: kp->y_eighth_px(z.Integer(kp->y_eighth_px())); break;
        case 2: kp->angle_256(z.Integer(kp->angle_256())); break;
        default: kp->octave(z.Integer(kp->octave())); break;
      }
      break;
    case 11: z.Chance(0.5) ? z.Resize(&m->keypoints()) : z.Resize(&m->descriptors()); break;
    case 12:
      // Own links (offsets from a base) or links to other agents' points (full ids).
      if (z.Chance(0.5)) {
        if (!m->own_mp_keypoint_index().empty() && z.Chance(0.5)) {
          auto& i = m->own_mp_keypoint_index()[z.Index(m->own_mp_keypoint_index().size())];
          i = z.Integer(i);
        } else {
          z.Chance(0.5) ? z.Resize(&m->own_mp_keypoint_index()) : z.Resize(&m->own_mp_offsets());
        }
      } else if (!m->other_mp_keypoint_index().empty() && z.Chance(0.5)) {
        auto& i = m->other_mp_keypoint_index()[z.Index(m->other_mp_keypoint_index().size())];
        i = z.Integer(i);
      } else {
        z.Chance(0.5) ? z.Resize(&m->other_mp_keypoint_index()) : z.Resize(&m->other_mp_ids());
      }
      break;
    case 13:
      if (z.Chance(0.3)) {
        m->own_mp_base(z.Id(m->own_mp_base()));
      } else if (!m->own_mp_offsets().empty() && z.Chance(0.5)) {
        auto& o = m->own_mp_offsets()[z.Index(m->own_mp_offsets().size())];
        o = z.Integer(o);
      } else if (!m->other_mp_ids().empty()) {
        auto& id = m->other_mp_ids()[z.Index(m->other_mp_ids().size())];
        id = z.Id(id);
      }
      break;
    case 14: z.Chance(0.5) ? m->predecessor_id(z.Id(m->predecessor_id())) : m->parent_id(z.Id(m->parent_id())); break;
    case 15:
      // Anchor flag flipped, with or without the features an anchor must not carry.
      m->anchor_only(!m->anchor_only());
      if (z.Chance(0.5)) {
        m->keypoints().clear();
        m->descriptors().clear();
        m->own_mp_keypoint_index().clear();
        m->own_mp_offsets().clear();
        m->other_mp_keypoint_index().clear();
        m->other_mp_ids().clear();
      }
      break;
    default: {
      msg::Pose* poses[] = {&m->pred_from_this(), &m->parent_from_this(), &m->segment_from_this()};
      z.Pose(poses[z.Index(3)]);
      break;
    }
  }
}

void MutateMapPoint(MsgMutator& z, msg::MapPointBatch* b) {
  msg::MapPointFull* m = &b->points()[0];
  switch (z.rng()() % 10) {
    case 0: b->protocol_version(z.Version()); break;
    case 1: b->agent_id(z.OtherAgent(b->agent_id())); break;
    case 2: m->id(z.Id(m->id())); break;
    case 3: b->segment_counter(z.Integer(b->segment_counter())); break;
    case 4: m->ref_kf_id(z.Id(m->ref_kf_id())); break;
    case 5: m->x_ref(z.Realf(m->x_ref())); break;
    case 6: m->z_ref(z.Realf(m->z_ref())); break;
    case 7: z.Chance(0.5) ? z.Resize(&m->obs_kf_offsets()) : z.Resize(&m->obs_keypoint_index()); break;
    case 8:
      if (!m->obs_kf_offsets().empty()) {
        auto& o = m->obs_kf_offsets()[z.Index(m->obs_kf_offsets().size())];
        o = z.Integer(o);
      }
      break;
    default: if (!m->obs_keypoint_index().empty()) { auto& i = m->obs_keypoint_index()[0]; i = z.Integer(i); } break;
  }
}

void MutateKeyframeUpdate(MsgMutator& z, msg::KeyframeUpdate* m) {
  switch (z.rng()() % 9) {
    case 0: m->protocol_version(z.Version()); break;
    case 1: m->agent_id(z.OtherAgent(m->agent_id())); break;
    case 2: m->id(z.Id(m->id())); break;
    case 3: m->segment_counter(z.Integer(m->segment_counter())); break;
    case 4: m->predecessor_id(z.Id(m->predecessor_id())); break;
    case 5: m->parent_id(z.Id(m->parent_id())); break;
    case 6: z.Pose(&m->pred_from_this()); break;
    case 7: z.Pose(&m->parent_from_this()); break;
    default: {  // sent by another agent, consistently
      const AgentId a = z.Chance(0.2) ? 0 : z.OtherAgent(m->agent_id());
      m->agent_id(a);
      m->id(MsgMutator::Readdress(m->id(), a));
      m->predecessor_id(MsgMutator::Readdress(m->predecessor_id(), a));
      break;
    }
  }
}

void MutateMapPointUpdate(MsgMutator& z, msg::MapPointUpdateBatch* b) {
  msg::MapPointUpdate* m = &b->updates()[0];
  switch (z.rng()() % 8) {
    case 0: b->protocol_version(z.Version()); break;
    case 1: b->agent_id(z.OtherAgent(b->agent_id())); break;
    case 2: m->id(z.Id(m->id())); break;
    case 3: b->segment_counter(z.Integer(b->segment_counter())); break;
    case 4: m->ref_kf_id(z.Id(m->ref_kf_id())); break;
    case 5: m->y_ref(z.Realf(m->y_ref())); break;
    case 6: m->z_ref(z.Realf(m->z_ref())); break;
    default: {  // sent by another agent, consistently
      const AgentId a = z.Chance(0.2) ? 0 : z.OtherAgent(b->agent_id());
      b->agent_id(a);
      m->id(MsgMutator::Readdress(m->id(), a));
      m->ref_kf_id(MsgMutator::Readdress(m->ref_kf_id(), a));
      break;
    }
  }
}

// Accepted items, grouped the way a server comm module would batch them.
class BatchSink {
 public:
  AgentBatch& For(AgentId agent, MapId segment, KeyframeId reference = {}) {
    AgentBatch& b = batches_[{agent, segment}];
    b.agent = agent;
    b.segment = segment;
    if (reference.valid()) b.reference_kf = reference;
    return b;
  }
  void Flush(ServerBackend* backend, int* refused) {
    for (auto& [key, batch] : batches_) {
      if (backend->Submit(std::move(batch)) < 0) ++*refused;
    }
    batches_.clear();
  }

 private:
  std::map<std::pair<AgentId, MapId>, AgentBatch> batches_;
};

TEST(MsgConversionFuzz, HundredThousandHostileMessagesNeverCrashTheBackend) {
  const auto sim = testing::LoadSim("hall3");
  ASSERT_TRUE(sim);
  const testing::VoStream stream = testing::RunVoStream(sim, 0, 0, 100, 5);
  ASSERT_FALSE(stream.batches.empty());
  ServerOptions options;
  options.max_agents = 4;  // messages re-addressed to other agents also meet the refusal
  options.optimization.global_ba_threads = 1;
  ASSERT_TRUE(testing::SimVocabulary());
  ServerBackend backend(testing::SimVocabulary(), options);

  // Base messages; the unmutated ones must all pass (real data) and go to the back-end.
  BaseMessages base;
  conv::CameraCache cameras(8);
  for (const AgentBatch& b : stream.batches) AddAgentMessages(b, &base);
  std::string error;
  for (const auto& m : base.keyframes) ASSERT_TRUE(conv::FromMsg(m, &cameras, &error)) << error;
  for (const auto& m : base.map_points) {
    const auto segment = conv::BatchSegment(m, &error);
    ASSERT_TRUE(segment && conv::FromMsg(m.points()[0], m.agent_id(), *segment, &error)) << error;
  }
  for (const auto& m : base.keyframe_updates) ASSERT_TRUE(conv::FromMsg(m, &error)) << error;
  for (const auto& m : base.map_point_updates) {
    ASSERT_TRUE(conv::BatchSegment(m, &error) && conv::FromMsg(m.updates()[0], m.agent_id(), &error)) << error;
  }
  for (const AgentBatch& b : stream.batches) backend.Submit(b);
  backend.ProcessAllQueued();
  for (const AgentBatch& b : stream.batches) {
    const AgentAcks acks = backend.TakeAcks(kAgent);
    if (const auto data = backend.Neighbourhood(kAgent, b.reference_kf)) {
      base.server.push_back(conv::ToMsg(kAgent, b.stamp_ns, acks.keyframes, acks.map_points, &*data));
    }
  }
  const ServerMapData synthetic = testing::MakeServerMapData(kAgent, 5, 500, 300);
  base.server.push_back(conv::ToMsg(kAgent, 1, {KeyframeId::Make(kAgent, 1)}, {}, &synthetic));
  for (const auto& m : base.server) ASSERT_TRUE(conv::FromMsg(m, kAgent, &cameras, &error)) << error;
  std::cout << "base: " << base.keyframes.size() << " keyframes, " << base.map_points.size() << " points, "
            << base.keyframe_updates.size() << " + " << base.map_point_updates.size() << " updates, "
            << base.server.size() << " server messages\n";
  ASSERT_FALSE(base.keyframes.empty() || base.map_points.empty() || base.keyframe_updates.empty() ||
               base.map_point_updates.empty());

  constexpr int kTotal = 100000;
  MsgMutator z(20240611);
  BatchSink sink;
  int accepted = 0, rejected = 0, refused_batches = 0;
  std::map<std::string, int> reasons;
  for (int i = 0; i < kTotal; ++i) {
    error.clear();
    bool ok = false;
    const int kind = static_cast<int>(z.Index(100));
    if (kind < 30) {
      msg::KeyframeFull m = base.keyframes[z.Index(base.keyframes.size())];
      KeyframeId ref;
      std::optional<KeyframeData> kf;
      if (Mutate<msg::KeyframeFullPubSubType>(z, &m, MutateKeyframe) && (kf = conv::FromMsg(m, &cameras, &error, &ref))) {
        sink.For(m.agent_id(), kf->segment, ref).keyframes.push_back(std::move(*kf));
        ok = true;
      }
    } else if (kind < 55) {
      msg::MapPointBatch m = base.map_points[z.Index(base.map_points.size())];
      std::optional<MapPointData> mp;
      std::optional<MapId> segment;
      if (Mutate<msg::MapPointBatchPubSubType>(z, &m, MutateMapPoint) && (segment = conv::BatchSegment(m, &error)) &&
          m.points().size() == 1 && (mp = conv::FromMsg(m.points()[0], m.agent_id(), *segment, &error))) {
        sink.For(m.agent_id(), mp->segment).map_points.push_back(std::move(*mp));
        ok = true;
      }
    } else if (kind < 70) {
      msg::KeyframeUpdate m = base.keyframe_updates[z.Index(base.keyframe_updates.size())];
      std::optional<KeyframePoseUpdate> u;
      if (Mutate<msg::KeyframeUpdatePubSubType>(z, &m, MutateKeyframeUpdate) && (u = conv::FromMsg(m, &error))) {
        sink.For(m.agent_id(), u->segment).keyframe_updates.push_back(*u);
        ok = true;
      }
    } else if (kind < 85) {
      msg::MapPointUpdateBatch m = base.map_point_updates[z.Index(base.map_point_updates.size())];
      std::optional<MapPointPositionUpdate> u;
      std::optional<MapId> segment;
      if (Mutate<msg::MapPointUpdateBatchPubSubType>(z, &m, MutateMapPointUpdate) &&
          (segment = conv::BatchSegment(m, &error)) && m.updates().size() == 1 &&
          (u = conv::FromMsg(m.updates()[0], m.agent_id(), &error))) {
        sink.For(m.agent_id(), *segment).map_point_updates.push_back(*u);
        ok = true;
      }
    } else {
      msg::ServerToAgent m = base.server[z.Index(base.server.size())];
      ok = Mutate<msg::ServerToAgentPubSubType>(z, &m, MutateServer) && conv::FromMsg(m, kAgent, &cameras, &error);
    }
    if (ok) {
      ++accepted;
    } else {
      ++rejected;
      ++reasons[error.empty() ? "payload refused by the deserializer" : conv::ReasonKind(error)];
    }
    if (i % 200 == 199) sink.Flush(&backend, &refused_batches);
    if (i % 5000 == 4999) backend.ProcessAllQueued();
  }
  sink.Flush(&backend, &refused_batches);
  backend.ProcessAllQueued();

  EXPECT_EQ(accepted + rejected, kTotal);
  EXPECT_GT(accepted, kTotal / 10);
  EXPECT_GT(rejected, kTotal / 10);
  int64_t backend_rejected = 0;
  for (const auto& [agent, c] : backend.Status().stats.agents) backend_rejected += c.rejected;
  EXPECT_EQ(backend_rejected, 0) << "FromMsg let through what the back-end's validation refuses";
  std::cout << accepted << " accepted, " << rejected << " rejected (" << reasons.size() << " kinds), "
            << refused_batches << " batches refused by the back-end (agents beyond max_agents / agent 0)\n";
  int shown = 0;
  for (const auto& [reason, count] : reasons) {
    if (shown++ < 200) std::cout << "  " << count << "  " << reason << "\n";
  }
}

}  // namespace
}  // namespace ccm
