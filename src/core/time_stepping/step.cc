// Moreau-Jean time stepping (docs/model.md §9): fixed step h, theta-method for the smooth
// linear part, contact detection at the midpoint, one velocity-level complementarity problem
// per island with Newton's impact law (rigid) or the Hertz force as a fixed normal (compliant).
//
// This file: the step as its list of stages (timeSteppingStep), the drum and the iteration
// matrices at its start (stage 1), the clock (stage 8) and its end (stage 10). The other stages
// live in the files of this folder; context.h lists them.
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <vector>

#include "context.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

namespace {

// C and mu of each modal tooth for step h (TimeSteppingScratch::iteration_basis): built when h
// changes (the first step, a recovery's smaller steps), never for a new drum speed.
void updateIterationBasis(const Model& m, double h, Workspace* ws) {
  TimeSteppingScratch& ts = ws->ts;
  const size_t T = m.teeth.size();
  if (ts.iteration_basis_h == h && ts.iteration_basis.size() == T) return;
  const double th = m.integrator.theta;
  ts.iteration_basis.resize(T);
  ts.iteration_mu.resize(T);
  ts.iteration_scaled.resize(T);
  for (size_t k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    ts.iteration_scaled[k].resize(n, n);
    if (tm.beam_model == ToothBeamModel::kLargeDeflection || n == 0) continue;
    const VecX a = VecX::Ones(n) + (h * th) * tm.damping_coeff + (h * h * th * th) * tm.omega0_sq;
    const VecX a_inv_sqrt = a.cwiseSqrt().cwiseInverse();
    const MatX B = (h * h * th * th) * (tm.K_G - MatX::Identity(n, n));
    const Eigen::SelfAdjointEigenSolver<MatX> eig(a_inv_sqrt.asDiagonal() * B *
                                                  a_inv_sqrt.asDiagonal());
    ts.iteration_basis[k] = a_inv_sqrt.asDiagonal() * eig.eigenvectors();
    ts.iteration_mu[k] = eig.eigenvalues();
  }
  ts.iteration_basis_h = h;
}

// (I + h theta D + h^2 theta^2 K(Omega))^-1 per tooth, rebuilt only when Omega or h changes
// (a recovery crosses an interval with smaller steps).
void updateIterationMatrices(const Model& m, double omega, double h, Workspace* ws) {
  if (ws->ts.iteration_omega == omega && ws->ts.iteration_h == h &&
      ws->ts.iteration_inverse.size() == m.teeth.size())
    return;
  updateIterationBasis(m, h, ws);
  const double th = m.integrator.theta;
  const size_t T = m.teeth.size();
  ws->ts.iteration_inverse.resize(T);
  ws->ts.iteration_stiffness.resize(T);
  ws->ts.iteration_matrix.resize(T);
  for (size_t k = 0; k < T; ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    // K(Omega) = Lambda + Omega^2 (K_G - I), written into storage of a fixed size per tooth so
    // that a drum ramp (new Omega every step) allocates nothing.
    MatX& K = ws->ts.iteration_stiffness[k];
    K.resize(n, n);
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      // The rod's implicit part is its constant elastic stiffness; its mass depends on q, so
      // updateLdIterationMatrices builds the matrix at every step's midpoint.
      K = tm.ld_K;
      ws->ts.iteration_matrix[k].resize(n, n);
      ws->ts.iteration_inverse[k].resize(n, n);
      continue;
    }
    K = (omega * omega) * tm.K_G;
    K.diagonal().array() =
        (omega * omega) * (tm.K_G.diagonal().array() - 1.0) + tm.omega0_sq.array();
    MatX& W = ws->ts.iteration_matrix[k];
    W.resize(n, n);
    W = (h * h * th * th) * K;
    W.diagonal().array() += 1.0 + h * th * tm.damping_coeff.array();
    ws->ts.iteration_inverse[k].resize(n, n);
    if (n == 0) continue;
    // W^-1 = C diag(1 / (1 + Omega^2 mu)) C^T: products into storage of fixed size.
    const MatX& C = ws->ts.iteration_basis[k];
    MatX& scaled = ws->ts.iteration_scaled[k];
    for (int j = 0; j < n; ++j)
      scaled.col(j) = C.col(j) / (1.0 + omega * omega * ws->ts.iteration_mu[k][j]);
    ws->ts.iteration_inverse[k].noalias() = scaled * C.transpose();
  }
  ws->ts.iteration_omega = omega;
  ws->ts.iteration_h = h;
}

}  // namespace

