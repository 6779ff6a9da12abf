#include "tools/replay/dataset_spec.h"

#include <filesystem>
#include <set>

namespace ccm::replay {

std::optional<DatasetSpec> ParseDatasetSpec(const std::string& text, std::string* error) {
  DatasetSpec spec;
  spec.path = text;
  const size_t at = text.rfind('@');
  if (at != std::string::npos && text.find_first_not_of("0123456789-", at + 1) == std::string::npos) {
    IoStatus status;
    spec.range = ParseFrameRange(text.substr(at + 1), &status);
    if (!spec.range) {
      *error = "--dataset " + text + ": " + status.message();
      return std::nullopt;
    }
    spec.path = text.substr(0, at);
  }
  if (spec.path.empty()) {
    *error = "--dataset " + text + ": no folder given";
    return std::nullopt;
  }
  // "a/b/" names the agent "b", as "a/b" does.
  std::filesystem::path p(spec.path);
  spec.name = (p.has_filename() ? p : p.parent_path()).filename().string();
  if (spec.range) {
    spec.name += "_" + std::to_string(spec.range->first) + "-" +
                 (spec.range->last >= 0 ? std::to_string(spec.range->last) : std::string("end"));
  }
  return spec;
}

void MakeNamesUnique(std::vector<std::string>* names) {
  std::set<std::string> taken(names->begin(), names->end());
  std::set<std::string> seen;
  for (std::string& n : *names) {
    if (seen.insert(n).second) continue;
    for (int k = 2;; ++k) {
      const std::string candidate = n + "_" + std::to_string(k);
      if (!taken.count(candidate)) {
        n = candidate;
        taken.insert(n);
        seen.insert(n);
        break;
      }
    }
  }
}

}  // namespace ccm::replay
