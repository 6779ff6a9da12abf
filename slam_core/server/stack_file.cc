#include "slam_core/server/stack_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>

#include "slam_core/common/checksum.h"

namespace ccm {
namespace {

constexpr size_t kHeader = sizeof(kMapStackMagic) + sizeof(uint32_t) + sizeof(uint64_t);

std::string Errno() { return std::strerror(errno); }

bool WriteAll(int fd, const char* data, size_t size) {
  while (size > 0) {
    const ssize_t n = ::write(fd, data, size);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return false;
    data += n;
    size -= static_cast<size_t>(n);
  }
  return true;
}

// Makes a rename in `folder` durable.
bool SyncFolder(const std::string& folder, std::string* error) {
  const int fd = ::open(folder.empty() ? "." : folder.c_str(), O_RDONLY | O_DIRECTORY);
  if (fd < 0 || ::fsync(fd) != 0) {
    *error = "cannot sync folder " + folder + ": " + Errno();
    if (fd >= 0) ::close(fd);
    return false;
  }
  ::close(fd);
  return true;
}

}  // namespace

std::string PreviousGeneration(const std::string& path) { return path + ".prev"; }

bool WriteStackFile(const std::string& path, const std::string& payload, std::string* error) {
  std::string envelope(kMapStackMagic, sizeof(kMapStackMagic));
  const uint32_t version = kMapStackVersion;
  const uint64_t size = payload.size();
  const uint64_t checksum = Fnv1a64(reinterpret_cast<const uint8_t*>(payload.data()), payload.size());
  envelope.append(reinterpret_cast<const char*>(&version), sizeof(version));
  envelope.append(reinterpret_cast<const char*>(&size), sizeof(size));
  const std::string tmp = path + ".tmp";
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    *error = "cannot write " + tmp + ": " + Errno();
    return false;
  }
  const bool written = WriteAll(fd, envelope.data(), envelope.size()) && WriteAll(fd, payload.data(), payload.size()) &&
                       WriteAll(fd, reinterpret_cast<const char*>(&checksum), sizeof(checksum)) && ::fsync(fd) == 0;
  const std::string write_error = Errno();
  ::close(fd);
  if (!written) {
    *error = "cannot write " + tmp + ": " + write_error;
    std::remove(tmp.c_str());
    return false;
  }
  // Keep the current file as the previous generation: a hard link renamed over path.prev,
  // so `path` itself never goes missing.
  std::error_code ec;
  if (std::filesystem::exists(path, ec)) {
    const std::string prev = PreviousGeneration(path), prev_tmp = prev + ".tmp";
    std::filesystem::remove(prev_tmp, ec);
    std::filesystem::create_hard_link(path, prev_tmp, ec);
    if (ec) {  // a file system without hard links: a copy does the same, slower
      ec.clear();
      std::filesystem::copy_file(path, prev_tmp, std::filesystem::copy_options::overwrite_existing, ec);
    }
    if (ec || std::rename(prev_tmp.c_str(), prev.c_str()) != 0) {
      *error = "cannot keep the previous generation as " + prev + ": " + (ec ? ec.message() : Errno());
      return false;
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    *error = "cannot rename " + tmp + " to " + path + ": " + Errno();
    return false;
  }
  return SyncFolder(std::filesystem::path(path).parent_path().string(), error);
}

std::optional<std::string> ReadStackFile(const std::string& path, std::string* error) {
  std::ifstream in(path, std::ios::binary);
  if (!in) {
    *error = path + ": cannot open";
    return std::nullopt;
  }
  const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (data.size() < kHeader + sizeof(uint64_t) || std::memcmp(data.data(), kMapStackMagic, sizeof(kMapStackMagic)) != 0) {
    *error = path + ": not a ccm map stack file";
    return std::nullopt;
  }
  uint32_t version = 0;
  uint64_t size = 0, checksum = 0;
  std::memcpy(&version, data.data() + 8, 4);
  std::memcpy(&size, data.data() + 12, 8);
  if (version != kMapStackVersion) {
    *error = path + ": format version " + std::to_string(version) + ", this build reads " + std::to_string(kMapStackVersion);
    return std::nullopt;
  }
  if (size != data.size() - kHeader - sizeof(uint64_t)) {
    *error = path + ": size mismatch (truncated or padded file)";
    return std::nullopt;
  }
  std::memcpy(&checksum, data.data() + kHeader + size, 8);
  if (Fnv1a64(reinterpret_cast<const uint8_t*>(data.data() + kHeader), size) != checksum) {
    *error = path + ": checksum mismatch: file corrupted";
    return std::nullopt;
  }
  return data.substr(kHeader, size);
}

}  // namespace ccm
