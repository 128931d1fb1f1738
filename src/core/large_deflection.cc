// threshing_sim core: the geometrically exact planar tooth (see large_deflection.h).

#include "threshing_sim/core/large_deflection.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "eigen_solvers.h"
#include "internal.h"
#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace {

// 8-point Gauss-Legendre rule on [-1, 1].
constexpr std::array<double, kLdGauss> kNode = {-0.96028985649753623168, -0.79666647741362673959,
                                                -0.52553240991632898582, -0.18343464249564980494,
                                                0.18343464249564980494,  0.52553240991632898582,
                                                0.79666647741362673959,  0.96028985649753623168};
constexpr std::array<double, kLdGauss> kWeight = {
    0.10122853629037625915, 0.22238103445337447054, 0.31370664587788728734, 0.36268378337836198297,
    0.36268378337836198297, 0.31370664587788728734, 0.22238103445337447054, 0.10122853629037625915};

template <int N>
double horner(const double (&c)[N], double x) {
  double v = c[N - 1];
  for (int k = N - 2; k >= 0; --k) v = v * x + c[k];
  return v;
}

// Monomial coefficients (in xi on [-1, 1]) of the Lagrange basis l_b on the Gauss nodes
// (degree 7) and of its integral from -1, S_b(xi) = int_{-1}^{xi} l_b (degree 8).
struct LagrangeTable {
  double l[kLdGauss][kLdGauss] = {};       // l_b(xi) = sum_k l[b][k] xi^k [-]
  double S[kLdGauss][kLdGauss + 1] = {};   // S_b(xi) = sum_k S[b][k] xi^k [-]
  double dl[kLdGauss][kLdGauss - 1] = {};  // l_b'(xi) = sum_k dl[b][k] xi^k [-]
  double S_node[kLdGauss][kLdGauss] = {};  // S_b(xi_j) at the nodes, [j][b] [-]
};

const LagrangeTable& lagrange() {
  static const LagrangeTable table = [] {
    LagrangeTable t;
    for (int b = 0; b < kLdGauss; ++b) {
      double c[kLdGauss] = {1.0};  // product polynomial, coefficients by power
      int deg = 0;
      for (int j = 0; j < kLdGauss; ++j) {
        if (j == b) continue;
        const double inv = 1.0 / (kNode[b] - kNode[j]);
        for (int k = deg + 1; k >= 0; --k) {  // c <- c (xi - x_j) / (x_b - x_j)
          const double shifted = k > 0 ? c[k - 1] : 0.0;
          const double same = k <= deg ? c[k] : 0.0;
          c[k] = (shifted - kNode[j] * same) * inv;
        }
        ++deg;
      }
      double at_minus_one = 0.0;
      for (int k = 0; k < kLdGauss; ++k) {
        t.l[b][k] = c[k];
        t.S[b][k + 1] = c[k] / (k + 1);
        at_minus_one += t.S[b][k + 1] * ((k + 1) % 2 == 0 ? 1.0 : -1.0);
        if (k > 0) t.dl[b][k - 1] = k * c[k];
      }
      t.S[b][0] = -at_minus_one;
    }
    for (int j = 0; j < kLdGauss; ++j)
      for (int b = 0; b < kLdGauss; ++b) t.S_node[j][b] = horner(t.S[b], kNode[j]);
    return t;
  }();
  return table;
}

double intervalLength(const ToothModel& t) { return t.length_m / t.ld_intervals; }
int nodeCount(const ToothModel& t) { return t.ld_intervals * kLdGauss; }

// Interval holding s and the local coordinate xi in [-1, 1] there.
void locate(const ToothModel& t, double s_m, int* k, double* xi) {
  const double h = intervalLength(t);
  const double s = std::clamp(s_m, 0.0, t.length_m);
  *k = std::min(t.ld_intervals - 1, static_cast<int>(s / h));
  *xi = std::clamp(2.0 * (s - *k * h) / h - 1.0, -1.0, 1.0);
}

inline Vec2 perpOf(const Vec2& v) { return Vec2(-v.y(), v.x()); }

}  // namespace

