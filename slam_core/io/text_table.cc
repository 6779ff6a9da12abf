#include "slam_core/io/text_table.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>

#include "slam_core/io/trajectory.h"

namespace ccm {

int64_t SecondsToNs(double stamp_s) { return static_cast<int64_t>(std::llround(stamp_s * 1e9)); }

namespace io_internal {
namespace {

std::vector<std::string> SplitFields(const std::string& text) {
  std::vector<std::string> fields;
  std::string current;
  bool after_comma = false;
  for (char c : text) {
    const bool space = c == ' ' || c == '\t' || c == '\r';
    if (c == ',' || space) {
      if (!current.empty()) fields.push_back(current);
      else if (c == ',' && after_comma) fields.emplace_back();  // "a,,b": keep the empty field
      current.clear();
      if (c == ',') after_comma = true;
      continue;
    }
    after_comma = false;
    current.push_back(c);
  }
  if (!current.empty()) fields.push_back(current);
  return fields;
}

}  // namespace

IoStatus ReadTable(const std::string& path, std::vector<TextLine>* lines) {
  lines->clear();
  std::ifstream in(path);
  if (!in) return IoStatus::Error("cannot open " + path);
  std::string text;
  int number = 0;
  while (std::getline(in, text)) {
    ++number;
    const size_t first = text.find_first_not_of(" \t\r");
    if (first == std::string::npos || text[first] == '#') continue;
    lines->push_back(TextLine{number, SplitFields(text)});
  }
  if (in.bad()) return IoStatus::Error("error while reading " + path);
  return IoStatus::Ok();
}

std::string Where(const std::string& path, int line) { return path + ":" + std::to_string(line); }

bool ParseDouble(const std::string& field, double* value) {
  if (field.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(field.c_str(), &end);
  if (end != field.c_str() + field.size() || errno == ERANGE || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

bool ParseInt64(const std::string& field, int64_t* value) {
  if (field.empty()) return false;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(field.c_str(), &end, 10);
  if (end != field.c_str() + field.size() || errno == ERANGE) return false;
  *value = static_cast<int64_t>(v);
  return true;
}

bool ParseSecondsToNs(const std::string& field, int64_t* stamp_ns) {
  if (field.find_first_not_of("0123456789.+-eE") != std::string::npos) return false;
  double as_double = 0.0;
  if (!ParseDouble(field, &as_double)) return false;
  if (std::fabs(as_double) > 9.0e9) return false;  // would overflow int64 nanoseconds
  const bool plain = field.find_first_of("eE") == std::string::npos;
  if (!plain) {
    *stamp_ns = SecondsToNs(as_double);
    return true;
  }
  // Digit by digit: integer seconds and up to 9 fractional digits (rounded on the 10th).
  const bool negative = field[0] == '-';
  const size_t start = (field[0] == '-' || field[0] == '+') ? 1 : 0;
  const size_t dot = field.find('.');
  const std::string int_part = field.substr(start, dot == std::string::npos ? std::string::npos
                                                                             : dot - start);
  std::string frac = dot == std::string::npos ? "" : field.substr(dot + 1);
  int64_t seconds = 0;
  for (char c : int_part) seconds = seconds * 10 + (c - '0');
  int64_t nanos = 0;
  for (size_t i = 0; i < 9; ++i) nanos = nanos * 10 + (i < frac.size() ? frac[i] - '0' : 0);
  if (frac.size() > 9 && frac[9] >= '5') ++nanos;
  const int64_t total = seconds * 1000000000LL + nanos;
  *stamp_ns = negative ? -total : total;
  return true;
}

IoStatus ParseDoubles(const std::string& path, const TextLine& line, size_t first, size_t count,
                      double* out) {
  for (size_t i = 0; i < count; ++i) {
    const size_t k = first + i;
    if (k >= line.fields.size() || !ParseDouble(line.fields[k], &out[i])) {
      return IoStatus::Error(Where(path, line.number) + ": field " + std::to_string(k + 1) +
                             " is not a number: '" +
                             (k < line.fields.size() ? line.fields[k] : std::string()) + "'");
    }
  }
  return IoStatus::Ok();
}

}  // namespace io_internal
}  // namespace ccm
