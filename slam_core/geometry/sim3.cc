#include "slam_core/geometry/sim3.h"

#include <cmath>

#include <Eigen/LU>

#include <unsupported/Eigen/MatrixFunctions>

#include "slam_core/geometry/so3_util.h"

namespace ccm {
namespace {

// W such that t = W * rho for the Sim(3) exponential. It is the integral
// int_0^1 exp(u * (sigma*I + hat(phi))) du, obtained exactly as the top-right block of
// exp([[A, I], [0, 0]]). This avoids the case analysis (sigma -> 0, theta -> 0) of the
// closed form, whose small-angle branches are easy to get wrong; speed is not critical
// here because optimizers use their own local parameterisation.
Eigen::Matrix3d SimW(const Eigen::Vector3d& phi, double sigma) {
  Eigen::Matrix<double, 6, 6> m = Eigen::Matrix<double, 6, 6>::Zero();
  m.topLeftCorner<3, 3>() = sigma * Eigen::Matrix3d::Identity() + internal::Hat(phi);
  m.topRightCorner<3, 3>() = Eigen::Matrix3d::Identity();
  const Eigen::Matrix<double, 6, 6> e = m.exp();
  return e.topRightCorner<3, 3>();
}

}  // namespace

Sim3 Sim3::Exp(const Eigen::Matrix<double, 7, 1>& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.segment<3>(3);
  const double sigma = xi(6);
  return Sim3(std::exp(sigma), internal::ExpSO3Public(phi), SimW(phi, sigma) * rho);
}

Eigen::Matrix<double, 7, 1> Sim3::Log() const {
  Eigen::Matrix<double, 7, 1> xi;
  const Eigen::Vector3d phi = internal::LogSO3Public(q_);
  const double sigma = std::log(s_);
  xi.head<3>() = SimW(phi, sigma).lu().solve(t_);
  xi.segment<3>(3) = phi;
  xi(6) = sigma;
  return xi;
}

Eigen::Matrix4d Sim3::matrix() const {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.topLeftCorner<3, 3>() = s_ * q_.toRotationMatrix();
  m.topRightCorner<3, 1>() = t_;
  return m;
}

}  // namespace ccm
