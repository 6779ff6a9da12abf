// Small deterministic random tools for the simulator. Why not <random> distributions:
// their output is implementation-defined, and "same scenario + seed => byte-identical
// images" must hold across standard libraries. Use SplitMix64 for sequences and
// HashMix for order-independent per-pixel noise.
#pragma once

#include <cmath>
#include <cstdint>
#include <initializer_list>

namespace ccm::sim {

/// Stateless 64-bit mixer (SplitMix64 finaliser).
inline std::uint64_t HashMix(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

inline std::uint64_t HashCombine(std::uint64_t a, std::uint64_t b) {
  return HashMix(a ^ (HashMix(b) + 0x632BE59BD9B4E019ull + (a << 6) + (a >> 2)));
}

/// FNV-1a string hash (std::hash is implementation-defined).
inline std::uint64_t StringHash(const char* s) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (; *s != 0; ++s) h = (h ^ static_cast<unsigned char>(*s)) * 0x100000001b3ull;
  return h;
}

/// Sequential generator. Not thread-safe; one per task.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(HashMix(seed)) {}
  std::uint64_t NextU64() { return HashMix(state_ += 0x9E3779B97F4A7C15ull); }
  /// Uniform in [0, 1).
  double Uniform() { return static_cast<double>(NextU64() >> 11) * 0x1.0p-53; }
  double Uniform(double lo, double hi) { return lo + (hi - lo) * Uniform(); }
  /// Uniform integer in [lo, hi].
  int Int(int lo, int hi) {
    return lo + static_cast<int>(NextU64() % static_cast<std::uint64_t>(hi - lo + 1));
  }
  /// Log-uniform in [lo, hi], both > 0.
  double LogUniform(double lo, double hi) { return lo * std::exp(Uniform() * std::log(hi / lo)); }
  /// Index i with probability weights[i] / sum(weights).
  int Pick(std::initializer_list<double> weights) {
    double total = 0.0;
    for (double w : weights) total += w;
    double x = Uniform() * total;
    int i = 0;
    for (double w : weights) {
      if ((x -= w) < 0.0) return i;
      ++i;
    }
    return i - 1;
  }
  double Normal() {
    const double u1 = 1.0 - Uniform();
    const double u2 = Uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
  }

 private:
  std::uint64_t state_;
};

/// Approximately standard-normal value from a hash (Irwin-Hall sum of four 16-bit
/// uniforms, variance-corrected); cheap enough for per-pixel sensor noise.
inline float HashNormal(std::uint64_t h) {
  const float s = static_cast<float>(h & 0xFFFF) + static_cast<float>((h >> 16) & 0xFFFF) +
                  static_cast<float>((h >> 32) & 0xFFFF) + static_cast<float>(h >> 48);
  // Sum of 4 U(0, 65536): mean 131072, std 65536 * sqrt(4 / 12).
  return (s - 131072.0f) * (1.0f / 37837.23f);
}

}  // namespace ccm::sim
