// Time stepping (docs/model.md §9): the velocity-level contact problem of a step: the free
// velocity (stage 3), the contact rows (stage 4), Newton's law targets (stage 5) and the
// impulses (stage 6).
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

// Stage 3: the free velocity: theta-method on the linear tooth equations, explicit kernel
// forces (the drum's acceleration over the step as the forcing).
void freeVelocity(TsStep* s) {
  const Model& m = s->m;
  const Data& d = *s->d;
  Workspace& ws = s->ws;
  const double h = s->h, th = m.integrator.theta;
  const int T = static_cast<int>(m.teeth.size());
  Drive forcing = s->mid;
  forcing.alpha_radps2 = (s->end.omega_radps - d.omega_radps) / h;
  smoothForces(m, d, ws.ts.z_mid, d.u, forcing, &ws.forces);
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0) continue;
    auto f = ws.forces.segment(tm.dof_offset, tm.n_modes);
    f.noalias() -=
        (h * (th - 0.5)) * (ws.ts.iteration_stiffness[k] * d.u.segment(tm.dof_offset, tm.n_modes));
  }
  ws.ts.u_free = d.u;
  for (int k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    if (tm.n_modes == 0) continue;
    ws.ts.u_free.segment(tm.dof_offset, tm.n_modes).noalias() +=
        h * (ws.ts.iteration_inverse[k] * ws.forces.segment(tm.dof_offset, tm.n_modes));
  }
  for (const KernelModel& k : m.kernels) {
    ws.ts.u_free.segment<2>(k.dof_offset) += h / k.mass_kg * ws.forces.segment<2>(k.dof_offset);
    ws.ts.u_free[k.dof_offset + 2] += h / k.inertia_kgm2 * ws.forces[k.dof_offset + 2];
  }
}

