// Prometheus' text exposition format (version 0.0.4), written by ccm_server's GET /metrics
// and ccm_agent's --metrics endpoint. Samples are grouped per family, each family preceded by
// one HELP and one TYPE line, as the format requires; label values are escaped.
// No DDS and no JSON here: the callers turn their own status into samples.
#pragma once

#include <map>
#include <string>
#include <utility>
#include <vector>

namespace ccm::rt {

/// Content type of the exposition format.
inline constexpr const char* kPrometheusContentType = "text/plain; version=0.0.4; charset=utf-8";

class PrometheusText {
 public:
  using Labels = std::vector<std::pair<std::string, std::string>>;
  /// `type`: "gauge" or "counter" (counters' names end in _total). A family's HELP and TYPE
  /// are taken from its first sample.
  void Add(const std::string& name, const char* type, const char* help, const Labels& labels, double value);
  std::string Text() const;

 private:
  struct Family {
    std::string type, help;
    std::vector<std::string> samples;
  };
  std::map<std::string, Family> families_;
  std::vector<std::string> order_;  // first-seen order of the families
};

}  // namespace ccm::rt