void ldShapes(const ToothModel& t, double s_m, double* phi, double* dphi) {
  const int n = t.n_modes;
  const double x = 2.0 * std::clamp(s_m, 0.0, t.length_m) / t.length_m - 1.0;
  // Legendre P_0..P_n by the three-term recurrence.
  double P[kLdMaxShapes + 2];
  P[0] = 1.0;
  P[1] = x;
  for (int k = 1; k < n; ++k) P[k + 1] = ((2 * k + 1) * x * P[k] - k * P[k - 1]) / (k + 1);
  for (int i = 1; i <= n; ++i) {
    // phi_i = (1/2) int_{-1}^x P_{i-1} = (P_i - P_{i-2}) / (2 (2i - 1)); phi_1 = (x + 1) / 2.
    phi[i - 1] = i == 1 ? 0.5 * (x + 1.0) : (P[i] - P[i - 2]) / (2.0 * (2 * i - 1));
    if (dphi != nullptr) dphi[i - 1] = P[i - 1] / t.length_m;
  }
}

void compileLargeDeflection(ToothModel* tooth) {
  ToothModel& t = *tooth;
  const int n = t.n_modes;
  if (n > kLdMaxShapes)
    throw std::invalid_argument("tooth.modes: must be <= " + std::to_string(kLdMaxShapes) +
                                " for a large_deflection tooth");
  t.ld_intervals = ldIntervalsFor(n);
  const double h = intervalLength(t);
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
  t.ld_root_T = Vec2(t.p_DR_D.dot(t.e1_D), t.p_DR_D.dot(t.e2_D));
  t.ld_node_s_m.resize(nodeCount(t));
  t.ld_node_mass_kg.resize(nodeCount(t));
  t.ld_Phi.resize(nodeCount(t), n);
  double phi[kLdMaxShapes], dphi[kLdMaxShapes];
  for (int k = 0; k < t.ld_intervals; ++k) {
    for (int j = 0; j < kLdGauss; ++j) {
      const int a = k * kLdGauss + j;
      t.ld_node_s_m[a] = (k + 0.5 * (kNode[j] + 1.0)) * h;
      t.ld_node_mass_kg[a] = t.mass_per_length_kgpm * 0.5 * h * kWeight[j];
      ldShapes(t, t.ld_node_s_m[a], phi, dphi);
      for (int i = 0; i < n; ++i) t.ld_Phi(a, i) = phi[i];
    }
  }
  // Stiffness: the curvatures P_{i-1}(x) / L are orthogonal, int = L / (2i - 1) / L^2.
  t.ld_K.setZero(n, n);
  for (int i = 0; i < n; ++i) t.ld_K(i, i) = EI / (t.length_m * (2 * i + 1));
  // Damping: modal damping 2 zeta omega of the linearised rod at rest, D = M0 V diag V^T M0
  // with K V = M0 V Omega^2, V^T M0 V = I.
  t.ld_D.setZero(n, n);
  t.ld_rotation_filter = MatX::Identity(n, n);
  if (n == 0) return;
  LdConfig cfg;
  const VecX q0 = VecX::Zero(n);
  ldConfigure(t, q0.data(), &cfg);
  LdMat M0;
  ldDynamics(t, cfg, q0.data(), q0.data(), 0.0, 0.0, &M0, nullptr, nullptr, nullptr);
  const MatX M0d = M0;
  Eigen::GeneralizedSelfAdjointEigenSolver<MatX> eig(t.ld_K, M0d);
  if (eig.info() != Eigen::Success)
    throw std::invalid_argument("tooth.modes: the large-deflection rod's modes did not converge");
  const MatX MV = M0d * eig.eigenvectors();
  const VecX omega_radps = eig.eigenvalues().cwiseMax(0.0).cwiseSqrt();
  t.ld_frequencies_Hz = omega_radps / (2.0 * kPi);
  const VecX c = 2.0 * t.damping_ratio * omega_radps;
  t.ld_D = MV * c.asDiagonal() * MV.transpose();
  // The shear-corrected rotation, mode by mode of the linearised rod (docs/model.md §9b): mode j
  // has the wave number beta_j = (omega_j^2 rho A / EI)^{1/4}. (Euler-Bernoulli: S = I.)
  if (t.section_rotation == ToothSectionRotation::kEulerBernoulli) return;
  VecX f(n);
  for (int j = 0; j < n; ++j) {
    const double beta_per_m =
        std::pow(std::max(eig.eigenvalues()[j], 0.0) * t.mass_per_length_kgpm / EI, 0.25);
    f[j] = sectionRotationFactor(t, beta_per_m);
  }
  t.ld_rotation_filter = eig.eigenvectors() * f.asDiagonal() * MV.transpose();
}

