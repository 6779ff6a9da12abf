// Strict YAML reading for the runtimes' config files: every key must be known, every value
// must have the right type, and errors name the file, the key and what was expected.
// Algorithms never see YAML: the runtimes fill their components' Options structs from it.
#pragma once

#include <yaml-cpp/yaml.h>

#include <optional>
#include <set>
#include <string>

namespace ccm::rt {

/// Reads one YAML mapping and records the first error. Usage:
///   YamlReader r(node, "agent.yaml");
///   r.Get("agent_id", &opts.agent_id); ...; r.RejectUnknownKeys();
///   if (!r.ok()) fail(r.error());
class YamlReader {
 public:
  YamlReader(YAML::Node node, std::string context);

  /// Loads `path`; on failure returns std::nullopt and fills *error (missing file, syntax
  /// error with line/column, top level not a mapping).
  static std::optional<YAML::Node> LoadFile(const std::string& path, std::string* error);

  template <typename T>
  void Get(const std::string& key, T* value) {
    seen_.insert(key);
    if (!error_.empty() || !node_[key]) return;
    try {
      *value = node_[key].as<T>();
    } catch (const YAML::Exception&) {
      Fail(key, "has the wrong type (expected " + TypeName(*value) + ")");
    }
  }
  /// A nested mapping, for a sub-reader; empty node if absent.
  YAML::Node Child(const std::string& key);
  /// Records an error if the mapping has keys nobody asked for (typos must not pass).
  void RejectUnknownKeys();
  void Fail(const std::string& key, const std::string& what);

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }

 private:
  static std::string TypeName(const std::string&) { return "a string"; }
  static std::string TypeName(bool) { return "true/false"; }
  static std::string TypeName(double) { return "a number"; }
  static std::string TypeName(int) { return "an integer"; }
  static std::string TypeName(unsigned) { return "a non-negative integer"; }

  YAML::Node node_;
  std::string context_;
  std::set<std::string> seen_;
  std::string error_;
};

}  // namespace ccm::rt
