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
  // Complex products written out in real arithmetic (the library's complex product checks for
  // infinities and NaNs in a call per product); the values are those of the complex operators.
  for (int i = 0; i < 2 * n; ++i) {
    double c_re = 0.0, c_im = 0.0;
    for (int j = 0; j < n; ++j) {
      const std::complex<double>& a = V_inv(i, j);
      const std::complex<double>& b = V_inv(i, n + j);
      c_re += a.real() * q0[j] + b.real() * qd0[j];
      c_im += a.imag() * q0[j] + b.imag() * qd0[j];
    }
    c[i] = std::complex<double>(c_re, c_im);
  }
}

// [q1; qd1] = Re(V diag(exp(lambda h)) c) from modal amplitudes c (the imaginary part cancels
// over conjugate pairs); c_h receives the advanced amplitudes and may be c itself. A conjugate
// pair's second factor is the conjugate of the first (cexp is exactly symmetric), so one
// exponential per pair. Allocates nothing.
template <class Lambda, class Mat, class C, class Ch, class Q1, class Qd1>
void modalEvaluate(const Lambda& lambda, const Mat& V, int n, double h_s, const C& c, Ch& c_h,
                   Q1& q1, Qd1& qd1) {
  const int n2 = 2 * n;
  std::complex<double> growth(0.0, 0.0);
  for (int i = 0; i < n2; ++i) {
    const bool conjugate_of_previous = i > 0 && lambda[i] == std::conj(lambda[i - 1]);
    growth = conjugate_of_previous ? std::conj(growth) : std::exp(lambda[i] * h_s);
    const std::complex<double> ci = c[i];
    c_h[i] = std::complex<double>(ci.real() * growth.real() - ci.imag() * growth.imag(),
                                  ci.real() * growth.imag() + ci.imag() * growth.real());
  }
  for (int r = 0; r < n2; ++r) {
    double y = 0.0;
    for (int i = 0; i < n2; ++i) y += V(r, i).real() * c_h[i].real() - V(r, i).imag() * c_h[i].imag();
    (r < n ? q1[r] : qd1[r - n]) = y;
  }
}

}  // namespace internal
}  // namespace threshing_sim