namespace {

// The residual spring's share of a compliant tooth contact's impulse (docs/model.md §9b):
// h (F^2/2) w_r with F = pn / h, a known impulse, into the free velocity (through the same
// iteration inverse as the contact impulses).
void addResidualImpulse(TsStep* s, const ContactGeom& g, double pn_Ns) {
  const double scale = s->h * residualForceFactor(g, pn_Ns / s->h);  // [N s]
  if (scale == 0.0) return;
  for (const BodyJac& side : g.side)
    applyInverseMass(s->m, &s->ws.ts.iteration_inverse, side.body, side.w_r, scale,
                     &s->ws.ts.u_free);
}

// The Hertz constant and approach speed of compliant candidate c's law this step: its
// episode's, or at its first step its own (the approach speed at the midpoint).
void compliantLawOf(TsStep* s, size_t c, double* K, double* v_in_mps) {
  const ContactGeom& g = s->ws.geoms[c];
  const PairMemory& mem = s->memoryOf(c);
  const bool first = mem.state == ContactState::kSeparated;
  *K = first ? g.hertz_K : mem.hertz_K;
  *v_in_mps = first ? -g.vn : mem.v_in_mps;
}

// The friction impulse a compliant row is expected to carry per unit of normal impulse [-]:
// its last step's ratio, or sliding (-mu sign vt) at its first step; within the cone.
double expectedFrictionRatio(TsStep* s, size_t c) {
  const ContactGeom& g = s->ws.geoms[c];
  const PairMemory& mem = s->memoryOf(c);
  const double mu = g.params->friction;
  if (mem.state == ContactState::kSeparated || !(mem.normal_force_N > 0.0))
    return g.vt > 0.0 ? -mu : (g.vt < 0.0 ? mu : 0.0);
  return std::clamp(mem.tangential_force_N / mem.normal_force_N, -mu, mu);
}

// Adds a compliant row's normal impulse dpn with its expected friction (r dpn) to u (if given);
// returns (when rate is given) the row's end gap rate per unit of dpn, w_n . W^-1 (w_n + r w_t).
void addCompliantImpulse(const TsStep& s, const ContactGeom& g, double dpn, double r, VecX* u,
                         double* rate = nullptr) {
  if (rate) *rate = 0.0;
  for (const BodyJac& side : g.side) {
    if (side.body < 0 || side.w_n.size() == 0) continue;
    const SmallVec w = side.w_n + r * side.w_t;
    if (u) applyInverseMass(s.m, &s.ws.ts.iteration_inverse, side.body, w, dpn, u);
    if (rate) *rate += weightedDot(s.m, &s.ws.ts.iteration_inverse, side.body, side.w_n, w);
  }
}

// One compliant row's force F >= 0 [N] with F = Phi(vn_mid(F)): Phi the law at the midpoint
// gap as a function of the gap rate, vn_mid = (vn_start + v0 + a h F) / 2 its midpoint rate,
// v0 the end rate without the row's own impulse, a >= 0 the end rate per unit of it. Phi falls
// with the rate, so the residual F - Phi(vn_mid(F)) rises with F, with a slope of at least 1:
// secant steps from the guess f_guess and its fixed-point image, kept inside the bracket of
// the residual's signs met so far (bisection where a step leaves it), find its one root
// however stiff the damping; a law that is linear in the rate (no series spring) takes two
// evaluations and a third to confirm.
double implicitCompliantForce(const Model& m, const ContactGeom& g, double K, double v_in_mps,
                              double v0_mps, double a_h, double f_guess) {
  auto residual = [&](double f) {
    const double vn_mid = 0.5 * (g.vn + v0_mps + a_h * f);
    return f - compliantNormalForceAt(g, g.gap_m, vn_mid, K, v_in_mps, m.hc_min_impact_speed_mps);
  };
  double lo = 0.0, hi = std::numeric_limits<double>::infinity();  // residual < 0 at lo, > 0 at hi
  double f0 = std::max(f_guess, 0.0), r0 = residual(f0);
  if (r0 == 0.0) return f0;
  if (f0 == 0.0 && r0 > 0.0) return 0.0;  // no compression at zero force: none at all
  (r0 < 0.0 ? lo : hi) = f0;
  double f1 = std::max(f0 - r0, 0.0);  // the fixed-point image Phi(vn_mid(f0))
  for (int it = 0; it < 60; ++it) {
    const double r1 = residual(f1);
    if (r1 == 0.0) return f1;
    if (r1 < 0.0)
      lo = std::max(lo, f1);
    else
      hi = std::min(hi, f1);
    if (r1 > 0.0 && f1 == 0.0) return 0.0;
    if (std::abs(r1) <= 1e-12 * f1 || hi - lo <= 1e-13 * hi) return f1;
    double next = r1 != r0 ? f1 - r1 * (f1 - f0) / (r1 - r0) : f1 - r1;
    if (!(next > lo && next < hi)) next = std::isfinite(hi) ? 0.5 * (lo + hi) : f1 - r1;
    f0 = f1, r0 = r1, f1 = std::max(next, 0.0);
  }
  return f1;
}

// Newton's method on n coupled compliant rows (row indices rows_i, 2 <= n <= kMaxCoupled):
// R_i(F) = F_i - Phi_i(vn_mid_i(F)), vn_mid_i = (vn_i + v0_i + h sum_j A_ij F_j) / 2, with v0 the
// free end rates and A_ij = w_n,i . W^-1 (w_n,j + r_j w_t,j) the end rate of row i per unit
// impulse of row j; the Jacobian I - (h/2) diag(Phi_i') A, Phi' by a forward difference (exact
// for a law linear in the rate), forces clamped at zero (a releasing contact). From the rows'
// first guesses it converges in a few iterations where Gauss-Seidel sweeps crawl (a kernel
// squeezed between two stiff contacts: nearly opposite normals). Returns false if it did not
// converge to 1e-12 of the largest force in 20 iterations (the rows are left as they were).
constexpr int kMaxCoupled = 8;
using CoupledMat =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCoupled, kMaxCoupled>;
using CoupledVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxCoupled, 1>;

bool newtonCompliantForces(TsStep* s, const int* rows_i, int n) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  const std::vector<MatX>* minv = &ws.ts.iteration_inverse;
  CoupledMat A(n, n), J(n, n);
  CoupledVec v0(n), F(n), R(n), dphi(n), K(n), v_in(n);
  for (int i = 0; i < n; ++i) {
    const ContactGeom& gi = ws.geoms[ws.active[rows_i[i]]];
    v0[i] = gi.wtilde_n;
    for (const BodyJac& a : gi.side) {
      if (a.body < 0 || a.w_n.size() == 0) continue;
      v0[i] += a.w_n.dot(ws.ts.u_free.segment(bodyDofOffset(m, a.body), a.w_n.size()));
    }
    for (int j = 0; j < n; ++j) {
      const ContactGeom& gj = ws.geoms[ws.active[rows_i[j]]];
      const double r = ws.ts.compliant_ratio[rows_i[j]];
      A(i, j) = 0.0;
      for (const BodyJac& a : gi.side)
        for (const BodyJac& b : gj.side)
          if (a.body >= 0 && a.body == b.body && a.w_n.size() > 0)
            A(i, j) += weightedDot(m, minv, a.body, a.w_n, b.w_n + r * b.w_t);
    }
    F[i] = ws.rows[rows_i[i]].lambda_n_fixed / s->h;
    compliantLawOf(s, ws.active[rows_i[i]], &K[i], &v_in[i]);
  }
  const double floor_mps = m.hc_min_impact_speed_mps;
  for (int it = 0; it < 20; ++it) {
    for (int i = 0; i < n; ++i) {
      const ContactGeom& g = ws.geoms[ws.active[rows_i[i]]];
      const double vm = 0.5 * (g.vn + v0[i] + s->h * A.row(i).dot(F));
      const double phi = compliantNormalForceAt(g, g.gap_m, vm, K[i], v_in[i], floor_mps);
      const double dv = 1e-7 * std::max(std::abs(vm), 1e-3);
      dphi[i] = (compliantNormalForceAt(g, g.gap_m, vm + dv, K[i], v_in[i], floor_mps) - phi) / dv;
      R[i] = F[i] - phi;
    }
    if (R.cwiseAbs().maxCoeff() <= 1e-12 * std::max(F.maxCoeff(), 1e-12)) {
      for (int i = 0; i < n; ++i) ws.rows[rows_i[i]].lambda_n_fixed = s->h * F[i];
      return true;
    }
    J = (-0.5 * s->h) * (dphi.asDiagonal() * A);
    J.diagonal().array() += 1.0;
    F = (F - Eigen::PartialPivLU<CoupledMat>(J).solve(R)).cwiseMax(0.0);
    if (!F.allFinite()) return false;
  }
  return false;
}

