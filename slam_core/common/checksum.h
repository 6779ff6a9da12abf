// FNV-1a 64-bit hash of a byte range: the checksum of the project's binary files
// (vocabulary, saved map stack). Not cryptographic: it detects corruption, not tampering.
#pragma once

#include <cstddef>
#include <cstdint>

namespace ccm {

inline std::uint64_t Fnv1a64(const std::uint8_t* data, std::size_t size) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (std::size_t i = 0; i < size; ++i) {
    h ^= data[i];
    h *= 0x100000001b3ull;
  }
  return h;
}

}  // namespace ccm
