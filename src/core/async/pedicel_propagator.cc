// Asynchronous core: the closed form of an idle kernel on its pedicel (see pedicel_propagator.h).
//
// Validity bound. With the deviation d = y - y_eq, the exact motion obeys d' = A d + n(d) with n
// the remainder, n_k = 1/2 d^T H^k d + O(|d|^3) for the rates k = 3..5 (H^k the Hessian at y_eq);
// the closed form drops n. Along the closed form d = V c(t), c_a(t) = c_a exp(lambda_a t), so the
// second-order forcing of mode m is sum_ab W_mab c_a c_b exp((lambda_a + lambda_b) t) with
// W_mab = 1/2 sum_k V^-1_{m,3+k} V_a^T H^k V_b, and the error it leaves in mode m,
// w (exp(mu t) - exp(lambda_m t)) / (mu - lambda_m) with mu = lambda_a + lambda_b, is at most
// |w| min(t, 2 / |mu - lambda_m|) (no mode grows): bounded unless resonant. Summed through |V|
// into the states, weighted by the absolute floor w_j of the integrators' error scale (1e-2 for
// positions and angles, 1 for rates), that is error_bounded q or t error_secular q per unit
// tolerance, q_ab = |c_a||c_b|; a factor 2 is kept for the third and higher orders, which the
// closed form admits only in the linear regime (rho = max_j E_j / s_j < 1e-2, E the envelope
// |d_j(t)| <= sum_a |V_ja||c_a|, s the stem's reach, 1 rad and the fastest mode's rate times
// those). The span over which the error stays within the tolerance is infinite when the bounded
// part is, else limited by the secular part.
// Pedicel break: the stem force is m (a - g) for the translational rows, so over the envelope
// |F(t)| <= |F_eq| + sum_j |dF_j| E_j + m |(n_3, n_4)|, |n_k| <= E^T (|H^k| / 2) E; while that
// stays below the detachment force the stem cannot break, whatever the span.
#include "pedicel_propagator.h"

#include "../modal_propagator.h"

namespace threshing_sim {
namespace internal {
namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr double kHigherOrderFactor = 2.0;  // room for the third and higher orders [-]
constexpr double kLinearRegime = 1e-2;      // largest rho the closed form is used at [-]

inline Vec2 rotated(double angle_rad, const Vec2& v) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y());
}

inline Vec2 perpOf(const Vec2& v) { return Vec2(-v.y(), v.x()); }

