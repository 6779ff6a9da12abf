// ccm_eval: trajectory evaluation (ATE/RPE, evo conventions) of one or several agents against
// ground truth, with one joint alignment for agents sharing a map. See docs/evaluation.md.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <opencv2/imgcodecs.hpp>

#include "eval_report.h"
#include "slam_core/eval/evaluator.h"
#include "slam_core/io/trajectory_io.h"
#include "trajectory_plot.h"

namespace {

struct Args {
  std::vector<std::string> gt, est, names;
  std::string align = "sim3", format = "auto", rpe_unit = "frames", kitti_times;
  std::string json_path, plot_path;
  ccm::EvalOptions eval;
  ccm::tools::PlotOptions plot;
};

void AddOptions(CLI::App* app, Args* args) {
  app->add_option("--gt", args->gt, "ground-truth trajectory (file or EuRoC folder); repeat per agent")
      ->required();
  app->add_option("--est", args->est, "estimated trajectory; one per --gt, same order")
      ->required();
  app->add_option("--name", args->names, "agent names, one per --gt (default agent0, agent1, ...)")
      ;
  app->add_option("--align", args->align, "sim3 (monocular), se3 (metric) or none")
      ->check(CLI::IsMember({"sim3", "se3", "none"}))->capture_default_str();
  app->add_option("--n-align", args->eval.align_first_n, "align on the first N pairs of each agent (-1: all)")
      ->capture_default_str();
  app->add_option("--max-dt", args->eval.association.max_dt_s, "association tolerance [s]")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  app->add_option("--t-offset", args->eval.association.est_offset_s, "added to estimate stamps [s]")
      ->capture_default_str();
  app->add_option("--format", args->format, "input format: auto (by content), tum, euroc, kitti")
      ->check(CLI::IsMember({"auto", "tum", "euroc", "kitti"}))->capture_default_str();
  app->add_option("--kitti-times", args->kitti_times,
                  "times.txt for KITTI pose files (default: pose i at i seconds)")->check(CLI::ExistingFile);
  app->add_option("--rpe-delta", args->eval.rpe.delta, "RPE step")->capture_default_str();
  app->add_option("--rpe-unit", args->rpe_unit, "RPE step unit: frames or m (path length)")
      ->check(CLI::IsMember({"frames", "m"}))->capture_default_str();
  app->add_flag("--rpe-all-pairs", args->eval.rpe.all_pairs, "RPE over all (overlapping) pairs");
  app->add_option("--scale-window", args->eval.scale_window_m,
                  "also print each agent's scale drift: its scale over windows of this many metres of path (0: off)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app->add_option("--json", args->json_path, "write results as JSON");
  app->add_option("--plot", args->plot_path, "write a PNG top view (ground truth vs aligned estimate)");
  app->add_option("--plot-plane", args->plot.plane, "auto, xy, xz or yz")->capture_default_str();
  app->add_option("--plot-size", args->plot.size_px, "plot width [px]")->capture_default_str();
}

int Fail(const std::string& message) {
  std::cerr << "ccm_eval: error: " << message << "\n";
  return 1;
}

bool LoadAgents(const Args& args, std::vector<ccm::AgentInput>* agents, std::string* error) {
  ccm::TrajectoryReadOptions read;
  read.format = *ccm::ParseTrajectoryFormat(args.format);
  read.kitti_times_path = args.kitti_times;
  for (size_t i = 0; i < args.gt.size(); ++i) {
    ccm::AgentInput agent;
    agent.name = i < args.names.size() ? args.names[i] : "agent" + std::to_string(i);
    ccm::IoStatus status = ccm::ReadTrajectory(args.gt[i], read, &agent.gt);
    if (status.ok()) status = ccm::ReadTrajectory(args.est[i], read, &agent.est);
    if (!status.ok()) {
      *error = status.message();
      return false;
    }
    if (agent.gt.empty() || agent.est.empty()) {
      *error = (agent.gt.empty() ? args.gt[i] : args.est[i]) + " contains no poses";
      return false;
    }
    agents->push_back(std::move(agent));
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ccm_eval: ATE/RPE of estimated trajectories against ground truth (evo conventions)"};
  Args args;
  AddOptions(&app, &args);
  CLI11_PARSE(app, argc, argv);

  if (args.gt.size() != args.est.size()) {
    return Fail("give one --est per --gt (" + std::to_string(args.gt.size()) + " --gt, " +
                std::to_string(args.est.size()) + " --est)");
  }
  if (!args.names.empty() && args.names.size() != args.gt.size()) {
    return Fail("give one --name per --gt or none");
  }
  args.eval.alignment = *ccm::ParseAlignmentType(args.align);
  args.eval.rpe.unit = args.rpe_unit == "m" ? ccm::RpeDeltaUnit::kMeters : ccm::RpeDeltaUnit::kFrames;
  std::string error;
  if (!args.eval.Validate(&error) || (!args.plot_path.empty() && !args.plot.Validate(&error))) {
    return Fail(error);
  }
  std::vector<ccm::AgentInput> agents;
  if (!LoadAgents(args, &agents, &error)) return Fail(error);
  ccm::EvalReport report;
  if (!ccm::Evaluate(agents, args.eval, &report, &error)) return Fail(error);

  std::cout << ccm::tools::FormatTable(report, args.eval);
  if (!args.json_path.empty()) {
    std::vector<ccm::tools::InputFiles> files;
    for (size_t i = 0; i < args.gt.size(); ++i) files.push_back({args.gt[i], args.est[i]});
    std::ofstream out(args.json_path);
    out << ccm::tools::ToJson(report, args.eval, files).dump(2) << "\n";
    if (!out) return Fail("cannot write " + args.json_path);
  }
  if (!args.plot_path.empty()) {
    const cv::Mat image = ccm::tools::RenderTopView(report, args.eval, args.plot);
    bool written = false;
    try {
      written = cv::imwrite(args.plot_path, image, {cv::IMWRITE_PNG_COMPRESSION, 9});
    } catch (const cv::Exception& e) {
      return Fail("cannot write " + args.plot_path + ": " + e.what());
    }
    if (!written) return Fail("cannot write " + args.plot_path);
  }
  return 0;
}
