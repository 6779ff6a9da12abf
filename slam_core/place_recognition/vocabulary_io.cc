#include "slam_core/place_recognition/vocabulary_io.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <random>

namespace ccm {

namespace {

constexpr std::size_t kHeaderBytes = 8 + 4 * 6;  // magic, version, k, L, weighting, scoring, nodes
constexpr std::size_t kNodeBytes = 4 + 1 + 4 + 32;
constexpr std::size_t kChecksumBytes = 8;
constexpr std::uint32_t kWeightingTfIdf = 0;
constexpr std::uint32_t kScoringL1 = 0;

void PutU32(std::vector<std::uint8_t>* out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out->push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
void PutU64(std::vector<std::uint8_t>* out, std::uint64_t v) {
  for (int i = 0; i < 8; ++i) out->push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}
std::uint32_t GetU32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 |
         std::uint32_t{p[3]} << 24;
}
std::uint64_t GetU64(const std::uint8_t* p) {
  return std::uint64_t{GetU32(p)} | std::uint64_t{GetU32(p + 4)} << 32;
}

}  // namespace

std::vector<std::uint8_t> SerializeVocabulary(const Vocabulary& vocabulary) {
  const auto& nodes = vocabulary.nodes();
  std::vector<std::uint8_t> out;
  out.reserve(kHeaderBytes + nodes.size() * kNodeBytes + kChecksumBytes);
  out.insert(out.end(), std::begin(kVocabularyMagic), std::end(kVocabularyMagic));
  PutU32(&out, kVocabularyVersion);
  PutU32(&out, static_cast<std::uint32_t>(vocabulary.branching()));
  PutU32(&out, static_cast<std::uint32_t>(vocabulary.levels()));
  PutU32(&out, kWeightingTfIdf);
  PutU32(&out, kScoringL1);
  PutU32(&out, static_cast<std::uint32_t>(nodes.size()));
  for (const auto& n : nodes) {
    PutU32(&out, n.parent);
    out.push_back(n.word != Vocabulary::kNoWord ? 1 : 0);
    std::uint32_t w;
    std::memcpy(&w, &n.weight, 4);
    PutU32(&out, w);
    out.insert(out.end(), n.descriptor.begin(), n.descriptor.end());
  }
  PutU64(&out, Fnv1a64(out.data(), out.size()));
  return out;
}

std::optional<Vocabulary> DeserializeVocabulary(const std::uint8_t* data, std::size_t size,
                                                std::string* error) {
  auto fail = [&](const std::string& message) -> std::optional<Vocabulary> {
    if (error) *error = message;
    return std::nullopt;
  };
  if (size < kHeaderBytes + kChecksumBytes) return fail("file too short for a vocabulary header");
  if (std::memcmp(data, kVocabularyMagic, 8) != 0) {
    return fail("not a ccm vocabulary file (bad magic; import DBoW2 text files with ccm_vocab convert)");
  }
  const std::uint32_t version = GetU32(data + 8);
  if (version != kVocabularyVersion) {
    return fail("unsupported vocabulary version " + std::to_string(version) + " (expected " +
                std::to_string(kVocabularyVersion) + ")");
  }
  const std::uint32_t num_nodes = GetU32(data + 28);
  const std::uint64_t expected =
      kHeaderBytes + std::uint64_t{num_nodes} * kNodeBytes + kChecksumBytes;
  if (expected != size) {
    return fail("size mismatch: header says " + std::to_string(num_nodes) + " nodes (" +
                std::to_string(expected) + " bytes), file has " + std::to_string(size) + " bytes");
  }
  if (GetU64(data + size - kChecksumBytes) != Fnv1a64(data, size - kChecksumBytes)) {
    return fail("checksum mismatch: file corrupted");
  }
  if (GetU32(data + 20) != kWeightingTfIdf || GetU32(data + 24) != kScoringL1) {
    return fail("unsupported weighting/scoring (only TF-IDF + L1)");
  }
  std::vector<Vocabulary::Node> nodes(num_nodes);
  const std::uint8_t* p = data + kHeaderBytes;
  std::size_t num_flagged_words = 0;
  for (std::uint32_t i = 0; i < num_nodes; ++i, p += kNodeBytes) {
    nodes[i].parent = GetU32(p);
    num_flagged_words += p[4] ? 1 : 0;
    const std::uint32_t w = GetU32(p + 5);
    std::memcpy(&nodes[i].weight, &w, 4);
    std::memcpy(nodes[i].descriptor.data(), p + 9, 32);
  }
  Vocabulary vocab;
  const std::string problem =
      vocab.Assign(static_cast<int>(GetU32(data + 12)), static_cast<int>(GetU32(data + 16)),
                   std::move(nodes));
  if (!problem.empty()) return fail("invalid vocabulary tree: " + problem);
  if (vocab.num_words() != num_flagged_words) return fail("invalid vocabulary tree: word flags disagree");
  return vocab;
}

std::string SaveVocabularyFile(const Vocabulary& vocabulary, const std::string& path) {
  const std::vector<std::uint8_t> bytes = SerializeVocabulary(vocabulary);
  // A unique temporary name: concurrent writers of the same path never share a file.
  const std::string tmp = path + ".tmp" + std::to_string(std::random_device{}());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) return "cannot open " + tmp + " for writing";
    out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (!out) return "write failed: " + tmp;
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) return "cannot rename " + tmp + " to " + path;
  return {};
}

