// Saving and loading the server's whole map stack, so a restarted server keeps its maps and
// agents rejoin them. File: magic "CCMSTACK", format version (u32), payload size (u64), the
// payload (cereal portable binary: maps with keyframes, points, covisibility, spanning tree,
// loop edges, anchors and merged ids; handlers with Sim(3) and scale; events), and an
// FNV-1a-64 checksum of the payload. Written to a temporary file and renamed. The place-
// recognition database is rebuilt from the keyframes with the vocabulary given at load time.
#pragma once

#include <memory>
#include <string>

#include "slam_core/server/server_backend.h"

namespace ccm {

inline constexpr char kMapStackMagic[8] = {'C', 'C', 'M', 'S', 'T', 'A', 'C', 'K'};
inline constexpr std::uint32_t kMapStackVersion = 1;

class MapPersistence {
 public:
  /// Consistent while the back-end runs: each map is copied under its shared structure lock.
  static bool Save(const ServerBackend& backend, const std::string& path, std::string* error);
  static std::unique_ptr<ServerBackend> Load(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                                             ServerOptions options, std::string* error);
};

}  // namespace ccm
