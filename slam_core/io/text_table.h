// Internal helpers of ccm_io: reads whitespace/comma separated text tables with line numbers,
// and parses numbers strictly, so every reader can report "file:line: what is wrong".
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "slam_core/io/io_status.h"

namespace ccm {
namespace io_internal {

struct TextLine {
  int number = 0;                   ///< 1-based line number in the file
  std::vector<std::string> fields;  ///< split on commas and whitespace
};

/// Reads all data lines of a text file: skips blank lines and lines starting with '#'.
/// Fields are separated by commas and/or whitespace; a trailing '\r' is ignored.
IoStatus ReadTable(const std::string& path, std::vector<TextLine>* lines);

/// "path:line".
std::string Where(const std::string& path, int line);

/// Strict parsers: the whole field must be consumed and the value finite.
bool ParseDouble(const std::string& field, double* value);
bool ParseInt64(const std::string& field, int64_t* value);
/// Seconds in decimal notation ("1305031102.175304", "1.038752e-01") to nanoseconds. Plain
/// decimals are converted digit by digit, so 10-digit epoch seconds keep ns precision.
bool ParseSecondsToNs(const std::string& field, int64_t* stamp_ns);

/// Parses fields[first, first + count) as doubles; on failure returns an error naming the field.
IoStatus ParseDoubles(const std::string& path, const TextLine& line, size_t first, size_t count,
                      double* out);

}  // namespace io_internal
}  // namespace ccm
