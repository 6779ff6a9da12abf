// Runs the ccm_eval binary on generated trajectory files and checks its JSON output and exit
// codes.
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include "slam_core/geometry/sim3.h"
#include "slam_core/io/trajectory_io.h"

namespace ccm {
namespace {

namespace fs = std::filesystem;

class CcmEvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("ccm_eval_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) +
            "_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string Path(const std::string& name) const { return (dir_ / name).string(); }

  // Runs ccm_eval with arguments; returns the exit code, stderr in *err.
  int Run(const std::string& args, std::string* err = nullptr) const {
    const std::string cmd = std::string(CCM_EVAL_BIN) + " " + args + " > " + Path("stdout.txt") +
                            " 2> " + Path("stderr.txt");
    const int status = std::system(cmd.c_str());
    if (err) {
      std::ifstream in(Path("stderr.txt"));
      err->assign(std::istreambuf_iterator<char>(in), {});
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }

  nlohmann::json ReadJson(const std::string& name) const {
    std::ifstream in(Path(name));
    return nlohmann::json::parse(in);
  }

  fs::path dir_;
};

Trajectory Circle(int n, double radius, double phase) {
  Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double a = phase + 2.0 * M_PI * i / n;
    t.push_back({1000000000LL + i * 100000000LL,
                 SE3(Eigen::Quaterniond(Eigen::AngleAxisd(a, Eigen::Vector3d::UnitZ())),
                     Eigen::Vector3d(radius * std::cos(a), radius * std::sin(a), 0.2 * std::sin(2 * a)))});
  }
  return t;
}

Trajectory ToMap(const Trajectory& gt, const Sim3& map_from_world, double noise_m, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, noise_m);
  Trajectory est = gt;
  for (StampedPose& p : est) {
    const SE3 noisy(p.world_from_cam.rotation(),
                    p.world_from_cam.translation() + Eigen::Vector3d(g(rng), g(rng), g(rng)));
    p.world_from_cam = map_from_world.TransformPose(noisy);
    p.stamp_ns += 2000000;  // estimator stamps 2 ms late: within --max-dt
  }
  return est;
}

TEST_F(CcmEvalCli, TwoAgentsJointJsonAndPlot) {
  const Sim3 map_from_world(2.5, Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitY())),
                            Eigen::Vector3d(1, -2, 3));
  const Trajectory gt_a = Circle(200, 5.0, 0.0), gt_b = Circle(150, 3.0, 1.0);
  ASSERT_TRUE(WriteEurocTrajectory(Path("gt_a.csv"), gt_a).ok());
  ASSERT_TRUE(WriteTumTrajectory(Path("gt_b.txt"), gt_b).ok());
  ASSERT_TRUE(WriteTumTrajectory(Path("est_a.txt"), ToMap(gt_a, map_from_world, 0.0, 1)).ok());
  ASSERT_TRUE(WriteEurocTrajectory(Path("est_b.csv"), ToMap(gt_b, map_from_world, 0.0, 2)).ok());
  const std::string args = "--gt " + Path("gt_a.csv") + " --est " + Path("est_a.txt") + " --gt " +
                           Path("gt_b.txt") + " --est " + Path("est_b.csv") +
                           " --name a --name b --json " + Path("out.json") + " --plot " + Path("plot.png");
  std::string err;
  ASSERT_EQ(Run(args, &err), 0) << err;
  const nlohmann::json j = ReadJson("out.json");
  ASSERT_EQ(j["agents"].size(), 2u);
  EXPECT_EQ(j["agents"][0]["name"], "a");
  EXPECT_EQ(j["agents"][0]["matched"], 200);
  EXPECT_EQ(j["agents"][1]["matched"], 150);
  EXPECT_EQ(j["joint"]["matched"], 350);
  EXPECT_LT(j["joint"]["ate_m"]["rmse"].get<double>(), 1e-6);
  EXPECT_NEAR(j["joint"]["alignment"]["scale"].get<double>(), 1.0 / 2.5, 1e-9);
  EXPECT_EQ(j["options"]["align"], "sim3");
  EXPECT_TRUE(fs::file_size(Path("plot.png")) > 1000);
}

