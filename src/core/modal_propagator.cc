// threshing_sim core: eigendecomposition of a linear system's state matrix for its exact
// propagator (see modal_propagator.h).
#include "modal_propagator.h"

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

namespace threshing_sim {
namespace internal {

bool decomposeStateMatrix(const MatX& A, const VecX& s, Eigen::VectorXcd* lambda,
                          Eigen::MatrixXcd* V, Eigen::MatrixXcd* V_inv) {
  const MatX A_s = s.asDiagonal() * A * s.cwiseInverse().asDiagonal();
  // Eigendecomposition A_s = V_s diag(lambda) V_s^-1 (complex conjugate pairs of damped modes).
  const Eigen::EigenSolver<MatX> solver(A_s, true);
  if (solver.info() != Eigen::Success) return false;
  *lambda = solver.eigenvalues();
  const Eigen::MatrixXcd V_s = solver.eigenvectors();
  const Eigen::PartialPivLU<Eigen::MatrixXcd> lu(V_s);
  const Eigen::MatrixXcd V_s_inv = lu.inverse();
  // Usable only if the factors rebuild A_s (a defective, e.g. critically damped, A would not).
  const Eigen::MatrixXcd rebuilt = V_s * lambda->asDiagonal() * V_s_inv;
  const double scale = A_s.cwiseAbs().maxCoeff();
  const double residual = (rebuilt - A_s.cast<std::complex<double>>()).cwiseAbs().maxCoeff();
  // The balancing folded in: exp(A h) = diag(1/s) V_s exp(lambda h) V_s^-1 diag(s).
  *V = s.cwiseInverse().cast<std::complex<double>>().asDiagonal() * V_s;
  *V_inv = V_s_inv * s.cast<std::complex<double>>().asDiagonal();
  return V_inv->allFinite() && V->allFinite() && residual <= 1e-9 * scale;
}

}  // namespace internal
}  // namespace threshing_sim
