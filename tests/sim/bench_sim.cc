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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"bench_sim: simulator speed and feature statistics"};
  std::string scenario_name = "hall3";
  int agent = 0, stride = 2, render_frames = 60;
  app.add_option("--scenario", scenario_name, "built-in scenario or YAML file")->capture_default_str();
  app.add_option("--agent", agent, "agent index for the ORB statistics")->capture_default_str();
  app.add_option("--stride", stride, "use every n-th frame for ORB statistics")->capture_default_str();
  app.add_option("--render-frames", render_frames, "frames for the fps measurement")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  cv::setNumThreads(1);

  std::string error;
  auto scenario = ccm::sim::LoadScenario(scenario_name, &error);
  if (!scenario) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 2;
  }
  auto t0 = std::chrono::steady_clock::now();
  auto sim = ccm::sim::Simulation::Create(*scenario, &error);
  if (!sim) {
    std::fprintf(stderr, "error: %s\n", error.c_str());
    return 2;
  }
  size_t texels = 0;
  for (const auto& t : sim->world()->textures()) texels += t.level(0).total();
  std::printf("world '%s': %zu surfaces, %zu textures, %.1f Mtexels, built in %.2f s\n", scenario->name.c_str(),
              sim->world()->surfaces().size(), sim->world()->textures().size(), texels / 1e6, Seconds(t0));

  const std::int64_t n_frames = sim->NumFrames(agent);
  t0 = std::chrono::steady_clock::now();
  const double cpu0 = ThreadCpuSeconds();
  for (int i = 0; i < render_frames; ++i) sim->RenderFrame(agent, (i * 7) % n_frames);
  const double fps = render_frames / Seconds(t0);
  const double cpu_fps = render_frames / (ThreadCpuSeconds() - cpu0);
  std::printf("render %dx%d, 1 thread: %.1f frames/s per CPU second (%.2f ms CPU/frame), %.1f frames/s wall clock "
              "(target 30)\n",
              sim->renderer().camera().width(), sim->renderer().camera().height(), cpu_fps, 1000.0 / cpu_fps, fps);
  {
    ccm::sim::Scenario blurred = *scenario;
    blurred.render.motion_blur_samples = 4;
    auto sim_blur = ccm::sim::Simulation::Create(blurred, &error, sim->world());
    const double c0 = ThreadCpuSeconds();
    for (int i = 0; i < 20; ++i) sim_blur->RenderFrame(agent, (i * 7) % n_frames);
    std::printf("render with 4-sample motion blur: %.1f frames/s per CPU second\n", 20 / (ThreadCpuSeconds() - c0));
  }

  cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  cv::BFMatcher matcher(cv::NORM_HAMMING);
  std::vector<int> counts;
  std::vector<double> inlier_ratios, match_fractions;
  std::vector<cv::KeyPoint> prev_kp;
  cv::Mat prev_desc;
  for (std::int64_t i = 0; i < n_frames; i += stride) {
    std::vector<cv::KeyPoint> kp;
    cv::Mat desc;
    orb->detectAndCompute(sim->RenderFrame(agent, i), cv::noArray(), kp, desc);
    counts.push_back(static_cast<int>(kp.size()));
    if (!prev_kp.empty() && !kp.empty()) {
      std::vector<std::vector<cv::DMatch>> knn;
      matcher.knnMatch(prev_desc, desc, knn, 2);
      std::vector<cv::Point2f> a, b;
      for (const auto& m : knn)
        if (m.size() == 2 && m[0].distance < 0.8f * m[1].distance) {
          a.push_back(prev_kp[m[0].queryIdx].pt);
          b.push_back(kp[m[0].trainIdx].pt);
        }
      if (a.size() >= 8) {
        const auto na = Normalized(sim->renderer().camera(), a), nb = Normalized(sim->renderer().camera(), b);
        cv::Mat mask;
        const double f = sim->scenario().camera.fx;
        cv::findEssentialMat(na, nb, cv::Mat::eye(3, 3, CV_64F), cv::RANSAC, 0.999, 1.0 / f, mask);
        inlier_ratios.push_back(cv::countNonZero(mask) / static_cast<double>(a.size()));
        match_fractions.push_back(a.size() / static_cast<double>(std::min(kp.size(), prev_kp.size())));
      }
    }
    prev_kp = kp;
    prev_desc = desc;
  }
  std::vector<int> sorted = counts;
  std::sort(sorted.begin(), sorted.end());
  const double ok = std::count_if(counts.begin(), counts.end(), [](int c) { return c >= 800; }) /
                    static_cast<double>(counts.size());
  std::printf("ORB(1000) on %s/%s, %zu frames (every %d-th): min %d, p5 %d, median %d, >=800 in %.1f%% (target 95%%)\n",
              scenario->name.c_str(), sim->agent_name(agent).c_str(), counts.size(), stride, sorted.front(),
              sorted[sorted.size() / 20], sorted[sorted.size() / 2], 100.0 * ok);
  auto mean = [](const std::vector<double>& v) { return std::accumulate(v.begin(), v.end(), 0.0) / std::max<size_t>(1, v.size()); };
  std::sort(inlier_ratios.begin(), inlier_ratios.end());
  if (!inlier_ratios.empty())
    std::printf("consecutive pairs (%d frames apart): ratio-test matches / keypoints %.2f, essential RANSAC inlier "
                "ratio mean %.3f, p5 %.3f, min %.3f\n",
                stride, mean(match_fractions), mean(inlier_ratios), inlier_ratios[inlier_ratios.size() / 20],
                inlier_ratios.front());
  return 0;
}
