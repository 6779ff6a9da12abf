// Benchmark (not a test): solve times of the optimizers on synthetic maps.
// Usage: bench_optimization [num_threads=2] [--iterative]  (also time ITERATIVE_SCHUR, slow)
#include <chrono>
#include <ctime>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <random>
#include <string>

#include "slam_core/optimization/bundle_adjustment.h"
#include "slam_core/optimization/pose_graph.h"
#include "synthetic_scene.h"

namespace {

using namespace ccm;
using namespace ccm::opt;

// The big map: 400 keyframes on a closed 30 m-radius loop, ~20,000 points. Walls at 3 m give
// ~11 observations per point (dense); at 1.6 m ~6, closer to ORB-SLAM maps after culling.
testing::Scene BigScene(double wall_distance_m, double relief_m, int num_candidate_points) {
  testing::SceneOptions so;
  so.wall_distance_m = wall_distance_m;
  so.relief_m = relief_m;
  so.num_keyframes = 400;
  so.num_points = num_candidate_points;  // those seen by >= 2 keyframes are kept
  so.radius_m = 30.0;
  so.arc_rad = 2.0 * M_PI;
  so.pixel_noise_px = 1.0;
  so.max_pyramid_level = 3;
  so.seed = 99;
  return testing::MakeScene(so);
}

void PrintRow(const char* what, const std::string& size, double value, double cpu, const char* unit,
              const std::string& note) {
  std::printf("| %-18s | %-36s | %9.3f %-2s | %9.3f %-2s | %s\n", what, size.c_str(), value, unit, cpu, unit, note.c_str());
}

// Process CPU seconds (all threads): on a shared, loaded machine wall time alone misleads.
double CpuSeconds() { return static_cast<double>(std::clock()) / CLOCKS_PER_SEC; }

void BenchGlobalBa(const testing::Scene& scene, int threads, BaLinearSolver solver, const char* name) {
  BundleProblem p = scene.problem;
  p.poses[0].fixed = true;
  std::mt19937 rng(1);
  testing::Perturb(&p, 0.5, 0.03, 0.05, &rng);
  const double rmse0 = ReprojectionRmsePx(p);
  BundleAdjusterOptions o = GlobalBaDefaults();
  o.num_threads = threads;
  o.linear_solver = solver;
  const double cpu0 = CpuSeconds();
  const OptimizationSummary s = GlobalBundleAdjustment(&p, o);
  const double cpu = CpuSeconds() - cpu0;
  char size[96], note[160];
  std::snprintf(size, sizeof(size), "%zu KF, %zu pts, %zu obs", p.poses.size(), p.points.size(), p.observations.size());
  std::snprintf(note, sizeof(note), "%s, %d thr, %d it, RMSE %.2f -> %.2f px%s", name, threads, s.iterations, rmse0,
                ReprojectionRmsePx(p), s.usable ? "" : " FAILED");
  PrintRow("global BA", size, s.solve_time_s, cpu, "s", note);
}

// ORB-SLAM's local BA problem: a window of keyframes, all their points, and every other
// keyframe observing those points as fixed periphery.
BundleProblem ExtractWindow(const BundleProblem& full, int first, int count) {
  BundleProblem w;
  w.cameras = full.cameras;
  std::map<int, int> point_map, pose_map;
  for (const Observation& o : full.observations) {
    if (o.pose_index >= first && o.pose_index < first + count && !point_map.count(o.point_index)) {
      point_map[o.point_index] = static_cast<int>(w.points.size());
      w.points.push_back(full.points[o.point_index]);
    }
  }
  for (const Observation& o : full.observations) {
    auto it = point_map.find(o.point_index);
    if (it == point_map.end()) continue;
    if (!pose_map.count(o.pose_index)) {
      pose_map[o.pose_index] = static_cast<int>(w.poses.size());
      PoseBlock pose = full.poses[o.pose_index];
      pose.fixed = o.pose_index < first || o.pose_index >= first + count;
      w.poses.push_back(pose);
    }
    w.observations.push_back(Observation{pose_map[o.pose_index], it->second, o.uv_px, o.sigma_px});
  }
  return w;
}

void BenchLocalBa(const testing::Scene& scene, BaLinearSolver solver, const char* name) {
  const BundleProblem window = ExtractWindow(scene.problem, 200, 20);
  BundleAdjusterOptions o = LocalBaDefaults();
  o.linear_solver = solver;
  const double cpu0 = CpuSeconds();
  const int runs = 5;
  double total = 0;
  int fixed = 0;
  for (const PoseBlock& pose : window.poses) fixed += pose.fixed ? 1 : 0;
  OptimizationSummary s;
  for (int r = 0; r < runs; ++r) {
    BundleProblem p = window;
    std::mt19937 rng(r);
    testing::Perturb(&p, 0.3, 0.02, 0.03, &rng);
    s = LocalBundleAdjustment(&p, o);
    total += s.solve_time_s;
  }
  char size[96], note[160];
  std::snprintf(size, sizeof(size), "20+%d fixed KF, %zu pts, %zu obs", fixed, window.points.size(), window.observations.size());
  const double cpu = CpuSeconds() - cpu0;
  std::snprintf(note, sizeof(note), "%s, 1 thr, 5+10 it max, %d run, cost %.6g, %d inliers, mean of %d", name,
                s.iterations, s.final_cost, s.num_inliers, runs);
  PrintRow("local BA", size, 1000.0 * total / runs, 1000.0 * cpu / runs, "ms", note);
}

void BenchPoseOnly(const testing::Scene& scene) {
  std::vector<PointObservation> obs;
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u01(0, 1), ux(0, 751), uy(0, 479);
  for (const Observation& o : scene.problem.observations) {
    if (o.pose_index != 123) continue;
    Eigen::Vector2d z = o.uv_px;
    if (u01(rng) < 0.2) z = Eigen::Vector2d(ux(rng), uy(rng));
    obs.push_back(PointObservation{scene.gt_points_w[o.point_index], z, o.sigma_px});
  }
  const int runs = 100;
  double total = 0;
  OptimizationSummary s;
  const double cpu0 = CpuSeconds();
  SE3 pose;
  for (int r = 0; r < runs; ++r) {
    pose = SE3(scene.gt_world_from_cam[123].rotation(), scene.gt_world_from_cam[123].translation() + Eigen::Vector3d(0.05, 0.03, -0.04));
    s = OptimizePose(*scene.problem.cameras[0], obs, &pose);
    total += s.solve_time_s;
  }
  char size[96], note[128];
  std::snprintf(size, sizeof(size), "%zu obs, 20%% outliers", obs.size());
  const SE3 err = scene.gt_world_from_cam[123].inverse() * pose;
  std::snprintf(note, sizeof(note), "4 rounds x 10 it, %d it run, %d inliers, error %.3f mm %.4f deg, mean of %d",
                s.iterations, s.num_inliers, 1000.0 * err.translation().norm(),
                Eigen::AngleAxisd(err.rotation()).angle() * 180.0 / M_PI, runs);
  PrintRow("pose-only", size, 1000.0 * total / runs, 1000.0 * (CpuSeconds() - cpu0) / runs, "ms", note);
}

// 1000 keyframes on a drifting loop: spanning tree + 2 covisibility edges per keyframe + loop.
void BenchPoseGraph(int threads) {
  const int n = 1000;
  std::mt19937 rng(5);
  std::normal_distribution<double> nd(0.0, 1.0);
  PoseGraphProblem g;
  std::vector<SE3> drifted;
  double scale = 1.0;
  SE3 pose;
  const Eigen::Quaterniond step_rot(Eigen::AngleAxisd(2.0 * M_PI / n, Eigen::Vector3d::UnitY()));
  const double step_len = 2.0 * M_PI * 50.0 / n;
  for (int i = 0; i < n; ++i) {
    drifted.push_back(pose);
    const Eigen::Vector3d w(0.0005 * nd(rng), 0.002 + 0.0005 * nd(rng), 0.0005 * nd(rng));
    const Eigen::Quaterniond noise(Eigen::AngleAxisd(w.norm(), w.normalized()));
    scale *= 0.999;
    pose = pose * SE3(step_rot * noise, Eigen::Vector3d(0, 0, scale * step_len));
  }
  for (int i = 0; i < n; ++i) g.nodes.push_back(Sim3Node{static_cast<std::uint64_t>(i), Sim3(drifted[i]), i == 0});
  for (int i = 0; i < n; ++i) {
    for (int d = 1; d <= 3 && i + d < n; ++d) {
      g.edges.push_back(Sim3Edge{i, i + d, Sim3(drifted[i].inverse() * drifted[i + d]), 1.0, Sim3EdgeKind::kCovisibility});
    }
  }
  const SE3 rel = SE3(step_rot, Eigen::Vector3d(0, 0, step_len));  // true last -> first motion
  g.edges.push_back(Sim3Edge{n - 1, 0, Sim3(scale, rel.rotation(), scale * rel.translation()), 10.0, Sim3EdgeKind::kLoop});
  PoseGraphOptions o;
  o.num_threads = threads;
  const double cpu0 = CpuSeconds();
  const OptimizationSummary s = OptimizePoseGraph(&g, o);
  const double cpu = CpuSeconds() - cpu0;
  char size[96], note[128];
  std::snprintf(size, sizeof(size), "%d nodes, %zu edges", n, g.edges.size());
  std::snprintf(note, sizeof(note), "%d thr, %d it, cost %.3g -> %.3g%s", threads, s.iterations, s.initial_cost, s.final_cost,
                s.usable ? "" : " FAILED");
  PrintRow("Sim(3) pose graph", size, s.solve_time_s, cpu, "s", note);
}

}  // namespace

