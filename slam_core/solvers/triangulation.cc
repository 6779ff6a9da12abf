#include "slam_core/solvers/triangulation.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>

#include "slam_core/solvers/solver_common.h"
#include "slam_core/solvers/solver_internal.h"

namespace ccm::solvers {
namespace {

// Largest pairwise ray angle, as its cosine, with rays expressed in the world frame.
double MinCosParallax(const std::vector<BearingObservation>& views) {
  std::vector<Eigen::Vector3d> rays;
  rays.reserve(views.size());
  for (const auto& v : views) rays.push_back(v.cam_from_world.rotation().conjugate() * v.bearing.normalized());
  double min_cos = 1.0;
  for (size_t i = 0; i < rays.size(); ++i) {
    for (size_t j = i + 1; j < rays.size(); ++j) min_cos = std::min(min_cos, rays[i].dot(rays[j]));
  }
  return min_cos;
}

// Homogeneous DLT: f x (R X + t) = 0 per view; smallest eigenvector of A^T A.
std::optional<Eigen::Vector3d> SolveLinear(const std::vector<BearingObservation>& views) {
  Eigen::Matrix4d ata = Eigen::Matrix4d::Zero();
  for (const auto& v : views) {
    Eigen::Matrix<double, 3, 4> P;
    P.leftCols<3>() = v.cam_from_world.rotation_matrix();
    P.col(3) = v.cam_from_world.translation();
    const Eigen::Vector3d f = v.bearing.normalized();
    Eigen::Matrix3d fx;
    fx << 0, -f.z(), f.y(), f.z(), 0, -f.x(), -f.y(), f.x(), 0;
    const Eigen::Matrix<double, 3, 4> A = fx * P;
    ata += A.transpose() * A;
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix4d> eig(ata);
  const Eigen::Vector4d X = eig.eigenvectors().col(0);
  if (std::abs(X(3)) < 1e-12 * X.head<3>().norm() || !X.allFinite()) return std::nullopt;
  return Eigen::Vector3d(X.head<3>() / X(3));
}

}  // namespace

std::string TriangulationOptions::Validate() const {
  if (!(max_cos_parallax > -1.0 && max_cos_parallax <= 1.0)) return "max_cos_parallax must be in (-1, 1]";
  if (!(max_error_px > 0.0)) return "max_error_px must be > 0";
  if (!(focal_px > 0.0)) return "focal_px must be > 0";
  if (!(min_depth >= 0.0)) return "min_depth must be >= 0";
  return "";
}

const char* TriangulationStatusName(TriangulationStatus status) {
  switch (status) {
    case TriangulationStatus::kOk: return "ok";
    case TriangulationStatus::kInvalidInput: return "invalid input";
    case TriangulationStatus::kLowParallax: return "low parallax";
    case TriangulationStatus::kDegenerate: return "degenerate";
    case TriangulationStatus::kBehindCamera: return "behind camera";
    case TriangulationStatus::kLargeError: return "large error";
  }
  return "unknown";
}

TriangulationResult TriangulateMultiView(const std::vector<BearingObservation>& views,
                                         const TriangulationOptions& options) {
  TriangulationResult result;
  if (views.size() < 2 || !options.Validate().empty()) return result;
  result.cos_parallax = MinCosParallax(views);
  if (result.cos_parallax > options.max_cos_parallax) {
    result.status = TriangulationStatus::kLowParallax;
    return result;
  }
  const std::optional<Eigen::Vector3d> X = SolveLinear(views);
  if (!X) {
    result.status = TriangulationStatus::kDegenerate;
    return result;
  }
  bool behind = false;
  for (const auto& v : views) {
    const Eigen::Vector3d p_cam = v.cam_from_world * (*X);
    const Eigen::Vector3d f = v.bearing.normalized();
    // "In front" means along the observed ray, which also covers fisheye rays beyond 90 deg.
    if (p_cam.dot(f) <= options.min_depth) behind = true;
    const double err_px = AngleToPixels(internal::AngleBetween(p_cam, f), options.focal_px);
    result.max_error_px = std::max(result.max_error_px, err_px);
  }
  if (behind) {
    result.status = TriangulationStatus::kBehindCamera;
  } else if (result.max_error_px > options.max_error_px) {
    result.status = TriangulationStatus::kLargeError;
  } else {
    result.status = TriangulationStatus::kOk;
    result.point = X;
  }
  return result;
}

TriangulationResult TriangulateTwoView(const Eigen::Vector3d& bearing1,
                                       const Eigen::Vector3d& bearing2,
                                       const SE3& cam2_from_cam1,
                                       const TriangulationOptions& options) {
  return TriangulateMultiView({{SE3(), bearing1}, {cam2_from_cam1, bearing2}}, options);
}

}  // namespace ccm::solvers
