// Random mutations of protocol messages for the conversion layer's fuzz test: field changes
// (ids of other agents, NaN/inf, huge values, non-unit quaternions, inconsistent lengths,
// truncated sequences, wrong versions) and byte-level ones on the serialized payload (bit
// flips, truncation). Deterministic for a seed.
#pragma once

#include <cstdint>
#include <limits>
#include <random>
#include <type_traits>

#include "idl/ccm_msgs.h"
#include "slam_core/common/ids.h"

namespace ccm::testing {

class MsgMutator {
 public:
  explicit MsgMutator(std::uint64_t seed) : rng_(seed) {}

  std::mt19937_64& rng() { return rng_; }
  size_t Index(size_t n) { return n == 0 ? 0 : static_cast<size_t>(rng_() % n); }
  bool Chance(double p) { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < p; }

  /// Another agent's id, counter 0, zero, random bits, all ones; rarely another counter of
  /// the same agent (a new object: accepted, and costly for the back-end, hence rare).
  std::uint64_t Id(std::uint64_t packed) {
    const KeyframeId id(packed);
    switch (rng_() % 7) {
      case 0: return 0;
      case 1: return KeyframeId::Make(id.agent(), 0).packed();
      case 2: return rng_();
      case 3: return ~std::uint64_t{0};
      case 4: return Chance(0.05) ? KeyframeId::Make(id.agent(), id.counter() + 1 + rng_() % 1000).packed() : packed;
      default: return KeyframeId::Make(OtherAgent(id.agent()), id.counter()).packed();
    }
  }
  AgentId OtherAgent(AgentId agent) { return static_cast<AgentId>(agent + 1 + rng_() % 5); }
  /// The same object as if another agent had sent it (agent 0 included: the server's).
  static std::uint64_t Readdress(std::uint64_t packed, AgentId agent) {
    return packed == 0 ? 0 : KeyframeId::Make(agent, KeyframeId(packed).counter()).packed();
  }

  /// NaN, +-inf, huge, zero, sign flip, denormal, or (often) a small perturbation.
  double Real(double v) {
    switch (rng_() % 12) {
      case 0: return std::numeric_limits<double>::quiet_NaN();
      case 1: return std::numeric_limits<double>::infinity();
      case 2: return -std::numeric_limits<double>::infinity();
      case 3: return 1e30;
      case 4: return -2e6;
      case 5: return 0.0;
      case 6: return -v;
      case 7: return std::numeric_limits<double>::denorm_min();
      default: return v * (1.0 + 1e-3 * Normal()) + 1e-3 * Normal();
    }
  }
  float Realf(float v) { return static_cast<float>(Real(v)); }

  /// 0, the maximum, +-1 (wrapping, as the sender's own integer arithmetic would: computed
  /// unsigned, since v + 1 overflows a signed T at its maximum), or random bits.
  template <typename T>
  T Integer(T v) {
    using U = std::make_unsigned_t<T>;
    switch (rng_() % 5) {
      case 0: return 0;
      case 1: return std::numeric_limits<T>::max();
      case 2: return static_cast<T>(static_cast<U>(static_cast<U>(v) + 1u));
      case 3: return static_cast<T>(static_cast<U>(static_cast<U>(v) - 1u));
      default: return static_cast<T>(rng_());
    }
  }

  std::uint16_t Version() {
    const std::uint16_t versions[] = {0, 1, 3, 4, 0xffff};
    return versions[rng_() % 5];
  }

  void Pose(msg::Pose* p) {
    switch (rng_() % 6) {
      case 0: p->tx(Real(p->tx())); break;
      case 1: p->tz(Real(p->tz())); break;
      case 2: p->qw(Real(p->qw())); break;
      case 3: p->qx(p->qx() * 1.5); p->qy(p->qy() * 1.5); p->qz(p->qz() * 1.5); p->qw(p->qw() * 1.5); break;
      case 4: p->qx(0); p->qy(0); p->qz(0); p->qw(0); break;
      default: p->qx(p->qx() + 1e-4); break;  // within the tolerance: accepted, normalized
    }
  }

  /// Truncate, clear, pop, or grow by repeating an element.
  template <typename Seq>
  void Resize(Seq* s) {
    switch (rng_() % 4) {
      case 0: s->resize(Index(s->size())); break;
      case 1: s->clear(); break;
      case 2: if (!s->empty()) s->pop_back(); break;
      default: if (!s->empty()) s->push_back(s->at(Index(s->size()))); break;
    }
  }

 private:
  double Normal() { return std::normal_distribution<double>(0.0, 1.0)(rng_); }

  std::mt19937_64 rng_;
};

}  // namespace ccm::testing
