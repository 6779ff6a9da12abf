// The map stack file's envelope (docs/server.md, persistence): magic "CCMSTACK", format
// version (u32), payload size (u64), the payload, FNV-1a-64 of the payload. Durable writes:
// the new file is written to path.tmp and fsynced, the current file is kept as path.prev
// (the previous generation, for when the newest cannot be read), path.tmp is renamed over
// path and the folder is fsynced, so at every moment `path` is a complete file and a crash
// or power cut loses at most the newest generation.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace ccm {

inline constexpr char kMapStackMagic[8] = {'C', 'C', 'M', 'S', 'T', 'A', 'C', 'K'};
inline constexpr std::uint32_t kMapStackVersion = 1;

/// The previous generation of `path`.
std::string PreviousGeneration(const std::string& path);
bool WriteStackFile(const std::string& path, const std::string& payload, std::string* error);
/// The payload, with magic, version, size and checksum checked; errors name `path`.
std::optional<std::string> ReadStackFile(const std::string& path, std::string* error);

}  // namespace ccm
