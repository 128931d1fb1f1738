// threshing_sim core: the residual flexibility of the truncated modes over the drum's reachable
// speeds (docs/model.md §9b), so that a drum speed change costs an interpolation, never a
// factorisation, inside a step.
//
// It is a smooth (rational) function of u = Omega^2, with poles at negative u only (the rotating
// tooth stiffens for R >= 0): it is interpolated in u at Chebyshev-Lobatto nodes on panels
// covering [0, speed_bound^2]. A panel takes 3, 5, 9 or 17 nested nodes, each level accepted
// when the one before predicted its new nodes to kTableTolerance of the static flexibility (or
// to 10 x the static solve's rounding, measured at rest against the closed form, if larger:
// ~1e-10 of it in x86 long double, ~1e-6 where long double is double, e.g. under valgrind), or
// when that prediction error stops falling; panels that need more are halved.

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "eigen_solvers.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace {

constexpr int kFineNodes = 17;            // nodes of the finest level [-]
constexpr double kTableTolerance = 1e-8;  // accepted prediction error / static flexibility [-]
constexpr int kMaxPanelDepth = 10;        // halvings of [0, speed_bound^2] at most [-]

using Sample = Eigen::Matrix<double, kResidualPoints, 3>;  // columns ww, wt, tt

// The static and (unclamped) residual flexibility at u = Omega^2. The modal part
// Phi K(u)^-1 Phi^T needs no factorisation per speed: with K(u) = Lambda + u (K_G - I) and
// Lambda^-1/2 (K_G - I) Lambda^-1/2 = V diag(mu) V^T, K(u)^-1 = C diag(1 / (1 + u mu)) C^T,
// C = Lambda^-1/2 V, so it is sum_j a_sj b_sj / (1 + u mu_j) with a = Phi C, b = Phi' C at the
// points, evaluated once.
class ResidualSampler {
 public:
  ResidualSampler(const ToothModel& tooth, double drum_radius_m)
      : t_(tooth), statics_(tooth, drum_radius_m, kResidualPoints) {
    const int n = tooth.n_modes;
    MatX phi_s, dphi_s;
    evaluateModesOnGrid(t_, kResidualPoints, &phi_s, &dphi_s);
    const VecX scale = tooth.omega0_sq.cwiseSqrt().cwiseInverse();  // Lambda^-1/2
    const MatX S = scale.asDiagonal() * (tooth.K_G - MatX::Identity(n, n)) * scale.asDiagonal();
    const Eigen::SelfAdjointEigenSolver<MatX> eig(S);
    const MatX C = scale.asDiagonal() * eig.eigenvectors();
    mu_ = eig.eigenvalues();
    a_ = phi_s * C;
    b_ = dphi_s * C;
  }

  // Residual (static minus modal) at u; *static_out (if given) the static flexibility.
  Sample operator()(double u_radps2, Sample* static_out = nullptr) const {
    return at(std::sqrt(u_radps2), static_out);
  }

  // The same at drum speed omega_radps.
  Sample at(double omega, Sample* static_out = nullptr) const {
    const StationFlexibility exact = statics_(omega);
    if (static_out != nullptr) {
      for (int s = 0; s < kResidualPoints; ++s)
        static_out->row(s) << exact.ww[s], exact.wt[s], exact.tt[s];
    }
    const VecX g = (VecX::Ones(mu_.size()) + (omega * omega) * mu_).cwiseInverse();
    Sample r;
    for (int s = 0; s < kResidualPoints; ++s) {
      double ww = 0.0, wt = 0.0, tt = 0.0;
      for (int j = 0; j < g.size(); ++j) {
        ww += a_(s, j) * a_(s, j) * g[j];
        wt += a_(s, j) * b_(s, j) * g[j];
        tt += b_(s, j) * b_(s, j) * g[j];
      }
      r.row(s) << exact.ww[s] - ww, exact.wt[s] - wt, exact.tt[s] - tt;
    }
    return r;
  }

  const ToothModel& tooth() const { return t_; }

 private:
  const ToothModel& t_;
  StaticFlexibilitySolver statics_;  // the tooth's static flexibility
  VecX mu_;                          // mu_j [s^2]
  MatX a_;                           // Phi C at the points [m/N]^(1/2)
  MatX b_;                           // Phi' C at the points [1/(N m)]^(1/2)
};