// Whether active row i shares a moving body with a rigid row.
bool sharesBodyWithRigidRow(const Workspace& ws, int i) {
  const ContactGeom& g = ws.geoms[ws.active[i]];
  for (size_t j = 0; j < ws.active.size(); ++j) {
    if (!ws.rows[j].normal_unknown) continue;
    const ContactGeom& r = ws.geoms[ws.active[j]];
    for (const BodyJac& a : g.side)
      for (const BodyJac& b : r.side)
        if (a.body >= 0 && a.body == b.body) return true;
  }
  return false;
}

// The compliant rows' forces over the step (docs/model.md §9): the Hertz-Hunt-Crossley law at
// the midpoint gap, its damping at the midpoint's gap rate (vn + vn_end) / 2. g.vn is the step
// start's rate; vn_end is the end's under the free velocity and the compliant impulses (normal,
// and friction at its expected ratio r): u_end = u_free + W^-1 sum_j h F_j (w_n + r_j w_t).
// The start's rate alone lags the damping by half a step (+3 % on the default strike's peak at
// 1e-6 s) and, explicit, amplifies a stiff squeeze. From the rows' first guesses (their last
// step's force, else the explicit law): a lone row is solved implicitly in its own impulse
// (implicitCompliantForce, no u_end needed), coupled rows by Newton's method
// (newtonCompliantForces), else (more than kMaxCoupled, or no convergence) row by row in
// Gauss-Seidel sweeps (a symmetric positive definite coupling: they converge, if slowly) until
// no force moves by 1e-9 of itself, at most 8.
void midpointCompliantForces(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  const int k = static_cast<int>(ws.active.size());
  if (k == 0) return;
  // A row on a body that a rigid row holds keeps the law at the start's rate: the rigid
  // reaction, unknown until the contact problem is solved, is not in u_end (without it, a
  // kernel wedged against a rigid bar would seem to yield to the compliant force).
  // Such rows are marked by a negative self rate.
  growTo(&ws.ts.compliant_ratio, k);
  growTo(&ws.ts.compliant_rate, k);
  int compliant = 0;
  for (int i = 0; i < k; ++i) {
    if (ws.rows[i].normal_unknown) continue;
    ws.ts.compliant_rate[i] = 0.0;
    if (sharesBodyWithRigidRow(ws, i)) {
      ws.ts.compliant_rate[i] = -1.0;
      double K, v_in;
      compliantLawOf(s, ws.active[i], &K, &v_in);
      ws.rows[i].lambda_n_fixed =
          s->h * compliantNormalForce(ws.geoms[ws.active[i]], K, v_in, m.hc_min_impact_speed_mps);
      continue;
    }
    ++compliant;
  }
  if (compliant == 0) return;
  const bool coupled = compliant > 1;
  for (int i = 0; i < k; ++i)
    if (!ws.rows[i].normal_unknown && ws.ts.compliant_rate[i] >= 0.0)
      ws.ts.compliant_ratio[i] = expectedFrictionRatio(s, ws.active[i]);
  // Coupled rows: Newton (Gauss-Seidel sweeps below if it fails or there are too many).
  if (coupled && compliant <= kMaxCoupled) {
    int rows_i[kMaxCoupled], n = 0;
    for (int i = 0; i < k; ++i)
      if (!ws.rows[i].normal_unknown && ws.ts.compliant_rate[i] >= 0.0) rows_i[n++] = i;
    if (newtonCompliantForces(s, rows_i, n)) return;
  }
  // Each row's self rate; the first guesses' impulses in u_end.
  VecX& u_end = ws.ts.u_end_guess;
  if (coupled) u_end = ws.ts.u_free;
  for (int i = 0; i < k; ++i) {
    if (ws.rows[i].normal_unknown || ws.ts.compliant_rate[i] < 0.0) continue;
    addCompliantImpulse(*s, ws.geoms[ws.active[i]], coupled ? ws.rows[i].lambda_n_fixed : 0.0,
                        ws.ts.compliant_ratio[i], coupled ? &u_end : nullptr,
                        &ws.ts.compliant_rate[i]);
    ws.ts.compliant_rate[i] = std::max(ws.ts.compliant_rate[i], 0.0);
  }
  const VecX& u = coupled ? u_end : ws.ts.u_free;
  for (int sweep = 0; sweep < 8; ++sweep) {
    bool moved = false;
    for (int i = 0; i < k; ++i) {
      if (ws.rows[i].normal_unknown || ws.ts.compliant_rate[i] < 0.0) continue;
      const ContactGeom& g = ws.geoms[ws.active[i]];
      double vn_end = g.wtilde_n;
      for (const BodyJac& side : g.side) {
        if (side.body < 0 || side.w_n.size() == 0) continue;
        vn_end += side.w_n.dot(u.segment(bodyDofOffset(m, side.body), side.w_n.size()));
      }
      const double a = ws.ts.compliant_rate[i], pn_old = ws.rows[i].lambda_n_fixed;
      const double v0 = vn_end - (coupled ? a * pn_old : 0.0);  // without the row's impulse
      double K, v_in;
      compliantLawOf(s, ws.active[i], &K, &v_in);
      const double pn = s->h * implicitCompliantForce(m, g, K, v_in, v0, a * s->h, pn_old / s->h);
      ws.rows[i].lambda_n_fixed = pn;
      if (coupled) addCompliantImpulse(*s, g, pn - pn_old, ws.ts.compliant_ratio[i], &u_end);
      moved = moved || std::abs(pn - pn_old) > 1e-9 * std::abs(pn);
    }
    if (!moved || !coupled) break;
  }
}

}  // namespace