void ldConfigure(const ToothModel& t, const double* q, LdConfig* cfg) {
  const int n = t.n_modes;
  const double h = intervalLength(t);
  cfg->n = n;
  for (int a = 0; a < nodeCount(t); ++a) {
    double th = 0.0;
    for (int i = 0; i < n; ++i) th += t.ld_Phi(a, i) * q[i];
    cfg->theta[a] = th;
    cfg->cos_t[a] = std::cos(th);
    cfg->sin_t[a] = std::sin(th);
  }
  cfg->r_end[0] = t.ld_root_T;
  cfg->J_end[0].setZero(2, n);
  for (int k = 0; k < t.ld_intervals; ++k) {
    Vec2 r = cfg->r_end[k];
    LdJac J = cfg->J_end[k];
    for (int j = 0; j < kLdGauss; ++j) {
      const int a = k * kLdGauss + j;
      const double w = 0.5 * h * kWeight[j];
      r += w * Vec2(cfg->cos_t[a], cfg->sin_t[a]);
      for (int i = 0; i < n; ++i) {
        J(0, i) -= w * t.ld_Phi(a, i) * cfg->sin_t[a];
        J(1, i) += w * t.ld_Phi(a, i) * cfg->cos_t[a];
      }
    }
    cfg->r_end[k + 1] = r;
    cfg->J_end[k + 1] = J;
  }
}

Vec2 ldPoint(const ToothModel& t, const LdConfig& cfg, double s_m, Vec2* r_s, Vec2* r_ss,
             LdJac* jac) {
  const LagrangeTable& L = lagrange();
  const double h = intervalLength(t);
  int k = 0;
  double xi = 0;
  locate(t, s_m, &k, &xi);
  Vec2 r = cfg.r_end[k];
  if (jac != nullptr) *jac = cfg.J_end[k];
  if (r_s != nullptr) r_s->setZero();
  if (r_ss != nullptr) r_ss->setZero();
  for (int b = 0; b < kLdGauss; ++b) {
    const int a = k * kLdGauss + b;
    const Vec2 tan(cfg.cos_t[a], cfg.sin_t[a]);
    const double Sb = 0.5 * h * horner(L.S[b], xi);
    r += Sb * tan;
    if (jac != nullptr)
      for (int i = 0; i < cfg.n; ++i) jac->col(i) += (Sb * t.ld_Phi(a, i)) * perpOf(tan);
    if (r_s != nullptr) *r_s += horner(L.l[b], xi) * tan;
    if (r_ss != nullptr) *r_ss += (2.0 / h) * horner(L.dl[b], xi) * tan;
  }
  return r;
}

void ldPointMotion(const ToothModel& t, const LdConfig& cfg, const double* qd, double s_m, Vec2* v,
                   Vec2* a_out, Vec2* v_s) {
  const LagrangeTable& L = lagrange();
  const double h = intervalLength(t);
  int k = 0;
  double xi = 0;
  locate(t, s_m, &k, &xi);
  Vec2 vel = Vec2::Zero(), acc = Vec2::Zero(), vel_s = Vec2::Zero();
  for (int kk = 0; kk <= k; ++kk) {
    for (int b = 0; b < kLdGauss; ++b) {
      const int a = kk * kLdGauss + b;
      double thd = 0.0;
      for (int i = 0; i < cfg.n; ++i) thd += t.ld_Phi(a, i) * qd[i];
      const Vec2 tan(cfg.cos_t[a], cfg.sin_t[a]);
      const double w = kk < k ? 0.5 * h * kWeight[b] : 0.5 * h * horner(L.S[b], xi);
      vel += (w * thd) * perpOf(tan);
      acc -= (w * thd * thd) * tan;
      if (kk == k) vel_s += (horner(L.l[b], xi) * thd) * perpOf(tan);
    }
  }
  *v = vel;
  *a_out = acc;
  *v_s = vel_s;
}

