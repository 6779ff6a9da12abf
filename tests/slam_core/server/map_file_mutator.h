// Mutations of a map stack file's payload for the map-file fuzz test: the payload is walked
// field by field (the record layout of slam_core/server/map_persistence.cc as cereal's
// portable binary archive writes it: little-endian scalars, u64 size tags before vectors and
// strings, nothing before std::array), so most mutations hit a field of a known kind (a size,
// an id, an index or level, a real, a bool) with a value chosen to break it; the rest are
// byte-level (bit flips, truncation, a slice removed or repeated). The test recomputes the
// checksum, so every input reaches the decoder. Deterministic for a seed.
#pragma once

#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <random>
#include <string>
#include <vector>

namespace ccm::testing {

struct PayloadField {
  enum Kind { kSize, kId, kIndex, kReal, kBool };
  size_t offset;
  int width;  ///< bytes: 1, 2, 4 or 8 (reals: 4 float, 8 double)
  Kind kind;
};

/// The fields of a map stack payload; nullopt when the walk does not end exactly at the end
/// of the payload (the layout here no longer matches map_persistence.cc).
class PayloadWalker {
 public:
  static std::optional<std::vector<PayloadField>> Walk(const std::string& payload) {
    PayloadWalker w(payload);
    if (!w.Byte(PayloadField::kBool)) return std::nullopt;  // the archive's endianness byte
    if (!w.Stack() || w.pos_ != payload.size()) return std::nullopt;
    return std::move(w.fields_);
  }

 private:
  explicit PayloadWalker(const std::string& p) : p_(p) {}

  bool Field(int width, PayloadField::Kind kind) {
    if (pos_ + width > p_.size()) return false;
    fields_.push_back({pos_, width, kind});
    pos_ += width;
    return true;
  }
  bool Byte(PayloadField::Kind kind) { return Field(1, kind); }
  bool Skip(size_t n) {
    if (pos_ + n > p_.size()) return false;
    pos_ += n;
    return true;
  }
  bool Size(uint64_t* n) {
    if (pos_ + 8 > p_.size()) return false;
    std::memcpy(n, p_.data() + pos_, 8);
    return Field(8, PayloadField::kSize) && *n <= p_.size();
  }
  template <class Fn>
  bool Vector(Fn element) {
    uint64_t n = 0;
    if (!Size(&n)) return false;
    for (uint64_t i = 0; i < n; ++i) {
      if (!element()) return false;
    }
    return true;
  }
  bool Reals(int count, int width = 8) {
    for (int i = 0; i < count; ++i) {
      if (!Field(width, PayloadField::kReal)) return false;
    }
    return true;
  }
  bool Ids(int count) {
    for (int i = 0; i < count; ++i) {
      if (!Field(8, PayloadField::kId)) return false;
    }
    return true;
  }
  bool Pose() { return Reals(7); }

  bool Camera() {
    return Field(4, PayloadField::kIndex) && Field(4, PayloadField::kIndex) && Field(4, PayloadField::kIndex) &&
           Reals(4) && Vector([&] { return Reals(1); });
  }
  bool Keyframe() {
    return Ids(1) && Field(8, PayloadField::kId) /* stamp */ && Field(4, PayloadField::kIndex) /* camera */ &&
           Field(4, PayloadField::kIndex) /* levels */ && Reals(1) /* scale factor */ &&
           Vector([&] { return Reals(1, 4); }) /* u v angle response */ &&
           Vector([&] { return Byte(PayloadField::kIndex); }) /* levels */ &&
           Vector([&] { return Skip(32); }) /* descriptors */ && Vector([&] { return Ids(1); }) /* map points */ &&
           Pose() && Ids(1) /* parent */ && Vector([&] { return Ids(1); }) /* children */ &&
           Vector([&] { return Ids(1); }) /* loop edges */ &&
           Vector([&] { return Ids(1) && Field(4, PayloadField::kIndex); }) /* covisibility */ &&
           Byte(PayloadField::kBool) /* has_info */ && Ids(3) && Pose() && Pose() && Pose() && Byte(PayloadField::kBool);
  }
  bool Point() {
    return Ids(2) && Reals(6) && Skip(32) && Reals(2) && Vector([&] { return Ids(1) && Field(4, PayloadField::kIndex); });
  }
  bool Anchor() { return Ids(3) && Pose() && Field(8, PayloadField::kId); }
  bool MapRecord() {
    return Ids(1) && Field(8, PayloadField::kIndex) /* generation */ && Vector([&] { return Keyframe(); }) &&
           Vector([&] { return Point(); }) && Vector([&] { return Anchor(); }) && Vector([&] { return Ids(2); });
  }
  bool Handler() {
    return Field(2, PayloadField::kIndex) && Ids(3) && Reals(1) && Reals(7) && Reals(1) && Field(8, PayloadField::kIndex);
  }
  bool Event() {
    return Field(4, PayloadField::kIndex) && Reals(2) && Field(8, PayloadField::kId) && Field(2, PayloadField::kIndex) &&
           Ids(4) && Field(4, PayloadField::kIndex) && Vector([&] { return Skip(1); });
  }
  bool Stack() {
    return Field(8, PayloadField::kIndex) /* next map */ && Vector([&] { return Camera(); }) &&
           Vector([&] { return MapRecord(); }) && Vector([&] { return Handler(); }) && Vector([&] { return Event(); });
  }

