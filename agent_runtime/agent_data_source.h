// What AgentComm streams to the server, behind one interface: the live VO's changes packed
// by a ChangePacker (VoDataSource, ccm_agent), or an agent's recorded keyframe stream played
// at its recorded pace (tools/fleet, one process posing as many agents). AgentComm calls it
// from its comm thread only, so an implementation needs no lock of its own for those calls.
#pragma once

#include <cstdint>

#include "slam_core/exchange/agent_data.h"
#include "slam_core/exchange/server_map_data.h"
#include "slam_core/vo/agent_vo.h"
#include "slam_core/vo/change_packer.h"

namespace ccm::agent {

class AgentDataSource {
 public:
  struct Counters {
    int64_t keyframes_created = 0;
    int64_t keyframes_lost = 0;         ///< left the local map unacknowledged (buffer N+B full)
    int64_t removed_unpersisted = 0;    ///< left it acknowledged but not saved by the server yet
    size_t deferred = 0;                ///< held back (keyframe delay): not in a batch yet
    size_t anchors_sent = 0;            ///< keyframes sent as pose anchors only
    size_t anchors_resent_in_full = 0;  ///< of those, resent in full (what they duplicate was gone)
  };

  virtual ~AgentDataSource() = default;
  /// What is new or changed since the last call, packed relative (may be empty). `flush`:
  /// the flight is over, send what a delay holds back.
  virtual AgentBatch TakeBatch(int64_t now_ns, bool flush) = 0;
  /// Puts keyframe `id` in full into the next batch; false if the source no longer has it
  /// (it left the local map: the server will never get it).
  virtual bool Resend(KeyframeId id) = 0;
  /// The server's map data (map sharing).
  virtual void ApplyServerData(ServerMapData data) = 0;
  virtual Counters counters() const = 0;
  /// The server keyframes the agent holds (reported so the server sends them as poses only);
  /// none by default (a recording keeps nothing it receives).
  virtual ServerHoldings Holdings() const { return {}; }
};

/// The live VO: its changes since the last batch, packed by a ChangePacker. The VO is the
/// caller's and outlives this.
class VoDataSource : public AgentDataSource {
 public:
  VoDataSource(AgentVo* vo, AgentId agent, ChangePackerOptions options) : vo_(vo), packer_(agent, options) {}
  AgentBatch TakeBatch(int64_t now_ns, bool flush) override;
  bool Resend(KeyframeId id) override;
  void ApplyServerData(ServerMapData data) override { vo_->ApplyServerData(std::move(data)); }
  Counters counters() const override;
  ServerHoldings Holdings() const override { return vo_->Holdings(); }

 private:
  AgentVo* vo_;
  ChangePacker packer_;
};

}  // namespace ccm::agent
