#include "slam_core/solvers/absolute_pose.h"

#include <memory>

#include <opengv/absolute_pose/CentralAbsoluteAdapter.hpp>
#include <opengv/absolute_pose/methods.hpp>
#include <opengv/sac/Ransac.hpp>
#include <opengv/sac_problems/absolute_pose/AbsolutePoseSacProblem.hpp>

#include "slam_core/solvers/solver_internal.h"

namespace ccm::solvers {
namespace {

using AbsoluteProblem = opengv::sac_problems::absolute_pose::AbsolutePoseSacProblem;

AbsoluteProblem::algorithm_t ToOpenGv(AbsolutePoseAlgorithm a) {
  switch (a) {
    case AbsolutePoseAlgorithm::kKneipP3P: return AbsoluteProblem::KNEIP;
    case AbsolutePoseAlgorithm::kGaoP3P: return AbsoluteProblem::GAO;
  }
  return AbsoluteProblem::KNEIP;
}

// OpenGV's nonlinear refinement on the inliers, then re-selection (its residual 1 - cos
// compares signed rays, so points behind the camera never come back). The refined model
// is kept unless it loses more than 10 % of the inliers (a bad local minimum).
void RefineAndReselect(AbsoluteProblem* problem, double threshold, opengv::transformation_t* model,
                       std::vector<int>* inliers) {
  for (int round = 0; round < 2; ++round) {
    opengv::transformation_t refined;
    problem->optimizeModelCoefficients(*inliers, *model, refined);
    if (!refined.allFinite()) break;
    std::vector<int> refined_inliers;
    problem->selectWithinDistance(refined, threshold, refined_inliers);
    if (refined_inliers.size() < 0.9 * inliers->size()) break;
    *model = refined;
    inliers->swap(refined_inliers);
  }
}

}  // namespace

std::string AbsolutePoseOptions::Validate() const {
  const std::string r = ransac.Validate();
  if (!r.empty()) return r;
  if (min_inliers < 4) return "min_inliers must be >= 4";
  return "";
}

AbsolutePoseResult EstimateAbsolutePose(const std::vector<Eigen::Vector3d>& bearings,
                                        const std::vector<Eigen::Vector3d>& points_world,
                                        const AbsolutePoseOptions& options) {
  AbsolutePoseResult result;
  result.message = options.Validate();
  if (!result.message.empty()) return result;
  if (bearings.size() != points_world.size()) {
    result.message = "bearings and points differ in size";
    return result;
  }
  const int n = static_cast<int>(bearings.size());
  result.inliers.assign(n, false);
  const opengv::bearingVectors_t f = internal::ToOpenGv(bearings);
  const opengv::points_t p(points_world.begin(), points_world.end());
  opengv::absolute_pose::CentralAbsoluteAdapter adapter(f, p);
  auto problem = std::make_shared<AbsoluteProblem>(adapter, ToOpenGv(options.algorithm), false);
  const int needed = std::max(problem->getSampleSize(), options.min_inliers);
  if (n < needed) {
    result.status = SolverStatus::kTooFewPoints;
    result.message = "need at least " + std::to_string(needed) + " correspondences, got " + std::to_string(n);
    return result;
  }
  internal::SeedOpenGvProblem(problem.get(), options.ransac.seed);

  opengv::sac::Ransac<AbsoluteProblem> ransac;
  ransac.sac_model_ = problem;
  ransac.threshold_ = internal::OneMinusCos(options.ransac.ThresholdAngleRad());
  ransac.max_iterations_ = options.ransac.max_iterations;
  ransac.probability_ = options.ransac.confidence;
  if (!ransac.computeModel(0)) {
    result.status = SolverStatus::kRansacFailed;
    result.message = "no P3P hypothesis";
    return result;
  }
  result.iterations = ransac.iterations_;
  opengv::transformation_t model = ransac.model_coefficients_;
  std::vector<int> inliers = ransac.inliers_;
  if (options.refine && static_cast<int>(inliers.size()) >= 6) {
    RefineAndReselect(problem.get(), ransac.threshold_, &model, &inliers);
  }
  result.world_from_cam = SE3(Eigen::Matrix3d(model.leftCols<3>()), Eigen::Vector3d(model.col(3)));
  for (int i : inliers) result.inliers[i] = true;
  result.num_inliers = static_cast<int>(inliers.size());
  if (result.num_inliers < options.min_inliers) {
    result.status = SolverStatus::kTooFewInliers;
    result.message = std::to_string(result.num_inliers) + " inliers < min_inliers " +
                     std::to_string(options.min_inliers);
    return result;
  }
  result.status = SolverStatus::kOk;
  return result;
}

}  // namespace ccm::solvers
