// Compact binary vocabulary files (docs/place-recognition.md, "File format"): an 8-byte magic,
// version, branching, levels, weighting/scoring ids, node count, then 41 bytes per node
// (parent, is-word flag, IDF weight, descriptor) and a trailing FNV-1a-64 checksum.
// Little-endian on disk regardless of the host. A 1M-word vocabulary is ~46 MB and loads in
// a few hundred ms; loading validates sizes, checksum and tree structure and says what failed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <istream>
#include <optional>
#include <string>
#include <vector>

#include "slam_core/common/checksum.h"
#include "slam_core/place_recognition/vocabulary.h"

namespace ccm {

/// File magic and the version this code writes (and the only one it reads).
inline constexpr char kVocabularyMagic[8] = {'C', 'C', 'M', 'V', 'O', 'C', 'A', 'B'};
inline constexpr std::uint32_t kVocabularyVersion = 1;

/// The file contents of a vocabulary.
std::vector<std::uint8_t> SerializeVocabulary(const Vocabulary& vocabulary);
/// Parses file contents; nullopt and *error ("checksum mismatch: file corrupted") on failure.
std::optional<Vocabulary> DeserializeVocabulary(const std::uint8_t* data, std::size_t size,
                                                std::string* error);

/// Writes `path` (via a temporary file and rename, so readers never see half a file).
/// Empty string on success, else the problem.
std::string SaveVocabularyFile(const Vocabulary& vocabulary, const std::string& path);
/// Reads a vocabulary file; nullopt and *error naming the file on failure.
std::optional<Vocabulary> LoadVocabularyFile(const std::string& path, std::string* error);

/// Imports the DBoW2 text format of ORB-SLAM (ORBvoc.txt: "k L scoring weighting", then per
/// node "parent is_leaf d0 .. d31 weight"). Only TF-IDF weighting and L1 scoring are accepted.
/// Word ids equal DBoW2's, so bags of words are compatible with ORB-SLAM's.
std::optional<Vocabulary> ImportDbow2TextVocabulary(std::istream& in, std::string* error);
std::optional<Vocabulary> ImportDbow2TextFile(const std::string& path, std::string* error);

}  // namespace ccm
