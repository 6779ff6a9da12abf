#include "runtime_common/yaml_config.h"

#include <fstream>

namespace ccm::rt {

YamlReader::YamlReader(YAML::Node node, std::string context) : node_(std::move(node)), context_(std::move(context)) {
  if (node_ && !node_.IsNull() && !node_.IsMap()) error_ = context_ + ": expected a mapping of key: value";
}

std::optional<YAML::Node> YamlReader::LoadFile(const std::string& path, std::string* error) {
  if (!std::ifstream(path).good()) {
    *error = "config file '" + path + "' does not exist or cannot be read";
    return std::nullopt;
  }
  try {
    YAML::Node node = YAML::LoadFile(path);
    if (!node.IsMap() && !node.IsNull()) {
      *error = path + ": the top level must be a mapping of key: value";
      return std::nullopt;
    }
    return node;
  } catch (const YAML::ParserException& e) {
    *error = path + ": YAML syntax error at line " + std::to_string(e.mark.line + 1) + ", column " +
             std::to_string(e.mark.column + 1) + ": " + e.msg;
    return std::nullopt;
  }
}

YAML::Node YamlReader::Child(const std::string& key) {
  seen_.insert(key);
  return node_[key];
}

void YamlReader::RejectUnknownKeys() {
  if (!error_.empty() || !node_ || !node_.IsMap()) return;
  for (const auto& item : node_) {
    const std::string key = item.first.as<std::string>();
    if (seen_.count(key) == 0) {
      std::string known;
      for (const auto& k : seen_) known += (known.empty() ? "" : ", ") + k;
      Fail(key, "is not a known key (known: " + known + ")");
      return;
    }
  }
}

void YamlReader::Fail(const std::string& key, const std::string& what) {
  if (error_.empty()) error_ = context_ + ": key '" + key + "' " + what;
}

}  // namespace ccm::rt
