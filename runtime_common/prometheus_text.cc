#include "runtime_common/prometheus_text.h"

#include <cmath>
#include <sstream>

namespace ccm::rt {
namespace {

// Label values escape backslash, double quote and newline (the format's only escapes).
std::string Escape(const std::string& v) {
  std::string out;
  for (const char c : v) {
    if (c == '\n') {
      out += "\\n";
      continue;
    }
    if (c == '\\' || c == '"') out += '\\';
    out += c;
  }
  return out;
}

std::string Number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  std::ostringstream s;
  s.precision(15);
  s << v;
  return s.str();
}

}  // namespace

void PrometheusText::Add(const std::string& name, const char* type, const char* help, const Labels& labels,
                         double value) {
  Family& f = families_[name];
  if (f.type.empty()) {
    f.type = type;
    f.help = help;
    order_.push_back(name);
  }
  std::string line = name;
  if (!labels.empty()) {
    line += '{';
    for (size_t i = 0; i < labels.size(); ++i) {
      line += (i ? "," : "") + labels[i].first + "=\"" + Escape(labels[i].second) + '"';
    }
    line += '}';
  }
  f.samples.push_back(line + ' ' + Number(value));
}

std::string PrometheusText::Text() const {
  std::string out;
  for (const std::string& name : order_) {
    const Family& f = families_.at(name);
    out += "# HELP " + name + ' ' + f.help + "\n# TYPE " + name + ' ' + f.type + '\n';
    for (const std::string& s : f.samples) out += s + '\n';
  }
  return out;
}

}  // namespace ccm::rt