// The panel table under construction.
struct TableBuild {
  std::vector<ResidualPanel> panels;
  std::vector<Sample> nodes;
  Eigen::RowVector3d scale;  // largest static flexibility entry of ww, wt, tt [m/N, 1/N, 1/(N m)]
  double error = 0;          // largest accepted prediction error / scale [-]
  double tolerance = kTableTolerance;  // kTableTolerance, or 10 x the static solve's rounding [-]
};

// The static solve's rounding, measured at rest against the closed form of docs/model.md §9b
// (w = x^3 / (3 EI), x^2 / (2 EI), x / EI at the points), over scale.
double roundingAtRest(const ToothModel& t, const Sample& at_rest, const Eigen::RowVector3d& scale) {
  const double EI = t.youngs_modulus_Pa * t.second_moment_m4;
  double worst = 0.0;
  for (int s = 0; s < kResidualPoints; ++s) {
    const double x = t.length_m * s / (kResidualPoints - 1);
    const Eigen::RowVector3d exact(x * x * x / (3 * EI), x * x / (2 * EI), x / EI);
    worst =
        std::max(worst, ((at_rest.row(s) - exact).cwiseAbs().array() / scale.array()).maxCoeff());
  }
  return worst;
}

// Error of the level-m interpolant (nodes v[j * 16 / (m - 1)]) at fine node idx, over scale.
double predictionError(const std::array<Sample, kFineNodes>& v, int m, int idx,
                       const Eigen::RowVector3d& scale) {
  std::array<double, kFineNodes> ell{};
  lobattoBasis(m, std::cos(kPi * idx / (kFineNodes - 1)), ell.data());
  Sample p = Sample::Zero();
  for (int j = 0; j < m; ++j) p += ell[j] * v[j * (kFineNodes - 1) / (m - 1)];
  return ((p - v[idx]).cwiseAbs().colwise().maxCoeff().array() / scale.array()).maxCoeff();
}

// Tabulates [u_lo, u_hi]: nested levels 3, 5, 9, 17 until one is predicted by the one before to
// the tolerance, else halves the panel.
void buildPanel(const ResidualSampler& sample, double u_lo, double u_hi, int depth,
                TableBuild* out) {
  std::array<Sample, kFineNodes> v;
  const double mid = 0.5 * (u_lo + u_hi), half = 0.5 * (u_hi - u_lo);
  auto at = [&](int idx) {
    v[idx] = sample(std::max(0.0, mid + half * std::cos(kPi * idx / (kFineNodes - 1))));
  };
  if (u_lo == 0.0 && depth == 0) {
    // The rest node first: its static flexibility is the scale of the errors, and it measures
    // the rounding the tolerance must stay above.
    Sample at_rest;
    v[16] = sample(0.0, &at_rest);
    out->scale = at_rest.cwiseAbs().colwise().maxCoeff();
    out->tolerance =
        std::max(kTableTolerance, 10 * roundingAtRest(sample.tooth(), at_rest, out->scale));
  } else {
    at(16);
  }
  for (int idx : {0, 8}) at(idx);
  int m = 3;
  double error = INFINITY;
  bool noise_floor = false;  // a level no better than the one before: rounding, not shape
  while (m < kFineNodes && !(error <= out->tolerance) && !noise_floor) {
    const int m2 = 2 * m - 1, step2 = (kFineNodes - 1) / (m2 - 1);
    const double previous = error;
    error = 0.0;
    for (int j = 1; j < m2; j += 2) {
      at(j * step2);
      error = std::max(error, predictionError(v, m, j * step2, out->scale));
    }
    noise_floor = error > 0.25 * previous;
    m = m2;
  }
  if (!(error <= out->tolerance) && !noise_floor && depth < kMaxPanelDepth) {
    buildPanel(sample, u_lo, mid, depth + 1, out);
    buildPanel(sample, mid, u_hi, depth + 1, out);
    return;
  }
  out->error = std::max(out->error, error);
  out->panels.push_back({u_lo, u_hi, m, static_cast<int>(out->nodes.size())});
  for (int j = 0; j < m; ++j) out->nodes.push_back(v[j * (kFineNodes - 1) / (m - 1)]);
}