inline double crossOf(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Hanging equilibrium: Newton on the static balance (f = 0 at rest) from the hanging guess
// (the stem along g, stretched by m |g| / k; the centre below the attachment point).
bool solveEquilibrium(const KernelModel& k, const Vec2& g, PedicelVec* y_eq) {
  const double g_norm = g.norm();
  const double p_norm = k.pedicel.p_KP_K.norm();
  if (!(g_norm > 0.0) || !(p_norm > 0.0)) return false;  // no unique equilibrium
  const Vec2 down = g / g_norm;
  const double len = k.pedicel.rest_length_m + k.mass_kg * g_norm / k.pedicel.stiffness_Npm;
  PedicelVec y = PedicelVec::Zero();
  y.head<2>() = k.pedicel.p_WA_W + down * (len + p_norm);
  y[2] = std::atan2(-down.y(), -down.x()) - std::atan2(k.pedicel.p_KP_K.y(), k.pedicel.p_KP_K.x());
  for (int it = 0; it < 8; ++it) {
    const PedicelVec f = pedicelRates(k, g, y);
    const Eigen::Matrix3d J = pedicelJacobian(k, y).block<3, 3>(3, 0);
    const Eigen::Vector3d step = J.partialPivLu().solve(f.tail<3>());
    if (!step.allFinite()) return false;
    y.head<3>() -= step;
  }
  const PedicelVec f = pedicelRates(k, g, y);
  *y_eq = y;
  return f.tail<3>().norm() <= 1e-9 * g_norm;
}

// The Hessians H^k of the acceleration rows k at y_eq, by central differences of the analytic
// Jacobian (symmetrised).
void hessians(const KernelModel& k, const PedicelVec& y_eq, const PedicelVec& scale,
              PedicelMat* H) {
  for (int j = 0; j < 6; ++j) {
    const double h = 1e-5 * scale[j];
    PedicelVec yp = y_eq, ym = y_eq;
    yp[j] += h;
    ym[j] -= h;
    const PedicelMat dJ = (pedicelJacobian(k, yp) - pedicelJacobian(k, ym)) / (2.0 * h);
    for (int r = 0; r < 3; ++r) H[r].col(j) = dJ.row(3 + r).transpose();
  }
  for (int r = 0; r < 3; ++r) H[r] = (0.5 * (H[r] + H[r].transpose())).eval();
}

// error_bounded and error_secular of p (see the validity bound above) from the Hessians H.
void modalErrorGains(const PedicelMat* H, PedicelPropagator* p) {
  p->error_bounded.setZero();
  p->error_secular.setZero();
  PedicelModeMat VtHV[3];  // V_a^T H^k V_b
  for (int r = 0; r < 3; ++r) VtHV[r] = p->V.transpose() * H[r].cast<std::complex<double>>() * p->V;
  for (int m = 0; m < 6; ++m) {
    for (int a = 0; a < 6; ++a) {
      for (int b = 0; b < 6; ++b) {
        std::complex<double> w(0.0, 0.0);
        for (int r = 0; r < 3; ++r) w += 0.5 * p->V_inv(m, 3 + r) * VtHV[r](a, b);
        const double den = std::abs(p->lambda[a] + p->lambda[b] - p->lambda[m]);
        const double bounded =
            den > 0.0 ? 2.0 * std::abs(w) / den : std::numeric_limits<double>::infinity();
        for (int j = 0; j < 6; ++j) {
          const double to_state = kHigherOrderFactor * p->abs_V(j, m) / (j < 3 ? 1e-2 : 1.0);
          p->error_bounded(j, 6 * a + b) += to_state * bounded;
          p->error_secular(j, 6 * a + b) += to_state * std::abs(w);
        }
      }
    }
  }
}

// The remainder bound n_k <= E^T C_k E of the rates k = 3..5 over the envelope E.
Eigen::Vector3d remainderBound(const PedicelPropagator& p, const PedicelVec& E) {
  return Eigen::Vector3d(E.dot(p.curvature[0] * E), E.dot(p.curvature[1] * E),
                         E.dot(p.curvature[2] * E));
}

// Eigendecomposition and the bounds of a class whose equilibrium is y_eq.
void buildModes(const KernelModel& k, const PedicelVec& y_eq, PedicelPropagator* p) {
  const PedicelMat A = pedicelJacobian(k, y_eq);
  // Balanced as the tooth: positions scaled by the stiffest rate.
  const double w_max = std::sqrt(std::max(A.block<3, 3>(3, 0).cwiseAbs().maxCoeff(), 1.0));
  VecX s = VecX::Ones(6);
  s.head<3>().setConstant(w_max);
  Eigen::VectorXcd lambda;
  Eigen::MatrixXcd V, V_inv;
  if (!decomposeStateMatrix(A, s, &lambda, &V, &V_inv)) return;
  double rate_max = 0.0, re_max = 0.0;
  for (int i = 0; i < 6; ++i) {
    rate_max = std::max(rate_max, std::abs(lambda[i]));
    re_max = std::max(re_max, lambda[i].real());
  }
  if (!(rate_max > 0.0) || re_max > 1e-9 * rate_max) return;  // a growing mode: no closed form
  for (int i = 0; i < 6; ++i)  // rounding of an undamped mode may not make it grow
    lambda[i] = std::complex<double>(std::min(lambda[i].real(), 0.0), lambda[i].imag());
  p->lambda = lambda;
  p->V = V;
  p->V_inv = V_inv;
  p->abs_V = V.cwiseAbs();
  double im_max = 0.0;
  for (int i = 0; i < 6; ++i) im_max = std::max(im_max, std::abs(lambda[i].imag()));
  p->min_period_s = im_max > 0.0 ? kTwoPi / im_max : kTwoPi / rate_max;
  const Vec2 r = rotated(y_eq[2], k.pedicel.p_KP_K);
  const double ell = (y_eq.head<2>() + r - k.pedicel.p_WA_W).norm() + k.pedicel.p_KP_K.norm();
  PedicelVec scale;
  scale << ell, ell, 1.0, rate_max * ell, rate_max * ell, rate_max;
  p->inv_scale = scale.cwiseInverse();
  PedicelMat H[3];
  hessians(k, y_eq, scale, H);
  for (int r = 0; r < 3; ++r) p->curvature[r] = (0.5 * kHigherOrderFactor) * H[r].cwiseAbs();
  modalErrorGains(H, p);
  for (int j = 0; j < 6; ++j) p->force_slope[j] = k.mass_kg * A.block<2, 1>(3, j).norm();
  double moment = 0.0;
  p->force_eq_N = pedicelStemForce(k, y_eq, &moment).norm();
  p->valid = p->V.allFinite() && p->V_inv.allFinite() && p->error_secular.allFinite();
}

}  // namespace

