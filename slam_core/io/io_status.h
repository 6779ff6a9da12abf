// Result of an I/O operation: ok, or a human-readable message that names the file (and line
// where one is at fault). slam_core never prints, so readers return this and the caller decides
// how to report it.
#pragma once

#include <string>
#include <utility>

namespace ccm {

class IoStatus {
 public:
  IoStatus() = default;
  static IoStatus Ok() { return IoStatus(); }
  static IoStatus Error(std::string message) {
    IoStatus s;
    s.ok_ = false;
    s.message_ = std::move(message);
    return s;
  }

  bool ok() const { return ok_; }
  /// Empty when ok().
  const std::string& message() const { return message_; }

 private:
  bool ok_ = true;
  std::string message_;
};

}  // namespace ccm