int main(int argc, char** argv) {
  const int threads = argc > 1 ? std::max(1, std::atoi(argv[1])) : 2;
  const auto t0 = std::chrono::steady_clock::now();
  const testing::Scene scene = BigScene(3.0, 1.5, 20500);
  const testing::Scene sparse_scene = BigScene(1.6, 0.6, 24700);
  const double gen_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  double load[1] = {0};
  if (getloadavg(load, 1) == 1) std::printf("load average at start: %.2f\n", load[0]);
  std::printf("synthetic map generated in %.2f s (1 px noise at sigma 1.2^level, levels 0-3)\n", gen_s);
  std::printf("| %-18s | %-36s | %12s | %12s | %s\n", "optimizer", "problem", "wall", "cpu (all thr)", "notes");
  BenchGlobalBa(scene, threads, BaLinearSolver::kSparseSchur, "SPARSE_SCHUR");
  BenchGlobalBa(sparse_scene, threads, BaLinearSolver::kSparseSchur, "SPARSE_SCHUR");
  if (argc > 2 && std::string(argv[2]) == "--iterative") {
    BenchGlobalBa(scene, threads, BaLinearSolver::kIterativeSchur, "ITERATIVE_SCHUR");
  }
  BenchLocalBa(scene, BaLinearSolver::kAuto, "own dense Schur LM");
  BenchLocalBa(scene, BaLinearSolver::kDenseSchur, "DENSE_SCHUR");
  BenchLocalBa(scene, BaLinearSolver::kSparseSchur, "SPARSE_SCHUR");
  BenchPoseOnly(scene);
  BenchPoseGraph(threads);
  return 0;
}
