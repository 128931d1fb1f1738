// threshing_sim core: exact propagators of linear constant-coefficient systems y' = A y by the
// eigendecomposition A = V diag(lambda) V^-1 (complex conjugate pairs of damped modes), so that
// y(t + h) = V diag(exp(lambda h)) V^-1 y(t) costs 2n exponentials and two products, for any h.
// Shared by the free modal tooth (beam.cc) and the idle kernel on its pedicel
// (async/pedicel_propagator.cc).
#pragma once

#include <Eigen/Core>
#include <complex>

#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Decomposes the state matrix A (2n x 2n) in balanced coordinates y_s = diag(s) y (s > 0 puts
// the states on comparable scales, which keeps the eigenvectors well conditioned) and folds the
// balancing back in: on success V, V_inv act on y itself. Returns whether the factors rebuild
// the balanced matrix to 1e-9 relative (a defective matrix, e.g. critically damped, does not) and
// are finite. Allocates.
bool decomposeStateMatrix(const MatX& A, const VecX& s, Eigen::VectorXcd* lambda,
                          Eigen::MatrixXcd* V, Eigen::MatrixXcd* V_inv);

// Modal amplitudes c = V^-1 y0 of y0 = [q0; qd0], q0 and qd0 of n entries each. Templated over
// fixed and dynamic sizes; allocates nothing.
template <class Mat, class Q0, class Qd0, class C>
void modalAmplitudes(const Mat& V_inv, int n, const Q0& q0, const Qd0& qd0, C& c) {
  for (int i = 0; i < 2 * n; ++i) {
    std::complex<double> ci(0.0, 0.0);
    for (int j = 0; j < n; ++j) ci += V_inv(i, j) * q0[j] + V_inv(i, n + j) * qd0[j];
    c[i] = ci;
  }
}

// [q1; qd1] = Re(V diag(exp(lambda h)) c) from modal amplitudes c (the imaginary part cancels
// over conjugate pairs); c_h receives the advanced amplitudes and may be c itself. Allocates
// nothing.
template <class Lambda, class Mat, class C, class Ch, class Q1, class Qd1>
void modalEvaluate(const Lambda& lambda, const Mat& V, int n, double h_s, const C& c, Ch& c_h,
                   Q1& q1, Qd1& qd1) {
  const int n2 = 2 * n;
  for (int i = 0; i < n2; ++i) c_h[i] = c[i] * std::exp(lambda[i] * h_s);
  for (int r = 0; r < n2; ++r) {
    double y = 0.0;
    for (int i = 0; i < n2; ++i) y += (V(r, i) * c_h[i]).real();
    (r < n ? q1[r] : qd1[r - n]) = y;
  }
}

}  // namespace internal
}  // namespace threshing_sim
