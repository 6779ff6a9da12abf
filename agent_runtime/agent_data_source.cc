#include "agent_runtime/agent_data_source.h"

namespace ccm::agent {

AgentBatch VoDataSource::TakeBatch(int64_t now_ns, bool flush) {
  if (flush) packer_.FlushNext();
  return packer_.Pack(vo_->TakeChanges(), now_ns);
}

bool VoDataSource::Resend(KeyframeId id) {
  const auto map = vo_->map();
  if (!map || !map->keyframe(id)) return false;
  packer_.Resend(id);
  return true;
}

AgentDataSource::Counters VoDataSource::counters() const {
  const AgentVoStats s = vo_->stats();
  Counters c;
  c.keyframes_created = s.keyframes_created;
  c.keyframes_lost = s.trim.removed_lost;
  c.removed_unpersisted = s.trim.removed_unpersisted;
  c.deferred = packer_.deferred();
  c.anchors_sent = packer_.anchors_sent();
  c.anchors_resent_in_full = packer_.anchors_resent_in_full();
  return c;
}

}  // namespace ccm::agent
