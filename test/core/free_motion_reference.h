// The reference free motion of a modal tooth at constant drum speed, for the tests of the exact
// free propagator (test_event_driven) and of the modal split (test_modal_split).
#pragma once

#include <unsupported/Eigen/MatrixFunctions>

#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace testutil {

// y(t) = exp(A t) y0 for y = [q; qdot], A = [0 I; -S -D], S = Lambda + Omega^2 (K_G - I) written
// out here from the model's fields, by Eigen's Pade matrix exponential. Taken in coordinates
// [omega_i q_i; qdot_i] (A's entries reach omega_4^2 ~ 1e10, which costs the plain Pade
// exponential ~1e-6 relative; balanced, it is exact to rounding).
inline VecX referenceFreeMotion(const ToothModel& tm, double omega, double t, const VecX& y0) {
  const int n = tm.n_modes;
  MatX A = MatX::Zero(2 * n, 2 * n);
  A.topRightCorner(n, n).setIdentity();
  A.bottomLeftCorner(n, n) = -omega * omega * tm.K_G;
  A.bottomLeftCorner(n, n).diagonal() += -(tm.omega0_sq.array() - omega * omega).matrix();
  A.bottomRightCorner(n, n).diagonal() = -tm.damping_coeff;
  VecX s = VecX::Ones(2 * n);
  s.head(n) = tm.omega0_sq.cwiseSqrt();
  const MatX At = s.asDiagonal() * A * s.cwiseInverse().asDiagonal() * t;
  return s.cwiseInverse().asDiagonal() * (At.exp() * (s.asDiagonal() * y0));
}

}  // namespace testutil
}  // namespace threshing_sim