PedicelMat pedicelJacobian(const KernelModel& k, const PedicelVec& y) {
  PedicelMat A = PedicelMat::Zero();
  A.block<3, 3>(0, 3).setIdentity();
  const PedicelModel& p = k.pedicel;
  const Vec2 r = rotated(y[2], p.p_KP_K);
  const Vec2 vP = y.segment<2>(3) + y[5] * perpOf(r);
  const Vec2 d = y.head<2>() + r - p.p_WA_W;
  const double len = d.norm();
  if (!(len > 0.0)) return A;
  const Vec2 n = d / len;
  const Eigen::Matrix2d Pn = Eigen::Matrix2d::Identity() - n * n.transpose();
  const double T = p.stiffness_Npm * (len - p.rest_length_m) + p.damping_Nspm * n.dot(vP);
  // dF/dd and dF/dvP of F = -T n; then the chain through d(c, psi) and vP(psi, v, omega).
  const Eigen::RowVector2d dT_dd =
      p.stiffness_Npm * n.transpose() + p.damping_Nspm * (vP.transpose() * Pn) / len;
  const Eigen::Matrix2d dF_dd = -n * dT_dd - (T / len) * Pn;
  const Eigen::Matrix2d dF_dv = -p.damping_Nspm * n * n.transpose();
  Eigen::Matrix<double, 2, 6> dF;  // over [c_x, c_y, psi, v_x, v_y, omega]
  dF.block<2, 2>(0, 0) = dF_dd;
  dF.col(2) = dF_dd * perpOf(r) - y[5] * (dF_dv * r);
  dF.block<2, 2>(0, 3) = dF_dv;
  dF.col(5) = dF_dv * perpOf(r);
  const Vec2 F = -T * n;
  A.block<2, 6>(3, 0) = dF / k.mass_kg;
  for (int j = 0; j < 6; ++j) A(5, j) = crossOf(r, dF.col(j)) / k.inertia_kgm2;
  A(5, 2) += crossOf(perpOf(r), F) / k.inertia_kgm2;
  return A;
}

bool samePedicelClass(const PedicelPropagator& p, const KernelModel& k, const Vec2& g) {
  const PedicelModel& s = k.pedicel;
  return p.mass_kg == k.mass_kg && p.inertia_kgm2 == k.inertia_kgm2 && p.p_KP_K == s.p_KP_K &&
         p.stiffness_Npm == s.stiffness_Npm && p.damping_Nspm == s.damping_Nspm &&
         std::abs(p.rest_length_m - s.rest_length_m) <=
             kRestLengthClassTolerance * p.rest_length_m &&
         p.detachment_force_N == s.detachment_force_N && p.gravity_mps2 == g;
}