void ldDynamics(const ToothModel& t, const LdConfig& cfg, const double* q, const double* qd,
                double omega, double alpha, LdMat* M, LdVec* f, double* kinetic_J,
                double* momentum) {
  const LagrangeTable& L = lagrange();
  const int n = cfg.n;
  const double h = intervalLength(t);
  double thd[kLdMaxNodes];
  for (int a = 0; a < nodeCount(t); ++a) {
    double v = 0.0;
    for (int i = 0; i < n; ++i) v += t.ld_Phi(a, i) * qd[i];
    thd[a] = v;
  }
  if (M != nullptr) M->setZero(n, n);
  LdVec Qin = LdVec::Zero(n);
  double T = 0.0, H = 0.0;
  Vec2 vel_end = Vec2::Zero(), acc_end = Vec2::Zero();  // at the interval start
  for (int k = 0; k < t.ld_intervals; ++k) {
    for (int j = 0; j < kLdGauss; ++j) {
      // Node g = (k, j): r, v, a and J by the interval's integration matrix.
      const int g = k * kLdGauss + j;
      Vec2 r = cfg.r_end[k], v = vel_end, acc = acc_end;
      LdJac J = cfg.J_end[k];
      for (int b = 0; b < kLdGauss; ++b) {
        const int a = k * kLdGauss + b;
        const double Sjb = 0.5 * h * L.S_node[j][b];
        const Vec2 tan(cfg.cos_t[a], cfg.sin_t[a]);
        const Vec2 nrm = perpOf(tan);
        r += Sjb * tan;
        v += (Sjb * thd[a]) * nrm;
        acc -= (Sjb * thd[a] * thd[a]) * tan;
        for (int i = 0; i < n; ++i) J.col(i) += (Sjb * t.ld_Phi(a, i)) * nrm;
      }
      const double m = t.ld_node_mass_kg[g];
      if (M != nullptr) M->noalias() += m * J.transpose() * J;
      // Inertial-frame velocity in the rotating frame's axes: Omega J r + v.
      const Vec2 V = omega * perpOf(r) + v;
      T += 0.5 * m * V.squaredNorm();
      H += m * (r.x() * V.y() - r.y() * V.x());
      // Absolute acceleration minus the part J q'': a + 2 Omega J v + alpha J r - Omega^2 r.
      const Vec2 X = acc + 2.0 * omega * perpOf(v) + alpha * perpOf(r) - omega * omega * r;
      Qin.noalias() += m * J.transpose() * X;
    }
    for (int b = 0; b < kLdGauss; ++b) {
      const int a = k * kLdGauss + b;
      const double w = 0.5 * h * kWeight[b];
      const Vec2 tan(cfg.cos_t[a], cfg.sin_t[a]);
      vel_end += (w * thd[a]) * perpOf(tan);
      acc_end -= (w * thd[a] * thd[a]) * tan;
    }
  }
  if (f != nullptr) {
    // The products into fixed-capacity storage: no heap temporary (the rod's right-hand side
    // runs every stage of every step).
    const Eigen::Map<const VecX> qv(q, n), qdv(qd, n);
    LdVec Kq(n), Dqd(n);
    Kq.noalias() = t.ld_K * qv;
    Dqd.noalias() = t.ld_D * qdv;
    *f = -Kq - Dqd - Qin;
  }
  if (kinetic_J != nullptr) *kinetic_J = T;
  if (momentum != nullptr) *momentum = H;
}

double ldElasticEnergy(const ToothModel& t, const double* q) {
  double e = 0.0;
  for (int i = 0; i < t.n_modes; ++i) e += 0.5 * t.ld_K(i, i) * q[i] * q[i];
  return e;
}

