// bench_solvers: milliseconds per call of each geometric solver at typical sizes
// (500 correspondences, 40 % outliers, 0.7 px noise, EuRoC-like camera). Not a test.
#include <chrono>
#include <ctime>
#include <cstdio>
#include <functional>

#include "slam_core/solvers/absolute_pose.h"
#include "slam_core/solvers/homography.h"
#include "slam_core/solvers/relative_pose.h"
#include "slam_core/solvers/similarity.h"
#include "slam_core/solvers/triangulation.h"
#include "slam_core/solvers/two_view_init.h"
#include "tests/slam_core/solvers/synthetic_scene.h"

namespace {

using namespace ccm;
using namespace ccm::solvers;

// Runs `fn` `reps` times with varying seeds; prints mean wall time and mean process CPU
// time (the CPU figure is the one to trust on a loaded machine; all solvers are
// single-threaded).
void Time(const char* name, int reps, const std::function<void(int)>& fn) {
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  for (int k = 0; k < reps; ++k) fn(k);
  const double cpu_ms = 1000.0 * double(std::clock() - c0) / CLOCKS_PER_SEC / reps;
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / reps;
  std::printf("%-44s %9.3f ms/call wall %9.3f ms/call cpu\n", name, ms, cpu_ms);
}

}  // namespace

int main() {
  constexpr int kN = 500;
  constexpr double kOutliers = 0.4, kNoise = 0.7;
  test::SceneGenerator gen(7);
  const double f = gen.camera().intrinsics().fx;
  const SE3 world_from_cam2 = test::MakePose(3, -8, 2, Eigen::Vector3d(0.6, 0.1, 0.15));
  const test::TwoViewData general = gen.MakeTwoView(world_from_cam2, kN, kNoise, kOutliers);
  const test::TwoViewData planar = gen.MakeTwoView(world_from_cam2, kN, kNoise, kOutliers, true);
  std::printf("bench_solvers: %d correspondences, %.0f %% outliers, %.1f px noise, f = %.0f px\n", kN,
              100 * kOutliers, kNoise, f);

  for (auto [alg, name] : {std::pair{RelativePoseAlgorithm::kStewenius5pt, "relative pose 5pt Stewenius + refine"},
                           std::pair{RelativePoseAlgorithm::kNister5pt, "relative pose 5pt Nister + refine"},
                           std::pair{RelativePoseAlgorithm::kEightPoint, "relative pose 8pt + refine"}}) {
    RelativePoseOptions o;
    o.algorithm = alg;
    o.ransac.focal_px = f;
    Time(name, 20, [&](int k) {
      o.ransac.seed = k;
      EstimateRelativePose(general.bearings1, general.bearings2, o);
    });
  }
  {
    RelativePoseOptions o;
    o.ransac.focal_px = f;
    o.refine = false;
    Time("relative pose 5pt Stewenius, no refinement", 20, [&](int k) {
      o.ransac.seed = k;
      EstimateRelativePose(general.bearings1, general.bearings2, o);
    });
  }
  HomographyOptions ho;
  ho.ransac.focal_px = f;
  ho.ransac.threshold_px = 2.45;
  Time("homography 4pt DLT RANSAC (planar)", 20, [&](int k) {
    ho.ransac.seed = k;
    EstimateHomography(planar.bearings1, planar.bearings2, ho);
  });
  TwoViewInitOptions io;
  io.focal_px = f;
  Time("two-view init E+H, general scene", 10, [&](int k) {
    io.seed = k;
    InitializeTwoView(general.bearings1, general.bearings2, io);
  });
  Time("two-view init E+H, planar scene", 10, [&](int k) {
    io.seed = k;
    InitializeTwoView(planar.bearings1, planar.bearings2, io);
  });

  // Absolute pose: bearings of cam2 against the ground-truth world points.
  AbsolutePoseOptions ao;
  ao.ransac.focal_px = f;
  for (auto [alg, name] : {std::pair{AbsolutePoseAlgorithm::kKneipP3P, "absolute pose P3P Kneip + refine"},
                           std::pair{AbsolutePoseAlgorithm::kGaoP3P, "absolute pose P3P Gao + refine"}}) {
    ao.algorithm = alg;
    Time(name, 50, [&](int k) {
      ao.ransac.seed = k;
      EstimateAbsolutePose(general.bearings2, general.points_world, ao);
    });
  }

  // Sim(3): cam1 points against the same points scaled/moved, outliers as in the 2D data.
  const Sim3 b_from_a(2.0, Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())), Eigen::Vector3d(0.5, 0, 1));
  std::vector<Eigen::Vector3d> pa = general.points_world, pb;
  for (size_t i = 0; i < pa.size(); ++i) pb.push_back(b_from_a * (general.is_outlier[i] ? pa[(i * 7919) % pa.size()] : pa[i]));
  Sim3Options so;
  so.ransac.focal_px = f;
  Time("sim3 Umeyama RANSAC (angular test)", 50, [&](int k) {
    so.ransac.seed = k;
    EstimateSim3(pa, pb, so);
  });

  TriangulationOptions to;
  to.focal_px = f;
  const SE3 cam2_from_cam1 = world_from_cam2.inverse();
  Time("triangulate two-view x500", 20, [&](int) {
    for (int i = 0; i < kN; ++i) TriangulateTwoView(general.bearings1[i], general.bearings2[i], cam2_from_cam1, to);
  });
  return 0;
}