// Stage 4: the active contacts, closed at the midpoint, as rows of the contact problem. Rigid:
// an unknown normal impulse with Newton's law; compliant: the Hertz-Hunt-Crossley force over
// the step as a fixed normal impulse. A pressed rigid contact (sticking or slipping at the last
// step, past its impact step) stays active up to a slop of clearance (h zeno_velocity): the
// drift its depth keeping corrects must not open it. A contact that just bounced is not pressed.
void assembleContactRows(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  ws.active.clear();
  ws.rows.clear();
  const double keep_m = s->h * m.integrator.zeno_velocity_mps;
  for (size_t c = 0; c < ws.geoms.size(); ++c) {
    const ContactGeom& g = ws.geoms[c];
    PairMemory& mem = s->memoryOf(c);
    const bool pressed = g.params->law == ContactLaw::kRigid &&
                         (mem.state == ContactState::kStick || mem.state == ContactState::kSlip);
    if (g.gap_m > (pressed ? keep_m : 0.0)) continue;
    ContactRow row;
    row.mu = g.params->friction;
    if (g.params->law == ContactLaw::kRigid) {
      row.normal_unknown = true;
    } else {
      double K, v_in;
      compliantLawOf(s, c, &K, &v_in);
      row.normal_unknown = false;
      // The first guess of midpointCompliantForces.
      row.lambda_n_fixed =
          s->h * (mem.state != ContactState::kSeparated
                      ? mem.normal_force_N
                      : compliantNormalForce(g, K, v_in, m.hc_min_impact_speed_mps));
    }
    ws.active.push_back(static_cast<int>(c));
    ws.rows.push_back(row);
  }
  midpointCompliantForces(s);
  for (size_t i = 0; i < ws.active.size(); ++i)
    if (!ws.rows[i].normal_unknown)
      addResidualImpulse(s, ws.geoms[ws.active[i]], ws.rows[i].lambda_n_fixed);
}