// The unclamped residual at u = Omega^2 (within the table's range) from the table's nodes.
Sample tableAt(const TableBuild& table, double u_radps2) {
  size_t k = 0;
  while (k + 1 < table.panels.size() && u_radps2 > table.panels[k].u_hi_radps2) ++k;
  const ResidualPanel& p = table.panels[k];
  std::array<double, kFineNodes> ell{};
  lobattoBasis(p.n_nodes,
               (2.0 * u_radps2 - p.u_lo_radps2 - p.u_hi_radps2) / (p.u_hi_radps2 - p.u_lo_radps2),
               ell.data());
  Sample r = Sample::Zero();
  for (int j = 0; j < p.n_nodes; ++j) r += ell[j] * table.nodes[p.first_node + j];
  return r;
}

}  // namespace

void lobattoBasis(int n_nodes, double x, double* ell) {
  double sum = 0.0;
  for (int j = 0; j < n_nodes; ++j) {
    const double x_j = std::cos(kPi * j / (n_nodes - 1));
    if (x == x_j) {
      for (int k = 0; k < n_nodes; ++k) ell[k] = k == j ? 1.0 : 0.0;
      return;
    }
    const double w = ((j % 2 == 0) ? 1.0 : -1.0) * ((j == 0 || j == n_nodes - 1) ? 0.5 : 1.0);
    ell[j] = w / (x - x_j);
    sum += ell[j];
  }
  for (int j = 0; j < n_nodes; ++j) ell[j] /= sum;
}

namespace {

// A residual sample clamped point by point to positive semidefinite blocks.
StationFlexibility clamped(const Sample& r) {
  StationFlexibility f;
  f.ww = r.col(0);
  f.wt = r.col(1);
  f.tt = r.col(2);
  for (int s = 0; s < kResidualPoints; ++s) clampResidualBlock(&f.ww[s], &f.wt[s], &f.tt[s]);
  return f;
}

// The modes the residual subtracts: the tooth's own, or with a cut-off (residual_modes >
// n_modes, docs/model.md §9b) those of a copy compiled with residual_modes modes, in *wide.
const ToothModel& residualBasis(const ToothModel& tooth, double drum_radius_m, ToothModel* wide) {
  if (tooth.residual_modes <= tooth.n_modes) return tooth;
  *wide = tooth;
  wide->n_modes = tooth.residual_modes;
  compileTooth(drum_radius_m, wide);
  return *wide;
}

}  // namespace

StationFlexibility residualFlexibility(const ToothModel& tooth, double drum_radius_m,
                                       double omega_radps) {
  if (tooth.n_modes == 0) return clamped(Sample::Zero());
  ToothModel wide;
  const ToothModel& basis = residualBasis(tooth, drum_radius_m, &wide);
  return clamped(ResidualSampler(basis, drum_radius_m).at(omega_radps));
}

void compileResidual(double drum_radius_m, double omega_radps, double speed_bound_radps,
                     ToothModel* tooth) {
  ToothModel& t = *tooth;
  const int P = kResidualPoints;
  t.residual_omega_radps = omega_radps;
  t.residual_panels.clear();
  t.residual_table_error = 0.0;
  if (!t.static_correction || t.n_modes == 0) {
    t.residual_ww = t.residual_wt = t.residual_tt = VecX::Zero(P);
    t.residual_nodes_ww = t.residual_nodes_wt = t.residual_nodes_tt = MatX::Zero(P, 0);
    return;
  }
  // The table over [0, max(speed_bound, |omega|)^2] in Omega^2 (from the residual's basis: the
  // tooth's modes, or more when modes slower than the contact are left out of the residual),
  // then the residual at the scene's speed from it (within the table's tolerance of the static
  // solve, which it saves).
  ToothModel wide;
  const ResidualSampler sample(residualBasis(t, drum_radius_m, &wide), drum_radius_m);
  TableBuild build;
  const double bound = std::max(speed_bound_radps, std::abs(omega_radps));
  buildPanel(sample, 0.0, bound * bound, 0, &build);
  const int n = static_cast<int>(build.nodes.size());
  t.residual_nodes_ww.resize(P, n);
  t.residual_nodes_wt.resize(P, n);
  t.residual_nodes_tt.resize(P, n);
  for (int j = 0; j < n; ++j) {
    t.residual_nodes_ww.col(j) = build.nodes[j].col(0);
    t.residual_nodes_wt.col(j) = build.nodes[j].col(1);
    t.residual_nodes_tt.col(j) = build.nodes[j].col(2);
  }
  // The scene's speed from the table where it met its tolerance; else (a table stopped at its
  // noise floor or depth, e.g. a soft tooth whose residual basis changes fast with Omega^2) the
  // static solve at that speed.
  const StationFlexibility r =
      clamped(build.error <= build.tolerance ? tableAt(build, omega_radps * omega_radps)
                                             : sample.at(omega_radps));
  t.residual_ww = r.ww;
  t.residual_wt = r.wt;
  t.residual_tt = r.tt;
  t.residual_panels = build.panels;
  t.residual_table_error = build.error;
}

