#include "slam_core/eval/alignment.h"

#include <Eigen/SVD>

namespace ccm {

std::optional<AlignmentType> ParseAlignmentType(const std::string& name) {
  if (name == "none") return AlignmentType::kNone;
  if (name == "se3") return AlignmentType::kSE3;
  if (name == "sim3") return AlignmentType::kSim3;
  return std::nullopt;
}

const char* ToString(AlignmentType type) {
  switch (type) {
    case AlignmentType::kNone: return "none";
    case AlignmentType::kSE3: return "se3";
    case AlignmentType::kSim3: return "sim3";
  }
  return "?";
}

std::optional<Sim3> UmeyamaAlignment(const std::vector<Eigen::Vector3d>& est,
                                     const std::vector<Eigen::Vector3d>& gt, bool with_scale,
                                     std::string* error) {
  if (est.size() != gt.size()) {
    *error = "alignment needs as many estimated as ground-truth positions";
    return std::nullopt;
  }
  const size_t n = est.size();
  if (n < 3) {
    *error = "alignment needs >= 3 associated poses, have " + std::to_string(n);
    return std::nullopt;
  }
  Eigen::Vector3d mean_est = Eigen::Vector3d::Zero(), mean_gt = Eigen::Vector3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    mean_est += est[i];
    mean_gt += gt[i];
  }
  mean_est /= static_cast<double>(n);
  mean_gt /= static_cast<double>(n);
  double var_est = 0.0;  // sigma_x^2 in Umeyama's notation
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d de = est[i] - mean_est;
    var_est += de.squaredNorm();
    cov += (gt[i] - mean_gt) * de.transpose();
  }
  var_est /= static_cast<double>(n);
  cov /= static_cast<double>(n);

  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d d = svd.singularValues();
  if (!(var_est > 0.0) || d(1) <= 1e-12 * d(0)) {
    *error = "alignment is degenerate: the positions are (nearly) all on one line or one point";
    return std::nullopt;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) S(2, 2) = -1.0;
  const Eigen::Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
  const double scale = with_scale ? (d.asDiagonal() * S).trace() / var_est : 1.0;
  const Eigen::Vector3d t = mean_gt - scale * R * mean_est;
  return Sim3(scale, Eigen::Quaterniond(R), t);
}

}  // namespace ccm
