// Saving and loading the server's whole map stack, so a restarted server keeps its maps and
// agents rejoin them. The payload (cereal portable binary) holds the maps with keyframes,
// points, covisibility, spanning tree, loop edges, anchors and merged ids; the handlers with
// Sim(3) and scale; the events. Its envelope and the durable write (fsync, previous
// generation kept as path.prev) are stack_file.h's. The place-recognition database is not
// saved: the back-end rebuilds it from the keyframes with the vocabulary given at load time.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/server/map_stack.h"
#include "slam_core/server/server_backend.h"

namespace ccm {

/// What a map stack file holds.
struct MapStackContents {
  std::vector<std::shared_ptr<ServerMap>> maps;
  std::vector<AgentHandler> handlers;  ///< each points to one of `maps`
  uint64_t next_map_counter = 0;
  std::vector<ServerEvent> events;
};

class MapPersistence {
 public:
  /// While the back-end runs: each map is copied under its shared structure lock; the
  /// handlers are taken after the maps, and one whose map is not in the file (created, or
  /// fused into another, while the maps were copied) is left out, so the file always loads
  /// (that agent's next data opens a new map).
  static bool Save(const MapStack& stack, const std::vector<ServerEvent>& events, const std::string& path,
                   std::string* error);
  /// The newest generation that reads back; when that is path.prev (path itself unreadable
  /// or corrupt), *warning says why.
  static std::optional<MapStackContents> Load(const std::string& path, const MapOptions& map_options,
                                              std::string* error, std::string* warning);
};

}  // namespace ccm
