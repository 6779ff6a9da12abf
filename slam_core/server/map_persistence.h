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

#include "slam_core/server/map_stack_snapshot.h"
#include "slam_core/server/server_backend.h"

namespace ccm {

class MapPersistence {
 public:
  /// While the back-end runs: each map of the snapshot is copied under its shared structure
  /// lock (a map retired meanwhile is left out); a handler whose map is not in the file
  /// (created, or fused into another, after the maps were taken) is left out too, so the
  /// file always loads (that agent's next data opens a new map).
  static bool Save(const MapStackSnapshot& snapshot, const std::string& path, std::string* error);
  /// The newest generation that reads back, as a stack to start a back-end from; when that
  /// is path.prev (path itself unreadable or corrupt), *warning says why.
  static std::optional<RestoredStack> Load(const std::string& path, const MapOptions& map_options,
                                           std::string* error, std::string* warning);
};

/// The back-end's maps, handlers and events (ServerBackend::Snapshot()) into `path`.
bool SaveBackend(const ServerBackend& backend, const std::string& path, std::string* error);
/// A back-end started from the map stack in `path` (or its previous generation, then
/// *warning says so); nullptr and *error if neither loads. The place-recognition database is
/// rebuilt from the keyframes with `vocabulary`.
std::unique_ptr<ServerBackend> LoadBackend(const std::string& path, std::shared_ptr<const Vocabulary> vocabulary,
                                           ServerOptions options, std::string* error,
                                           std::string* warning = nullptr);

}  // namespace ccm