// Stage 1: the drum over the step (midpoint for forces and contacts, end for the new state),
// the iteration matrices, and the energy and angular momentum at the start: those the previous
// step ended with if the state is still exactly that one (the energy is O(kernels) to compute
// and only needed when an episode begins or ends: computed later only then).
void beginStep(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  s->mid = driveAt(m, *d, 0.5 * s->h);
  s->end = driveAt(m, *d, s->h);
  updateIterationMatrices(m, s->mid.omega_radps, s->h, &s->ws);
  s->have_energy_before = s->ws.ts.end_values.lookup(*d, &s->energy_before, &s->H_before);
  if (!s->have_energy_before) s->H_before = angularMomentumOf(m, d->z, d->u, d->omega_radps);
  s->drive_work_before_J = d->stats.drive_work_J;
}

// Stage 8: the drive's work, Omega (change of the teeth's angular momentum - the contacts'
// angular impulse); then time and the drum advance, time kept on the grid of the model's step
// (no round-off drift).
void advanceClock(TsStep* s) {
  const Model& m = s->m;
  Data* d = s->d;
  const Workspace& ws = s->ws;
  double contact_angular_impulse = 0.0;
  for (int i = 0; i < static_cast<int>(ws.active.size()); ++i) {
    const ContactGeom& g = ws.geoms[ws.active[i]];
    if (g.pair.kind != PairKind::kToothKernel) continue;
    const Vec2& p = g.p0;
    contact_angular_impulse += -ws.lambda[2 * i] * (p.x() * g.n.y() - p.y() * g.n.x()) -
                               ws.lambda[2 * i + 1] * (p.x() * g.t.y() - p.y() * g.t.x());
    // A compliant force's residual spring (the impulse assembleContactRows added): h (F^2/2)
    // dR/dtheta with F = lambda_n_fixed / h.
    const double pn = ws.rows[i].lambda_n_fixed;
    contact_angular_impulse += s->h * residualForceFactor(g, pn / s->h) * g.residual_dtheta_mpNprad;
  }
  s->H_after = angularMomentumOf(m, d->z, d->u, s->end.omega_radps);
  d->stats.drive_work_J +=
      s->mid.omega_radps * (s->H_after - s->H_before - contact_angular_impulse);
  d->t_s = s->end.t_s;
  const double grid = m.integrator.dt_s;
  const double snapped = std::round(d->t_s / grid) * grid;
  if (std::abs(snapped - d->t_s) < 1e-6 * grid) d->t_s = snapped;
  d->theta_rad = s->end.theta_rad;
  d->omega_radps = s->end.omega_radps;
  d->alpha_radps2 = s->end.alpha_radps2;
  ++d->steps;
}

// Stage 10: pedicels that reached their detachment force break; the end values for the next
// step (it starts from the end energy with the pedicels as they were before this step's
// breaks: if one breaks, that energy is computed now, the pedicels put back meanwhile); the
// contacts published to the data.
void finishStep(TsStep* s) {
  Data* d = s->d;
  Workspace& ws = s->ws;
  if (!s->have_energy_after) ws.ts.attached_before = d->kernel_attached;
  updatePedicels(s->m, d);
  if (!s->have_energy_after && d->kernel_attached != ws.ts.attached_before) {
    std::swap(d->kernel_attached, ws.ts.attached_before);
    s->energyNetAfter();
    std::swap(d->kernel_attached, ws.ts.attached_before);
  }
  if (s->have_energy_after)
    ws.ts.end_values.store(*d, s->energy_after, s->H_after);
  else
    ws.ts.end_values.invalidate();
  publishContacts(d, &ws);
}

}  // namespace time_stepping

// One Moreau-Jean time step of length h.
StepStatus timeSteppingStep(const Model& m, Data* d, double h) {
  time_stepping::TsStep s{m, d, *d->ws, h, Drive{}, Drive{}};
  time_stepping::beginStep(&s);
  time_stepping::detectContacts(&s);
  time_stepping::freeVelocity(&s);
  time_stepping::assembleContactRows(&s);
  time_stepping::contactTargets(&s);
  time_stepping::solveImpulses(&s);
  time_stepping::applyImpulses(&s);
  time_stepping::advanceClock(&s);
  time_stepping::updateContactStates(&s);
  time_stepping::finishStep(&s);
  return s.solved ? StepStatus::kOk : StepStatus::kRecovered;
}

}  // namespace internal
}  // namespace threshing_sim