Vec2 ldStaticTipLoad(const ToothModel& t, const Vec2& P, VecX* q_out) {
  const int n = t.n_modes;
  VecX q = VecX::Zero(n);
  LdConfig cfg;
  const double h = intervalLength(t);
  // Load steps of the force, Newton at each: residual K q - J(L)^T P, tangent
  // K + Phi^T diag(w_a P . t_a) Phi (J(L) = sum_a w_a J t_a phi_a^T).
  constexpr int kSteps = 20;
  for (int step = 1; step <= kSteps; ++step) {
    const Vec2 Ps = P * (static_cast<double>(step) / kSteps);
    bool converged = false;
    for (int it = 0; it < 50 && !converged; ++it) {
      ldConfigure(t, q.data(), &cfg);
      VecX res = t.ld_K * q - cfg.J_end[t.ld_intervals].transpose() * Ps;
      MatX tangent = t.ld_K;
      for (int a = 0; a < nodeCount(t); ++a) {
        const double w = 0.5 * h * kWeight[a % kLdGauss];
        const double pt = Ps.x() * cfg.cos_t[a] + Ps.y() * cfg.sin_t[a];
        tangent.noalias() += (w * pt) * t.ld_Phi.row(a).transpose() * t.ld_Phi.row(a);
      }
      const VecX dq = tangent.partialPivLu().solve(res);
      q -= dq;
      converged = dq.norm() <= 1e-13 * (1.0 + q.norm());
    }
    if (!converged) return Vec2::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  ldConfigure(t, q.data(), &cfg);
  if (q_out != nullptr) *q_out = q;
  return cfg.r_end[t.ld_intervals] - (t.ld_root_T + Vec2(t.length_m, 0.0));
}

namespace internal {

const LdConfig& ldConfigOf(const Model& m, int tooth, const VecX& z, Workspace* ws) {
  const ToothModel& tm = m.teeth[tooth];
  if (ws->ld_cfg.size() != m.teeth.size() || ws->ld_cfg_q.size() != m.teeth.size()) {
    ws->ld_cfg.resize(m.teeth.size());
    ws->ld_cfg_q.assign(m.teeth.size(), VecX());
  }
  VecX& key = ws->ld_cfg_q[tooth];
  const double* q = z.data() + tm.dof_offset;
  const int n = tm.n_modes;
  if (key.size() == n && n > 0 && std::memcmp(key.data(), q, sizeof(double) * n) == 0)
    return ws->ld_cfg[tooth];
  key = z.segment(tm.dof_offset, n);
  ldConfigure(tm, q, &ws->ld_cfg[tooth]);
  return ws->ld_cfg[tooth];
}

const std::vector<MatX>* toothInverseMass(const Model& m, const VecX& z, Workspace* ws) {
  if (!m.has_large_deflection) return nullptr;
  if (ws->ld_minv_valid && ws->ld_minv_z.size() == z.size() &&
      std::memcmp(ws->ld_minv_z.data(), z.data(), sizeof(double) * z.size()) == 0)
    return &ws->ld_minv;
  ws->ld_minv.resize(m.teeth.size());
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    MatX& minv = ws->ld_minv[k];
    if (tm.beam_model != ToothBeamModel::kLargeDeflection) {
      minv.setIdentity(n, n);
      continue;
    }
    const LdConfig& cfg = ldConfigOf(m, static_cast<int>(k), z, ws);
    LdMat M;
    const double* q = z.data() + tm.dof_offset;
    ldDynamics(tm, cfg, q, q, 0.0, 0.0, &M, nullptr, nullptr, nullptr);
    minv.resize(n, n);
    minv = M.llt().solve(LdMat::Identity(n, n));
  }
  ws->ld_minv_z = z;
  ws->ld_minv_valid = true;
  return &ws->ld_minv;
}

void updateLdIterationMatrices(const Model& m, const VecX& z_mid, double h, Workspace* ws) {
  if (!m.has_large_deflection) return;
  const double th = m.integrator.theta;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.beam_model != ToothBeamModel::kLargeDeflection || tm.n_modes == 0) continue;
    const LdConfig& cfg = ldConfigOf(m, static_cast<int>(k), z_mid, ws);
    LdMat M;
    const double* q = z_mid.data() + tm.dof_offset;
    ldDynamics(tm, cfg, q, q, 0.0, 0.0, &M, nullptr, nullptr, nullptr);
    // Factorised and inverted in fixed-capacity storage (no heap temporary), then copied into
    // the workspace's matrices (sized for the tooth by the step's set-up).
    const LdMat W = M + (h * th) * tm.ld_D + (h * h * th * th) * tm.ld_K;
    ws->ts.iteration_matrix[k] = W;
    const Eigen::PartialPivLU<LdMat> lu(W);
    const LdMat W_inv = lu.inverse();
    ws->ts.iteration_inverse[k] = W_inv;
  }
}

}  // namespace internal
}  // namespace threshing_sim