namespace {

// The panel of a compiled tooth's table over Omega^2 holding omega_radps^2 (clamped to the
// table's range), with its Lagrange basis at that speed in ell.
const ResidualPanel& panelAtSpeed(const ToothModel& t, double omega_radps, double* ell) {
  const std::vector<ResidualPanel>& panels = t.residual_panels;
  const double u = std::min(omega_radps * omega_radps, panels.back().u_hi_radps2);
  size_t k = 0;
  while (k + 1 < panels.size() && u > panels[k].u_hi_radps2) ++k;
  const ResidualPanel& p = panels[k];
  lobattoBasis(p.n_nodes,
               (2.0 * u - p.u_lo_radps2 - p.u_hi_radps2) / (p.u_hi_radps2 - p.u_lo_radps2), ell);
  return p;
}

// The block (ww, wt, tt) at table point s interpolated in Omega^2 by the basis ell of panel p,
// clamped to positive semidefinite.
void blockAtPoint(const ToothModel& t, const ResidualPanel& p, const double* ell, int s,
                  double block[3]) {
  block[0] = block[1] = block[2] = 0.0;
  for (int j = 0; j < p.n_nodes; ++j) {
    block[0] += ell[j] * t.residual_nodes_ww(s, p.first_node + j);
    block[1] += ell[j] * t.residual_nodes_wt(s, p.first_node + j);
    block[2] += ell[j] * t.residual_nodes_tt(s, p.first_node + j);
  }
  clampResidualBlock(&block[0], &block[1], &block[2]);
}

}  // namespace

void residualAtSpeed(const ToothModel& t, double omega_radps, double x_m, double* ww, double* wt,
                     double* tt) {
  if (omega_radps == t.residual_omega_radps || t.residual_panels.empty()) {
    *ww = residualAt(t.residual_ww, t.length_m, x_m);
    *wt = residualAt(t.residual_wt, t.length_m, x_m);
    *tt = residualAt(t.residual_tt, t.length_m, x_m);
    return;
  }
  std::array<double, kFineNodes> ell;
  const ResidualPanel& p = panelAtSpeed(t, omega_radps, ell.data());
  // The two points around x, each interpolated in u and clamped, then blended linearly in x.
  const int last = kResidualPoints - 1;
  const double pos = std::clamp(x_m / t.length_m, 0.0, 1.0) * last;
  const int s = std::min(static_cast<int>(pos), last - 1);
  const double f = pos - s;
  double block[2][3];
  for (int q = 0; q < 2; ++q) blockAtPoint(t, p, ell.data(), s + q, block[q]);
  *ww = (1 - f) * block[0][0] + f * block[1][0];
  *wt = (1 - f) * block[0][1] + f * block[1][1];
  *tt = (1 - f) * block[0][2] + f * block[1][2];
}

void residualWwAtSpeed(const ToothModel& t, double omega_radps, int first, int count, double* ww) {
  if (omega_radps == t.residual_omega_radps || t.residual_panels.empty()) {
    for (int i = 0; i < count; ++i) ww[i] = t.residual_ww[first + i];
    return;
  }
  std::array<double, kFineNodes> ell;
  const ResidualPanel& p = panelAtSpeed(t, omega_radps, ell.data());
  double block[3];
  for (int i = 0; i < count; ++i) {
    blockAtPoint(t, p, ell.data(), first + i, block);
    ww[i] = block[0];
  }
}

}  // namespace threshing_sim