  const std::string& p_;
  size_t pos_ = 0;
  std::vector<PayloadField> fields_;
};

class PayloadMutator {
 public:
  PayloadMutator(uint64_t seed, const std::string& base, std::vector<PayloadField> fields)
      : rng_(seed), base_(base), fields_(std::move(fields)) {
    for (const PayloadField& f : fields_) {
      by_kind_[f.kind].push_back(f);
      if (f.kind == PayloadField::kId) ids_.push_back(Read(base_, f));
    }
  }

  /// A mutated copy of the base payload: 1-3 field mutations (80 %) or one byte-level one.
  std::string Next() {
    std::string p = base_;
    if (Chance(0.2)) {
      Bytes(&p);
      return p;
    }
    const int n = 1 + static_cast<int>(rng_() % 3);
    for (int i = 0; i < n; ++i) {
      // By kind first: keypoint coordinates (reals) outnumber the size tags 1000 to 1.
      const int roll = static_cast<int>(rng_() % 100);
      const auto kind = roll < 25 ? PayloadField::kSize
                        : roll < 45 ? PayloadField::kId
                        : roll < 70 ? PayloadField::kIndex
                        : roll < 90 ? PayloadField::kReal
                                    : PayloadField::kBool;
      const auto& pool = by_kind_[kind];
      MutateField(&p, pool[rng_() % pool.size()]);
    }
    return p;
  }

 private:
  bool Chance(double p) { return std::uniform_real_distribution<double>(0.0, 1.0)(rng_) < p; }
  static uint64_t Read(const std::string& p, const PayloadField& f) {
    uint64_t v = 0;
    std::memcpy(&v, p.data() + f.offset, f.width);
    return v;
  }
  static void Write(std::string* p, const PayloadField& f, uint64_t v) { std::memcpy(&(*p)[f.offset], &v, f.width); }

  void MutateField(std::string* p, const PayloadField& f) {
    const uint64_t v = Read(*p, f);
    const uint64_t all = f.width == 8 ? ~uint64_t{0} : (uint64_t{1} << (8 * f.width)) - 1;
    const uint64_t sign = uint64_t{1} << (8 * f.width - 1);
    switch (f.kind) {
      case PayloadField::kSize: {
        const uint64_t sizes[] = {0, v + 1, v - 1, v * 2 + 1, 1u << 20, uint64_t{1} << 32, uint64_t{1} << 62, all};
        Write(p, f, sizes[rng_() % 8]);
        break;
      }
      case PayloadField::kId: {
        // Another id of the same file (dangling or duplicated references), zero, or noise.
        const uint64_t choices[] = {ids_[rng_() % ids_.size()], 0, v + 1, v ^ (uint64_t{1} << (rng_() % 64)), rng_(), all};
        Write(p, f, choices[rng_() % 6]);
        break;
      }
      case PayloadField::kIndex: {
        const uint64_t choices[] = {0, all, sign, sign - 1, v + 1, v - 1, v + 16 + rng_() % 1000, rng_() & all};
        Write(p, f, choices[rng_() % 8] & all);
        break;
      }
      case PayloadField::kReal: Write(p, f, Real(v, f.width)); break;
      case PayloadField::kBool: Write(p, f, 2 + rng_() % 254); break;
    }
  }

  uint64_t Real(uint64_t bits, int width) {
    double d = 0;
    float x = 0;
    if (width == 8) std::memcpy(&d, &bits, 8);
    if (width == 4) std::memcpy(&x, &bits, 4), d = x;
    const double choices[] = {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(),
                              -std::numeric_limits<double>::infinity(), 0.0, -d, 1e300, -1e-300, d * 1.5 + 1e-3};
    d = choices[rng_() % 8];
    uint64_t out = 0;
    if (width == 8) std::memcpy(&out, &d, 8);
    if (width == 4) x = static_cast<float>(d), std::memcpy(&out, &x, 4);
    return out;
  }

  void Bytes(std::string* p) {
    switch (rng_() % 4) {
      case 0: p->resize(rng_() % p->size()); break;  // truncated
      case 1: {
        const int flips = 1 + static_cast<int>(rng_() % 8);
        for (int i = 0; i < flips; ++i) (*p)[1 + rng_() % (p->size() - 1)] ^= static_cast<char>(1u << (rng_() % 8));
        break;
      }
      case 2: {  // a slice removed
        const size_t at = rng_() % p->size();
        p->erase(at, 1 + rng_() % 64);
        break;
      }
      default: {  // a slice repeated
        const size_t at = rng_() % p->size();
        p->insert(at, p->substr(at, 1 + rng_() % 64));
        break;
      }
    }
  }

  std::mt19937_64 rng_;
  const std::string base_;
  const std::vector<PayloadField> fields_;
  std::vector<PayloadField> by_kind_[5];
  std::vector<uint64_t> ids_;
};

}  // namespace ccm::testing
