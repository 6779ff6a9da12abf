// Globally unique ids for keyframes, map points and map segments.
// An id packs the owning agent (16 bits) and that agent's ascending counter (48 bits),
// so ids from different agents never collide and no global/static counter is needed:
// each agent owns an IdGenerator and passes it to whoever creates objects.
#pragma once

#include <cstdint>
#include <functional>
#include <ostream>

namespace ccm {

using AgentId = std::uint16_t;

template <typename Tag>
class Id {
 public:
  static constexpr int kCounterBits = 48;
  static constexpr std::uint64_t kCounterMask = (std::uint64_t{1} << kCounterBits) - 1;

  constexpr Id() = default;
  constexpr explicit Id(std::uint64_t packed) : packed_(packed) {}
  static constexpr Id Make(AgentId agent, std::uint64_t counter) {
    return Id((std::uint64_t{agent} << kCounterBits) | (counter & kCounterMask));
  }
  /// The "no object" id. Counters start at 1 so a packed value of 0 is never valid.
  static constexpr Id Invalid() { return Id(); }

  constexpr std::uint64_t packed() const { return packed_; }
  constexpr AgentId agent() const { return static_cast<AgentId>(packed_ >> kCounterBits); }
  constexpr std::uint64_t counter() const { return packed_ & kCounterMask; }
  constexpr bool valid() const { return counter() != 0; }

  friend constexpr bool operator==(Id a, Id b) { return a.packed_ == b.packed_; }
  friend constexpr bool operator!=(Id a, Id b) { return a.packed_ != b.packed_; }
  friend constexpr bool operator<(Id a, Id b) { return a.packed_ < b.packed_; }
  friend std::ostream& operator<<(std::ostream& os, Id id) {
    return os << id.agent() << ':' << id.counter();
  }

 private:
  std::uint64_t packed_ = 0;
};

struct KeyframeTag {};
struct MapPointTag {};
struct MapTag {};
using KeyframeId = Id<KeyframeTag>;
using MapPointId = Id<MapPointTag>;
using MapId = Id<MapTag>;

/// Hands out ascending ids for one agent. Not thread-safe: owned by one component.
template <typename IdT>
class IdGenerator {
 public:
  explicit IdGenerator(AgentId agent, std::uint64_t next_counter = 1)
      : agent_(agent), next_(next_counter) {}
  IdT Next() { return IdT::Make(agent_, next_++); }
  AgentId agent() const { return agent_; }

 private:
  AgentId agent_;
  std::uint64_t next_;
};

}  // namespace ccm

namespace std {
template <typename Tag>
struct hash<ccm::Id<Tag>> {
  size_t operator()(ccm::Id<Tag> id) const noexcept { return std::hash<std::uint64_t>()(id.packed()); }
};
}  // namespace std
