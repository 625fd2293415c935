// A small Levenberg–Marquardt for the calibration's few-parameter refinements (a board pose
// seen by camera and projector, the turntable axis): numeric central-difference Jacobians,
// dense normal equations. Tens of parameters and a few thousand residuals at most.
#pragma once

#include <cmath>
#include <functional>

#include <Eigen/Cholesky>
#include <Eigen/Core>

namespace sls::calib {

// residuals(x, r) fills r (its size fixed by the first call).
using ResidualFunction = std::function<void(const Eigen::VectorXd& x, Eigen::VectorXd* residuals)>;

struct LeastSquaresResult {
  Eigen::VectorXd x;
  double rms = 0.0;  // sqrt(mean of squared residuals) at x
  int iterations = 0;
};

inline LeastSquaresResult minimize_least_squares(const ResidualFunction& residuals, Eigen::VectorXd x,
                                                 const Eigen::VectorXd& step_scale, int max_iterations = 50) {
  Eigen::VectorXd r;
  residuals(x, &r);
  double cost = r.squaredNorm();
  double lambda = 1e-3;
  LeastSquaresResult result;
  for (int iteration = 0; iteration < max_iterations; ++iteration) {
    Eigen::MatrixXd jacobian(r.size(), x.size());
    for (Eigen::Index j = 0; j < x.size(); ++j) {
      const double h = 1e-6 * step_scale(j);
      Eigen::VectorXd plus = x, minus = x, r_plus, r_minus;
      plus(j) += h;
      minus(j) -= h;
      residuals(plus, &r_plus);
      residuals(minus, &r_minus);
      jacobian.col(j) = (r_plus - r_minus) / (2.0 * h);
    }
    const Eigen::MatrixXd normal = jacobian.transpose() * jacobian;
    const Eigen::VectorXd gradient = jacobian.transpose() * r;
    bool improved = false;
    for (int attempt = 0; attempt < 10 && !improved; ++attempt) {
      Eigen::MatrixXd damped = normal;
      damped.diagonal() += lambda * normal.diagonal().cwiseMax(1e-12);
      const Eigen::VectorXd delta = -damped.ldlt().solve(gradient);
      Eigen::VectorXd candidate = x + delta, r_candidate;
      residuals(candidate, &r_candidate);
      const double candidate_cost = r_candidate.squaredNorm();
      if (std::isfinite(candidate_cost) && candidate_cost < cost) {
        const double relative_gain = (cost - candidate_cost) / std::max(cost, 1e-300);
        x = candidate;
        r = r_candidate;
        cost = candidate_cost;
        lambda = std::max(lambda * 0.3, 1e-9);
        improved = true;
        result.iterations = iteration + 1;
        if (relative_gain < 1e-12) iteration = max_iterations;  // converged
      } else {
        lambda *= 10.0;
      }
    }
    if (!improved) break;
  }
  result.x = x;
  result.rms = r.size() > 0 ? std::sqrt(cost / static_cast<double>(r.size())) : 0.0;
  return result;
}

}  // namespace sls::calib