PedicelPropagator buildPedicelPropagator(const KernelModel& k, const Vec2& gravity_mps2) {
  PedicelPropagator p;
  p.mass_kg = k.mass_kg;
  p.inertia_kgm2 = k.inertia_kgm2;
  p.p_KP_K = k.pedicel.p_KP_K;
  p.stiffness_Npm = k.pedicel.stiffness_Npm;
  p.damping_Nspm = k.pedicel.damping_Nspm;
  p.rest_length_m = k.pedicel.rest_length_m;
  p.detachment_force_N = k.pedicel.detachment_force_N;
  p.gravity_mps2 = gravity_mps2;
  PedicelVec y_eq;
  if (!solveEquilibrium(k, gravity_mps2, &y_eq)) return p;
  p.p_AC_W = y_eq.head<2>() - k.pedicel.p_WA_W;
  p.down_W = gravity_mps2 / gravity_mps2.norm();
  p.psi_eq_rad = y_eq[2];
  buildModes(k, y_eq, &p);
  return p;
}

PedicelAmplitude pedicelAmplitude(const PedicelPropagator& p, const KernelModel& k,
                                  const PedicelVec& y) {
  PedicelAmplitude a;
  a.p_WC_eq_W =
      k.pedicel.p_WA_W + p.p_AC_W + (k.pedicel.rest_length_m - p.rest_length_m) * p.down_W;
  a.psi_branch_rad = p.psi_eq_rad + kTwoPi * std::round((y[2] - p.psi_eq_rad) / kTwoPi);
  const Eigen::Vector3d q(y[0] - a.p_WC_eq_W.x(), y[1] - a.p_WC_eq_W.y(), y[2] - a.psi_branch_rad);
  const Eigen::Vector3d qd = y.tail<3>();
  modalAmplitudes(p.V_inv, 3, q, qd, a.c);
  PedicelVec c_abs;
  for (int i = 0; i < 6; ++i) c_abs[i] = std::abs(a.c[i]);
  a.envelope = p.abs_V * c_abs;
  a.rho = a.envelope.cwiseProduct(p.inv_scale).maxCoeff();
  return a;
}

double pedicelClosedFormSpan(const PedicelPropagator& p, const PedicelAmplitude& a, double tol) {
  if (!p.valid || !(a.rho < kLinearRegime)) return 0.0;
  const Eigen::Vector3d n = remainderBound(p, a.envelope);
  const double force_N =
      p.force_eq_N + p.force_slope.dot(a.envelope) + p.mass_kg * n.head<2>().norm();
  if (!(force_N < p.detachment_force_N)) return 0.0;
  PedicelVec c_abs;
  for (int i = 0; i < 6; ++i) c_abs[i] = std::abs(a.c[i]);
  Eigen::Matrix<double, 36, 1> q;  // |c_i||c_j|
  for (int i = 0; i < 6; ++i) q.segment<6>(6 * i) = c_abs[i] * c_abs;
  const PedicelVec bounded = p.error_bounded * q, secular = p.error_secular * q;
  double span = std::numeric_limits<double>::infinity();
  for (int j = 0; j < 6; ++j)
    if (!(bounded[j] <= tol)) span = std::min(span, secular[j] > 0.0 ? tol / secular[j] : 0.0);
  return span;
}

PedicelVec propagatePedicel(const PedicelPropagator& p, const PedicelAmplitude& a, double h_s) {
  PedicelModes c_h;
  Eigen::Vector3d q, qd;
  modalEvaluate(p.lambda, p.V, 3, h_s, a.c, c_h, q, qd);
  PedicelVec y;
  y << a.p_WC_eq_W.x() + q[0], a.p_WC_eq_W.y() + q[1], a.psi_branch_rad + q[2], qd;
  return y;
}

}  // namespace internal
}  // namespace threshing_sim
