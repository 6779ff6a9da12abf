// Helpers for io tests: a scratch folder per test and small file writers.
#pragma once

#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <unistd.h>

#include <gtest/gtest.h>

#include "slam_core/io/trajectory.h"

namespace ccm::test {

/// Creates an empty folder unique to the running test; removed in the destructor.
class ScratchDir {
 public:
  ScratchDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            ("ccm_io_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
             std::to_string(::getpid()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~ScratchDir() { std::filesystem::remove_all(path_); }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  std::string str() const { return path_.string(); }

 private:
  std::filesystem::path path_;
};

inline void WriteText(const std::string& path, const std::string& text) {
  std::filesystem::create_directories(std::filesystem::path(path).parent_path());
  std::ofstream(path) << text;
}

/// Random smooth-ish trajectory with stamps from start_ns every step_ns.
inline Trajectory RandomTrajectory(int n, uint32_t seed, int64_t start_ns = 1403636579758555392,
                                   int64_t step_ns = 50000000) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(Eigen::Vector4d(g(rng), g(rng), g(rng), g(rng))).normalized();
    t.push_back(StampedPose{start_ns + i * step_ns,
                            SE3(q, Eigen::Vector3d(g(rng), g(rng), g(rng)) * 3.0)});
  }
  return t;
}

}  // namespace ccm::test
