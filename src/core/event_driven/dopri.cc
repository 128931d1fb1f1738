// The event-driven integrator's trial step: one Dormand-Prince 5(4) step (tableau kA, kC, kE
// in internal.h) with its error estimate; free teeth advanced exactly, teeth in contact optionally
// by the Lawson split (modal_split.cc).
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace event_driven {

namespace {

// Marks in ws.ed.tooth_exact the teeth that the step from the data's time may advance exactly:
// the option is on, the drum is at its target speed (no ramp, so dOmega/dt = 0 all through the
// step), the tooth has modes and a valid propagator, and none of its pairs is in contact (a
// separated pair exerts no force within a step). Returns the number of teeth marked.
int markExactTeeth(const Ctx& c) {
  const Model& m = c.m;
  Workspace& ws = c.ws;
  const int T = static_cast<int>(m.teeth.size());
  ws.ed.tooth_exact.assign(T, 0);
  if (!m.integrator.exact_free_teeth || c.d.omega_radps != c.d.omega_target_radps) return 0;
  if (ws.ed.prop.size() != static_cast<size_t>(T)) ws.ed.prop.resize(T);
  // Teeth with a mode and a usable propagator at this drum speed.
  int marked = 0;
  for (int k = 0; k < T; ++k) {
    if (m.teeth[k].n_modes == 0) continue;
    if (!buildToothPropagator(m, k, c.d.omega_radps, &ws.ed.prop[k])) continue;
    ws.ed.tooth_exact[k] = 1;
    ++marked;
  }
  // Minus the teeth in contact.
  for (const PairId& p : ws.candidates) {
    if (p.kind != PairKind::kToothKernel || !ws.ed.tooth_exact[p.a]) continue;
    if (isActive(ws.memory[pairKey(p)])) {
      ws.ed.tooth_exact[p.a] = 0;
      --marked;
    }
  }
  return marked;
}

// Stage state y0 + h sum_j a_sj k_j of stage s into ws.ed.zz, ws.ed.uu, component by component
// (plain loops: the vectors are short, where Eigen's dynamic-size expressions cost more than
// the arithmetic).
void stageState(const Ctx& c, int s, double h, const VecX& z0, const VecX& u0) {
  const int n = c.m.n_dof;
  Workspace& ws = c.ws;
  VecX& zz = ws.ed.zz;
  VecX& uu = ws.ed.uu;
  const double* k_j[6];
  double a_j[6];
  int n_j = 0;
  for (int j = 0; j < s; ++j) {
    if (kA[s][j] == 0.0) continue;
    k_j[n_j] = ws.ed.rk_k[j].data();
    a_j[n_j++] = h * kA[s][j];
  }
  const double* z0p = z0.data();
  const double* u0p = u0.data();
  for (int i = 0; i < n; ++i) {
    double zi = z0p[i], ui = u0p[i];
    for (int j = 0; j < n_j; ++j) {
      zi += a_j[j] * k_j[j][i];
      ui += a_j[j] * k_j[j][n + i];
    }
    zz[i] = zi;
    uu[i] = ui;
  }
}

// Stage s's derivative [u; udot] into ws.ed.rk_k[s]; the contact impulses (ws.ed.imp_n,
// ws.ed.imp_t over the first n_pairs geoms) and drum torque impulse integrated with the
// 5th-order weights (b = row 7 of A), from the stage's forces ws.ed.fn, ws.ed.ft and torque.
void storeStage(const Ctx& c, int s, double h, int n_pairs, double torque) {
  const int n = c.m.n_dof;
  Workspace& ws = c.ws;
  const VecX& uu = ws.ed.uu;
  const VecX& udot = ws.ed.udot;
  double* k_s = ws.ed.rk_k[s].data();
  for (int i = 0; i < n; ++i) {
    k_s[i] = uu[i];
    k_s[n + i] = udot[i];
  }
  // Contact impulses and drum torque integrated with the 5th-order weights (b = row 7 of A).
  if (s < 6 && kA[6][s] != 0.0) {
    const double b = h * kA[6][s];
    for (int i = 0; i < n_pairs; ++i) {
      ws.ed.imp_n[i] += b * ws.ed.fn[i];
      ws.ed.imp_t[i] += b * ws.ed.ft[i];
    }
    ws.ed.torque_impulse += b * torque;
  }
}

// Free teeth (marked by markExactTeeth): the exact end state replaces the Runge-Kutta one in
// (z1, u1); their dofs are left out of the error estimate (ws.ed.own_error = 0).
void propagateExactTeeth(const Ctx& c, int n_exact, double h, const VecX& z0, const VecX& u0,
                         VecX* z1, VecX* u1) {
  Workspace& ws = c.ws;
  std::vector<std::uint8_t>& own_error = ws.ed.own_error;  // per dof: in the error estimate
  if (n_exact == 0) return;
  for (size_t k = 0; k < c.m.teeth.size(); ++k) {
    if (!ws.ed.tooth_exact[k]) continue;
    const ToothModel& tm = c.m.teeth[k];
    propagateTooth(&ws.ed.prop[k], h, z0.segment(tm.dof_offset, tm.n_modes),
                   u0.segment(tm.dof_offset, tm.n_modes), z1->segment(tm.dof_offset, tm.n_modes),
                   u1->segment(tm.dof_offset, tm.n_modes));
    std::fill_n(own_error.begin() + tm.dof_offset, tm.n_modes, 0);
  }
}

// Error estimate of the step of length h from (z0, u0) (stages in ws.ed.rk_k, the Runge-Kutta
// end state in ws.ed.zz, ws.ed.uu) scaled per component: positions by 1e-2 m, velocities by
// 1 m/s; the RMS over the components it covers (ws.ed.own_error).
double errorNorm(const Ctx& c, double h, const VecX& z0, const VecX& u0) {
  const int n = c.m.n_dof;
  const Workspace& ws = c.ws;
  const VecX& zz = ws.ed.zz;
  const VecX& uu = ws.ed.uu;
  const std::vector<std::uint8_t>& own_error = ws.ed.own_error;
  double e2 = 0.0;
  int n_err = 0;
  for (int i = 0; i < 2 * n; ++i) {
    const std::uint8_t own = own_error[i < n ? i : i - n];
    if (!own) continue;
    ++n_err;
    double ei = 0.0;
    if (own == 2) {
      ei = ws.ed.err_split[i];  // the modal split's estimate (already times h)
    } else {
      for (int s = 0; s < 7; ++s) ei += kE[s] * ws.ed.rk_k[s][i];
      ei *= h;
    }
    const double y = i < n ? std::max(std::abs(z0[i]), std::abs(zz[i]))
                           : std::max(std::abs(u0[i - n]), std::abs(uu[i - n]));
    const double scale = c.m.integrator.tolerance * ((i < n ? 1e-2 : 1.0) + y);
    e2 += (ei / scale) * (ei / scale);
  }
  return std::sqrt(e2 / std::max(1, n_err));
}

}  // namespace

// One Dormand-Prince step of length h from (t0, y0 = [z; u]); y1 and its error estimate.
// Teeth marked by markExactTeeth take the exact solution of their free modal equations at the
// step end instead, and stay out of the error estimate (their stages affect no other body);
// teeth marked by beginModalSplit take the Lawson step of modal_split.cc, stages included.
bool dopriStep(const Ctx& c, double t0, double h, const VecX& z0, const VecX& u0, VecX* z1,
               VecX* u1, double* err, double* torque1) {
  const int n = c.m.n_dof;
  Workspace& ws = c.ws;
  ++ws.ed.trial_steps;
  for (auto& k : ws.ed.rk_k) k.resize(2 * n);
  ws.ed.rk_tmp.resize(2 * n);
  VecX& zz = ws.ed.zz;
  VecX& uu = ws.ed.uu;
  VecX& udot = ws.ed.udot;
  double torque = 0;
  const int n_pairs = static_cast<int>(ws.candidates.size());
  growTo(&ws.ed.imp_n, n_pairs);
  growTo(&ws.ed.imp_t, n_pairs);
  // Their copies (an event bracket's end, a graze probe's saved values) are assigned whole:
  // they grow with them (keeping their values), so that no assignment reallocates later.
  for (VecX* copy : {&ws.ed.imp_n_hi, &ws.ed.imp_t_hi, &ws.ed.imp_n_saved, &ws.ed.imp_t_saved})
    if (copy->size() != ws.ed.imp_n.size()) copy->conservativeResize(ws.ed.imp_n.size());
  ws.ed.imp_n.head(n_pairs).setZero();
  ws.ed.imp_t.head(n_pairs).setZero();
  ws.ed.torque_impulse = 0;
  zz.resize(n);
  uu.resize(n);
  // Free teeth advanced exactly; teeth in contact split (modal_split.cc).
  ws.ed.own_error.assign(n, 1);
  const int n_exact = markExactTeeth(c);
  const int n_split = beginModalSplit(c, h, z0, u0);
  for (int s = 0; s < 7; ++s) {
    stageState(c, s, h, z0, u0);
    if (n_split > 0) modalSplitStageState(c, s, h);
    if (!rhs(c, t0 + kC[s] * h, zz, uu, &udot, &torque, false, SeparatedPairs::kNone)) return false;
    storeStage(c, s, h, n_pairs, torque);
    if (n_split > 0) modalSplitStoreStage(c, s, c.d.omega_radps);
  }
  // Stage 7 is the 5th-order solution (FSAL).
  *z1 = zz;
  *u1 = uu;
  *torque1 = torque;
  propagateExactTeeth(c, n_exact, h, z0, u0, z1, u1);
  if (n_split > 0) modalSplitError(c, h);
  *err = errorNorm(c, h, z0, u0);
  return z1->allFinite() && u1->allFinite();
}

}  // namespace event_driven
}  // namespace internal
}  // namespace threshing_sim
