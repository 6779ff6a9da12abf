// Presentation of a ccm::EvalReport for the ccm_eval tool: the human-readable table and the
// JSON document (schema in docs/evaluation.md).
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "slam_core/eval/evaluator.h"

namespace ccm::tools {

struct InputFiles {
  std::string gt_path;
  std::string est_path;
};

std::string FormatTable(const EvalReport& report, const EvalOptions& options);

nlohmann::json ToJson(const EvalReport& report, const EvalOptions& options,
                      const std::vector<InputFiles>& files);

}  // namespace ccm::tools
