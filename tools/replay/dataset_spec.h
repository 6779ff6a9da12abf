// One --dataset argument of ccm_replay: a dataset folder, optionally with a frame range
// ("DIR@60-159": frames 60..159 of DIR), so that two slices of one recorded sequence can be
// two agents (two cars on the same road), and the agent name the outputs use.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "slam_core/io/frame_range_source.h"

namespace ccm::replay {

struct DatasetSpec {
  std::string path;
  std::optional<FrameRange> range;  ///< none: every frame
  std::string name;                 ///< folder name, plus "_FIRST-LAST" with a range
};

/// "DIR" or "DIR@FIRST-LAST" / "DIR@FIRST-". The text after the last '@' is a range only if
/// it consists of digits and '-' (so a folder named "run@home" stays a path); a malformed
/// range ("DIR@60", "DIR@9-3") is an error, not a path.
std::optional<DatasetSpec> ParseDatasetSpec(const std::string& text, std::string* error);

/// Makes agent names unique (outputs are named after them): the second "x" becomes "x_2".
void MakeNamesUnique(std::vector<std::string>* names);

}  // namespace ccm::replay