// Stage 5: the free contact velocities b = W^T u_free (+ the restitution target e dg_N- of
// Newton's law 0 <= P_N _|_ dg_N+ + e dg_N- >= 0; slow approaches are plastic: Zeno).
void contactTargets(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  const int k = static_cast<int>(ws.active.size());
  growTo(&ws.b, 2 * k);
  growTo(&ws.b_offset, k);
  ws.b_offset.head(k).setZero();
  for (int i = 0; i < k; ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    double bn = g.wtilde_n, bt = g.wtilde_t;
    for (const BodyJac& side : g.side) {
      if (side.body < 0 || side.w_n.size() == 0) continue;
      const auto uf = ws.ts.u_free.segment(bodyDofOffset(m, side.body), side.w_n.size());
      bn += side.w_n.dot(uf);
      bt += side.w_t.dot(uf);
    }
    if (ws.rows[i].normal_unknown && g.vn < -m.integrator.zeno_velocity_mps)
      ws.b_offset[i] = g.params->restitution * g.vn;
    ws.b[2 * i] = bn + ws.b_offset[i];
    ws.b[2 * i + 1] = bt;
  }
}

namespace {

// A compliant force held over a coarse step can throw the bodies apart faster than they met
// (energy from nothing). No contact may separate faster than its approach speed (e <= 1): such
// a contact becomes a rigid row with that bound as its target. Returns whether any did.
bool capSeparationSpeeds(TsStep* s) {
  const Model& m = s->m;
  Workspace& ws = s->ws;
  bool capped = false;
  for (int i = 0; i < static_cast<int>(ws.active.size()); ++i) {
    if (ws.rows[i].normal_unknown) continue;
    const PairMemory& mem = s->memoryOf(ws.active[i]);
    const double v_in =
        mem.state == ContactState::kSeparated ? -ws.geoms[ws.active[i]].vn : mem.v_in_mps;
    // 1 % above the approach speed is the discretisation noise of an elastic (e = 1) contact.
    const double v_max = 1.01 * std::max(v_in, m.integrator.zeno_velocity_mps);
    if (ws.y[2 * i] <= v_max) continue;
    ws.rows[i].normal_unknown = true;
    ws.b_offset[i] = -v_max;
    ws.b[2 * i] -= v_max;
    capped = true;
  }
  return capped;
}

// Newton's law with friction can create energy. The impulses' work relative to the free
// motion is P.dg+ - 1/2 P.G P = P.(y - offset) - 1/2 P.(y - b); if it is positive, the step's
// impacts lose their restitution targets (to be solved again plastically, which cannot gain
// energy). Returns whether they did.
bool dropRestitutionIfWorkGained(Workspace* ws) {
  const int k = static_cast<int>(ws->active.size());
  double work = 0.0, restitution = 0.0;
  for (int i = 0; i < 2 * k; ++i) {
    const double off = (i % 2 == 0) ? ws->b_offset[i / 2] : 0.0;
    work += ws->lambda[i] * (ws->y[i] - off) - 0.5 * ws->lambda[i] * (ws->y[i] - ws->b[i]);
    if (i % 2 == 0 && ws->rows[i / 2].normal_unknown) restitution += std::abs(off);
  }
  if (!(restitution > 0.0 && work > 1e-15)) return false;
  for (int i = 0; i < k; ++i) {
    if (!ws->rows[i].normal_unknown || ws->b_offset[i] >= 0.0) continue;
    ws->b[2 * i] -= ws->b_offset[i];
    ws->b_offset[i] = 0.0;
  }
  return true;
}

}  // namespace

// Stage 6: the contact impulses: the complementarity problem per island, again with capped
// separation speeds, and again plastically if Newton's law gained energy.
void solveImpulses(TsStep* s) {
  Workspace& ws = s->ws;
  s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws);
  if (capSeparationSpeeds(s))
    s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws) && s->solved;
  if (dropRestitutionIfWorkGained(&ws))
    s->solved = solveContactIslands(s->m, &ws.ts.iteration_inverse, &ws) && s->solved;
}

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
