// bench_sim: simulator numbers (not a test). Prints
//  - world build time, render fps at 752x480 on this thread (sharp and motion-blurred),
//  - ORB (1000 requested) keypoint statistics over one agent of a scenario,
//  - consecutive-frame ORB matching: ratio-test matches and essential-matrix RANSAC inliers.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <numeric>

#include <CLI/CLI.hpp>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>

#include "tests/sim/simulation.h"

namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// CPU time of this thread: on a shared machine wall-clock fps understates one core's speed.
double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

// Undistorted normalized coordinates of keypoints, for the essential matrix.
std::vector<cv::Point2f> Normalized(const ccm::CameraModel& cam, const std::vector<cv::Point2f>& pts) {
  std::vector<cv::Point2f> out;
  for (const auto& p : pts) {
    Eigen::Vector2d xy(0, 0);
    cam.UnprojectToNormalized(Eigen::Vector2d(p.x, p.y), &xy);
    out.emplace_back(static_cast<float>(xy.x()), static_cast<float>(xy.y()));
  }
  return out;
}

void ReportRenderSpeed(const ccm::sim::Simulation& sim, int agent, int render_frames) {
  const std::int64_t n_frames = sim.NumFrames(agent);
  const auto t0 = std::chrono::steady_clock::now();
  const double cpu0 = ThreadCpuSeconds();
  for (int i = 0; i < render_frames; ++i) sim.RenderFrame(agent, (i * 7) % n_frames);
  const double fps = render_frames / Seconds(t0);
  const double cpu_fps = render_frames / (ThreadCpuSeconds() - cpu0);
  std::printf("render %dx%d, 1 thread: %.1f frames/s per CPU second (%.2f ms CPU/frame), %.1f frames/s wall clock "
              "(target 30)\n",
              sim.renderer().camera().width(), sim.renderer().camera().height(), cpu_fps, 1000.0 / cpu_fps, fps);
  ccm::sim::Scenario blurred = sim.scenario();
  blurred.render.motion_blur_samples = 4;
  std::string error;
  auto sim_blur = ccm::sim::Simulation::Create(blurred, &error, sim.world());
  const double c0 = ThreadCpuSeconds();
  for (int i = 0; i < 20; ++i) sim_blur->RenderFrame(agent, (i * 7) % n_frames);
  std::printf("render with 4-sample motion blur: %.1f frames/s per CPU second\n", 20 / (ThreadCpuSeconds() - c0));
}

// Ratio-test matches between two frames and the essential-matrix RANSAC inlier ratio.
bool MatchPair(const ccm::CameraModel& cam, const std::vector<cv::KeyPoint>& kp0, const cv::Mat& d0,
               const std::vector<cv::KeyPoint>& kp1, const cv::Mat& d1, double* match_fraction, double* inliers) {
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(d0, d1, knn, 2);
  std::vector<cv::Point2f> a, b;
  for (const auto& m : knn)
    if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
      a.push_back(kp0[m[0].queryIdx].pt);
      b.push_back(kp1[m[0].trainIdx].pt);
    }
  if (a.size() < 8) return false;
  cv::Mat mask;
  cv::findEssentialMat(Normalized(cam, a), Normalized(cam, b), cv::Mat::eye(3, 3, CV_64F), cv::RANSAC, 0.999,
                       1.0 / cam.intrinsics().fx, mask);
  *inliers = cv::countNonZero(mask) / static_cast<double>(a.size());
  *match_fraction = a.size() / static_cast<double>(std::min(kp0.size(), kp1.size()));
  return true;
}

void ReportOrb(const ccm::sim::Simulation& sim, int agent, int stride) {
  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  std::vector<int> counts;
  std::vector<double> inlier_ratios, match_fractions;
  std::vector<cv::KeyPoint> prev_kp;
  cv::Mat prev_desc;
  for (std::int64_t i = 0; i < sim.NumFrames(agent); i += stride) {
    std::vector<cv::KeyPoint> kp;
    cv::Mat desc;
    orb->detectAndCompute(sim.RenderFrame(agent, i), cv::noArray(), kp, desc);
    counts.push_back(static_cast<int>(kp.size()));
    double fraction = 0, inliers = 0;
    if (!prev_kp.empty() && !kp.empty() &&
        MatchPair(sim.renderer().camera(), prev_kp, prev_desc, kp, desc, &fraction, &inliers)) {
      inlier_ratios.push_back(inliers);
      match_fractions.push_back(fraction);
    }
    prev_kp = kp;
    prev_desc = desc;
  }
  std::vector<int> sorted = counts;
  std::sort(sorted.begin(), sorted.end());
  const double ok = std::count_if(counts.begin(), counts.end(), [](int c) { return c >= 800; }) /
                    static_cast<double>(counts.size());
  std::printf("ORB(1000) on %s/%s, %zu frames (every %d-th): min %d, p5 %d, median %d, >=800 in %.1f%% (target 95%%)\n",
              sim.scenario().name.c_str(), sim.agent_name(agent).c_str(), counts.size(), stride, sorted.front(),
              sorted[sorted.size() / 20], sorted[sorted.size() / 2], 100.0 * ok);
  if (inlier_ratios.empty()) return;
  const double mean_fraction =
      std::accumulate(match_fractions.begin(), match_fractions.end(), 0.0) / match_fractions.size();
  const double mean_inliers = std::accumulate(inlier_ratios.begin(), inlier_ratios.end(), 0.0) / inlier_ratios.size();
  std::sort(inlier_ratios.begin(), inlier_ratios.end());
  std::printf("consecutive pairs (%d frames apart): ratio-test matches / keypoints %.2f, essential RANSAC inlier "
              "ratio mean %.3f, p5 %.3f, min %.3f\n",
              stride, mean_fraction, mean_inliers, inlier_ratios[inlier_ratios.size() / 20], inlier_ratios.front());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_sim: simulator speed and feature statistics"};
  std::string scenario_name = "hall3";
  int agent = 0, stride = 1, render_frames = 60;
  bool fisheye = false;
  app.add_option("--scenario", scenario_name, "built-in scenario or YAML file")->capture_default_str();
  app.add_option("--agent", agent, "agent index for the ORB statistics")->capture_default_str();
  app.add_option("--stride", stride, "use every n-th frame for ORB statistics")->capture_default_str();
  app.add_option("--render-frames", render_frames, "frames for the fps measurement")->capture_default_str();
  app.add_flag("--fisheye", fisheye, "use the fisheye camera");
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);

  std::string error;
  auto scenario = ccm::sim::LoadScenario(scenario_name, &error);
  if (!scenario) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 2;
  }
  if (fisheye) scenario->camera = ccm::sim::FisheyeCamera();
  const auto t0 = std::chrono::steady_clock::now();
  auto sim = ccm::sim::Simulation::Create(*scenario, &error);
  if (!sim || agent < 0 || agent >= sim->num_agents()) {
    std::fprintf(stderr, "error: %s\n", sim ? "--agent out of range" : error.c_str());
    return 2;
  }
  size_t texels = 0;
  for (const auto& t : sim->world()->textures()) texels += t.level(0).total();
  std::printf("world '%s': %zu surfaces, %zu textures, %.1f Mtexels, built in %.2f s\n", scenario->name.c_str(),
              sim->world()->surfaces().size(), sim->world()->textures().size(), texels / 1e6, Seconds(t0));
  std::fflush(stdout);
  ReportRenderSpeed(*sim, agent, render_frames);
  std::fflush(stdout);
  ReportOrb(*sim, agent, stride);
  return 0;
}