TEST_F(CcmEvalCli, NoisyEstimateSe3AndRpeOptions) {
  const Trajectory gt = Circle(300, 4.0, 0.0);
  const Sim3 rigid(1.0, Eigen::Quaterniond(Eigen::AngleAxisd(-1.0, Eigen::Vector3d::UnitZ())),
                   Eigen::Vector3d(3, 0, 1));
  ASSERT_TRUE(WriteTumTrajectory(Path("gt.txt"), gt).ok());
  ASSERT_TRUE(WriteTumTrajectory(Path("est.txt"), ToMap(gt, rigid, 0.02, 3)).ok());
  ASSERT_EQ(Run("--gt " + Path("gt.txt") + " --est " + Path("est.txt") +
                " --align se3 --rpe-delta 10 --json " + Path("out.json")), 0);
  const nlohmann::json j = ReadJson("out.json");
  const double rmse = j["agents"][0]["ate_m"]["rmse"].get<double>();
  EXPECT_NEAR(rmse, 0.02 * std::sqrt(3.0), 0.2 * 0.02 * std::sqrt(3.0));
  EXPECT_EQ(j["agents"][0]["rpe_translation_m"]["count"], 29);  // (0,10) ... (280,290)
  EXPECT_DOUBLE_EQ(j["agents"][0]["alignment"]["scale"].get<double>(), 1.0);
}

TEST_F(CcmEvalCli, KittiPosesAssociateByIndex) {
  const Trajectory gt = Circle(50, 10.0, 0.0);
  ASSERT_TRUE(WriteKittiPoses(Path("gt.txt"), gt).ok());
  ASSERT_TRUE(WriteKittiPoses(Path("est.txt"), ToMap(gt, Sim3(0.5, Eigen::Quaterniond::Identity(),
                                                                   Eigen::Vector3d::Zero()), 0.0, 4)).ok());
  ASSERT_EQ(Run("--format kitti --gt " + Path("gt.txt") + " --est " + Path("est.txt") + " --json " +
                Path("out.json")), 0);
  const nlohmann::json j = ReadJson("out.json");
  EXPECT_EQ(j["agents"][0]["matched"], 50);
  EXPECT_LT(j["agents"][0]["ate_m"]["max"].get<double>(), 1e-6);
}

TEST_F(CcmEvalCli, BadInputFailsWithMessage) {
  std::string err;
  EXPECT_NE(Run("--gt " + Path("missing.txt") + " --est " + Path("missing.txt"), &err), 0);
  EXPECT_NE(err.find("no such file"), std::string::npos) << err;

  std::ofstream(Path("bad.txt")) << "0.0 0 0 0 0 0 0 1\n0.1 0 0 zero 0 0 0 1\n";
  EXPECT_EQ(Run("--gt " + Path("bad.txt") + " --est " + Path("bad.txt"), &err), 1);
  EXPECT_NE(err.find("bad.txt:2: field 4 is not a number"), std::string::npos) << err;

  ASSERT_TRUE(WriteTumTrajectory(Path("gt.txt"), Circle(20, 1.0, 0.0)).ok());
  EXPECT_NE(Run("--gt " + Path("gt.txt") + " --est " + Path("gt.txt") + " --gt " + Path("gt.txt"), &err), 0);
  EXPECT_NE(err.find("one --est per --gt"), std::string::npos) << err;
  EXPECT_NE(Run("--gt " + Path("gt.txt") + " --est " + Path("gt.txt") + " --align affine", &err), 0);
  EXPECT_NE(Run("--gt " + Path("gt.txt"), &err), 0);  // --est is required
}

}  // namespace
}  // namespace ccm