std::optional<Vocabulary> LoadVocabularyFile(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  if (!in) {
    if (error) *error = path + ": cannot open";
    return std::nullopt;
  }
  const std::streamsize size = in.tellg();
  in.seekg(0);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(std::max<std::streamsize>(size, 0)));
  if (!in.read(reinterpret_cast<char*>(bytes.data()), size)) {
    if (error) *error = path + ": read failed";
    return std::nullopt;
  }
  std::string problem;
  auto vocab = DeserializeVocabulary(bytes.data(), bytes.size(), &problem);
  if (!vocab && error) *error = path + ": " + problem;
  return vocab;
}

std::optional<Vocabulary> ImportDbow2TextVocabulary(std::istream& in, std::string* error) {
  auto fail = [&](const std::string& message) -> std::optional<Vocabulary> {
    if (error) *error = message;
    return std::nullopt;
  };
  int k = 0, levels = 0, scoring = -1, weighting = -1;
  if (!(in >> k >> levels >> scoring >> weighting)) return fail("DBoW2 text: bad header line");
  if (scoring != 0 || weighting != 0) {
    return fail("DBoW2 text: only L1 scoring (0) and TF-IDF weighting (0) are supported");
  }
  std::vector<Vocabulary::Node> nodes(1);
  std::size_t line = 1;
  long long parent = 0;
  int is_leaf = 0;
  while (in >> parent >> is_leaf) {
    ++line;
    Vocabulary::Node n;
    for (auto& byte : n.descriptor) {
      int v = 0;
      if (!(in >> v) || v < 0 || v > 255) return fail("DBoW2 text: bad descriptor on line " + std::to_string(line));
      byte = static_cast<std::uint8_t>(v);
    }
    double weight = 0.0;
    if (!(in >> weight)) return fail("DBoW2 text: bad weight on line " + std::to_string(line));
    if (parent < 0) return fail("DBoW2 text: negative parent on line " + std::to_string(line));
    n.parent = static_cast<NodeId>(parent);
    n.weight = static_cast<float>(weight);
    nodes.push_back(n);
  }
  if (!in.eof()) return fail("DBoW2 text: unreadable line " + std::to_string(line + 1));
  Vocabulary vocab;
  const std::string problem = vocab.Assign(k, levels, std::move(nodes));
  if (!problem.empty()) return fail("DBoW2 text: invalid tree: " + problem);
  return vocab;
}

std::optional<Vocabulary> ImportDbow2TextFile(const std::string& path, std::string* error) {
  std::ifstream in(path);
  if (!in) {
    if (error) *error = path + ": cannot open";
    return std::nullopt;
  }
  std::string problem;
  auto vocab = ImportDbow2TextVocabulary(in, &problem);
  if (!vocab && error) *error = path + ": " + problem;
  return vocab;
}

}  // namespace ccm
