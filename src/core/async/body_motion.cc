// Asynchronous core, stage "body motion": lone bodies between events, each on its own clock.
//   - a free kernel (no pedicel, or a broken one) flies a parabola with constant spin: exact;
//   - a kernel on its pedicel touching nothing: the exact propagator of its dynamics linearised
//     about its hanging equilibrium (pedicel_propagator.h) while the amplitude keeps the
//     linearisation error within the tolerance and the stem force below the detachment force;
//     beyond that its own adaptive Dormand-Prince 5(4) over its 3 dofs (6 states, fixed-size,
//     no allocation), with the error norm and tolerance of the global integrator, breaking the
//     pedicel at a step end as the global integrator does;
//   - a free tooth at constant drum speed: the exact solution of its linear modal equations. A
//     large-deflection rod has none (it is nonlinear): it is always integrated, in an island
//     of its own when it touches nothing (async_step.cc, toothNeedsIntegration).
#include <Eigen/Cholesky>

#include "async.h"
#include "threshing_sim/core/large_deflection.h"

namespace threshing_sim {
namespace internal {
namespace {

inline Vec2 rotated(double angle_rad, const Vec2& v) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y());
}

using Vec6 = PedicelVec;

// The kernel's rates on its pedicel (pedicel_propagator.cc, the law of pedicelForce).
inline Vec6 pedicelRhs(const KernelModel& k, const Vec2& g, const Vec6& y) {
  return pedicelRates(k, g, y);
}

// One Dormand-Prince step of length h from y0 with f0 = f(y0) given; returns the scaled RMS
// error (the global norm) and f1 = f(y1), the last stage (first same as last: the next step's
// f0, the same numbers as evaluating it again).
double pedicelDopri(const KernelModel& k, const Vec2& g, double tol, const Vec6& y0, const Vec6& f0,
                    double h, Vec6* y1, Vec6* f1) {
  Vec6 stage[7];
  stage[0] = f0;
  for (int s = 1; s < 7; ++s) {
    Vec6 y = y0;
    for (int j = 0; j < s; ++j)
      if (kA[s][j] != 0.0) y += h * kA[s][j] * stage[j];
    stage[s] = pedicelRhs(k, g, y);
    if (s == 6) *y1 = y;
  }
  *f1 = stage[6];
  double e2 = 0.0;
  for (int i = 0; i < 6; ++i) {
    double ei = 0.0;
    for (int s = 0; s < 7; ++s) ei += kE[s] * stage[s][i];
    ei *= h;
    const double y = std::max(std::abs(y0[i]), std::abs((*y1)[i]));
    const double scale = tol * ((i < 3 ? 1e-2 : 1.0) + y);
    e2 += (ei / scale) * (ei / scale);
  }
  return std::sqrt(e2 / 6.0);
}

Vec6 kernelState(const Data& d, const KernelModel& k) {
  Vec6 y;
  y.head<3>() = d.z.segment<3>(k.dof_offset);
  y.tail<3>() = d.u.segment<3>(k.dof_offset);
  return y;
}

void setKernelState(Data* d, const KernelModel& k, const Vec6& y) {
  d->z.segment<3>(k.dof_offset) = y.head<3>();
  d->u.segment<3>(k.dof_offset) = y.tail<3>();
}

// Free flight over dt: parabola under gravity, constant spin.
void freeFlight(const Model& m, Data* d, const KernelModel& k, double dt_s) {
  auto z = d->z.segment<3>(k.dof_offset);
  auto u = d->u.segment<3>(k.dof_offset);
  z.head<2>() += dt_s * u.head<2>() + (0.5 * dt_s * dt_s) * m.gravity_mps2;
  z[2] += dt_s * u[2];
  u.head<2>() += dt_s * m.gravity_mps2;
}

// Whether a kernel on its pedicel is at rest over the jump dt_s: with velocity v and
// acceleration a of any point, the state moves by at most |v| dt + |a| dt^2 / 2 and its
// velocity by |a| dt, which must stay below the error scales of the global norm (positions
// tolerance x 1e-2 m, velocities tolerance x 1 m/s). Such a kernel sleeps: its clock jumps.
// ratesAtRest takes the rates f(y), atRest computes them.
bool ratesAtRest(const KernelModel& k, double tol, const Vec6& f, double dt_s) {
  const double a = k.semi_axis_a_m;
  const double v = f.head<2>().norm() + a * std::abs(f[2]);
  const double acc = f.segment<2>(3).norm() + a * std::abs(f[5]);
  return v * dt_s + 0.5 * acc * dt_s * dt_s <= tol * 1e-2 && acc * dt_s <= tol;
}

bool atRest(const KernelModel& k, const Vec2& g, double tol, const Vec6& y, double dt_s) {
  return ratesAtRest(k, tol, pedicelRhs(k, g, y), dt_s);
}

// A state farther from the hanging equilibrium than this (centre offset over the stem's reach,
// speed over sqrt(k/m) times that reach) is far outside any closed form's validity: it is not
// even looked at (its class is not built) [-].
constexpr double kNearHanging = 0.1;

// The closed form of kernel i's class if its state y is near its hanging equilibrium (the
// class is found, or built, on first need: only kernels that come near it pay for one).
const PedicelPropagator* closedFormOf(const Model& m, AsyncState* as, int i, const Vec6& y) {
  int& cls = as->kernels[i].pedicel_class;
  if (cls == -1) return nullptr;
  const KernelModel& k = m.kernels[i];
  const PedicelModel& p = k.pedicel;
  const double g = m.gravity_mps2.norm(), p_m = p.p_KP_K.norm();
  if (!(g > 0.0) || !(p_m > 0.0)) {
    cls = -1;  // no unique hanging equilibrium
    return nullptr;
  }
  const double reach_m = p.rest_length_m + k.mass_kg * g / p.stiffness_Npm + p_m;
  const Vec2 c_hang = p.p_WA_W + (reach_m / g) * m.gravity_mps2;
  const double rate_ps = std::sqrt(p.stiffness_Npm / k.mass_kg);
  if ((y.head<2>() - c_hang).norm() > kNearHanging * reach_m ||
      y.segment<2>(3).norm() > kNearHanging * rate_ps * reach_m)
    return nullptr;
  if (cls < 0) {
    // Classes are few (kernels of a scene share their parameters): a linear search.
    for (size_t c = 0; c < as->pedicel_classes.size() && cls < 0; ++c)
      if (samePedicelClass(as->pedicel_classes[c], k, m.gravity_mps2)) cls = static_cast<int>(c);
    if (cls < 0) {
      as->pedicel_classes.push_back(buildPedicelPropagator(k, m.gravity_mps2));
      cls = static_cast<int>(as->pedicel_classes.size()) - 1;
    }
  }
  const PedicelPropagator& prop = as->pedicel_classes[cls];
  return prop.valid ? &prop : nullptr;
}

// What a lone kernel's clock failure names (FailureInfo::scope).
constexpr const char* kClockScope = "island scheme: a lone kernel's pedicel clock";

// Whether a lone kernel's clock ended finite (else the failure is recorded).
bool finiteClock(Data* d, const AsyncState& as, const Vec6& y) {
  if (y.allFinite()) return true;
  recordFailure(d, as, FailureCause::kNonFinite, kClockScope);
  return false;
}

// Advances of at most this many closed-form spans per call; then the numerical clock takes over.
constexpr int kMaxClosedFormSpans = 64;

// The closed form from kc->t_s towards t_s, span by span while each stays within tolerance and
// is no shorter than a quarter of the shortest modal period (below that, the numerical clock's
// steps cost less). Leaves y and kc->t_s where it stopped; returns whether it reached t_s.
bool pedicelClosedForm(const Model& m, AsyncState* as, int i, double t_s, Vec6* y) {
  KernelClock& kc = as->kernels[i];
  const PedicelPropagator* cls = closedFormOf(m, as, i, *y);
  if (cls == nullptr) return false;
  const PedicelPropagator& p = *cls;
  for (int n = 0; n < kMaxClosedFormSpans && kc.t_s < t_s; ++n) {
    const PedicelAmplitude a = pedicelAmplitude(p, m.kernels[i], *y);
    const double span = pedicelClosedFormSpan(p, a, m.integrator.tolerance);
    const double left = t_s - kc.t_s;
    if (span < left && !(span >= 0.25 * p.min_period_s)) return false;
    const double h = std::min(span, left);
    *y = propagatePedicel(p, a, h);
    kc.t_s = h == left ? t_s : kc.t_s + h;
    ++as->pedicel_closed_forms;
  }
  return kc.t_s >= t_s;
}

// The pedicel kernel's own clock from kc->t_s to t_s. Returns false, the cause recorded, on a
// numerical failure or when its steps exceed the call's work budget (its span adds its share);
// sets *broke_at_s when the pedicel broke (the kernel is then at that time).
bool pedicelClock(const Model& m, Data* d, AsyncState* as, int i, double t_s, double* broke_at_s) {
  const KernelModel& k = m.kernels[i];
  KernelClock& kc = as->kernels[i];
  const double tol = m.integrator.tolerance;
  double h = kc.h_s > 0 ? kc.h_s : std::min(m.integrator.max_step_s, 1e-6);
  Vec6 y = kernelState(*d, k), y1;
  if (t_s <= kc.rest_until_s || atRest(k, m.gravity_mps2, tol, y, t_s - kc.t_s)) {
    ++as->counters.sleeps;
    kc.t_s = t_s;
    return true;
  }
  if (pedicelClosedForm(m, as, i, t_s, &y)) {
    setKernelState(d, k, y);
    return finiteClock(d, *as, y);
  }
  as->work_allowed += kWorkPerSecond * (t_s - kc.t_s);  // the span's share of the budget
  Vec6 f0 = pedicelRhs(k, m.gravity_mps2, y), f1;
  while (kc.t_s < t_s) {
    if (!spendWork(as, 1)) {  // each trial step, accepted or rejected, is a unit
      recordFailure(d, *as, FailureCause::kWorkBudget, kClockScope);
      return false;
    }
    const double h_try = std::min({h, m.integrator.max_step_s, t_s - kc.t_s});
    const double err = pedicelDopri(k, m.gravity_mps2, tol, y, f0, h_try, &y1, &f1);
    if (!(err <= 1.0)) {
      ++as->counters.pedicel_rejected;
      h = h_try * std::max(0.1, 0.9 * std::pow(std::isfinite(err) ? err : 1e10, -0.2));
      if (!(h > 1e-15)) {
        recordFailure(d, *as, FailureCause::kStepSizeLimit, kClockScope);
        return false;
      }
      continue;
    }
    ++as->counters.pedicel_steps;
    y = y1;
    f0 = f1;
    kc.t_s = (h_try == t_s - kc.t_s) ? t_s : kc.t_s + h_try;
    if (h_try == h || h_try < h)
      h = std::max(h, h_try * std::min(5.0, 0.9 * std::pow(std::max(err, 1e-10), -0.2)));
    double moment = 0.0;
    if (pedicelStemForce(k, y, &moment).norm() > k.pedicel.detachment_force_N) {
      *broke_at_s = kc.t_s;
      break;
    }
  }
  kc.h_s = h;
  setKernelState(d, k, y);
  return finiteClock(d, *as, y);
}

}  // namespace

bool advanceLazyKernel(const Model& m, Data* d, AsyncState* as, int i, double t_s) {
  KernelClock& kc = as->kernels[i];
  if (kc.motion == KernelMotion::kIsland || t_s <= kc.t_s) return true;
  const KernelModel& k = m.kernels[i];
  if (kc.motion == KernelMotion::kPedicel) {
    double broke_at_s = -1.0;
    if (!pedicelClock(m, d, as, i, t_s, &broke_at_s)) return false;
    if (broke_at_s < 0.0) return true;
    // The stem broke at a step end: the kernel flies free from there.
    d->kernel_attached[i] = 0;
    d->stats.kernel_detach_time_s[i] = broke_at_s;
    kc.motion = KernelMotion::kFree;
    ++as->counters.pedicel_breaks;
  }
  ++as->counters.free_advances;
  freeFlight(m, d, k, t_s - kc.t_s);
  kc.t_s = t_s;
  return true;
}

bool pedicelEnvelope(const Model& m, const Data& d, AsyncState* as, int i, double horizon_s,
                     double* growth_m) {
  const KernelModel& k = m.kernels[i];
  const Vec6 y = kernelState(d, k);
  const PedicelPropagator* cls = closedFormOf(m, as, i, y);
  if (cls == nullptr) return false;
  const PedicelPropagator& p = *cls;
  const PedicelAmplitude a = pedicelAmplitude(p, k, y);
  if (!(pedicelClosedFormSpan(p, a, m.integrator.tolerance) >= horizon_s)) return false;
  // The centre stays within E_xy of the equilibrium, the angle within E_psi of its own: each
  // point moves at most |c - c_eq| + E_xy + a (|psi - psi_eq| + E_psi) from where it is now, plus
  // the closed form's error (within the tolerance's position scale).
  const double a_m = k.semi_axis_a_m;
  *growth_m = (y.head<2>() - a.p_WC_eq_W).norm() + a.envelope.head<2>().norm() +
              a_m * (std::abs(y[2] - a.psi_branch_rad) + a.envelope[2]) +
              m.integrator.tolerance * 1e-2;
  return true;
}

bool lazyAtRest(const Model& m, const Data& d, int i, double horizon_s) {
  const KernelModel& k = m.kernels[i];
  return atRest(k, m.gravity_mps2, m.integrator.tolerance, kernelState(d, k), horizon_s);
}

bool lazyAtRestAt(const Model& m, const Data& d, int i, double horizon_s, double cos_psi,
                  double sin_psi) {
  const KernelModel& k = m.kernels[i];
  return ratesAtRest(k, m.integrator.tolerance,
                     pedicelRates(k, m.gravity_mps2, kernelState(d, k), cos_psi, sin_psi),
                     horizon_s);
}

LazySpeedTerms lazySpeedTerms(const Model& m, const Data& d, const AsyncState& as, int i) {
  const KernelModel& k = m.kernels[i];
  const auto z = d.z.segment<3>(k.dof_offset);
  const auto u = d.u.segment<3>(k.dof_offset);
  LazySpeedTerms t;
  t.g_mps2 = m.gravity_mps2.norm();
  t.pedicel = as.kernels[i].motion == KernelMotion::kPedicel;
  if (!t.pedicel) {
    t.speed_mps = u.head<2>().norm();
    t.spin_mps = std::abs(u[2]) * k.semi_axis_a_m;
    return t;
  }
  // On the pedicel: energy. Only gravity does positive work, so over a horizon H the kinetic
  // plus spring energy stays below today's plus m g times the drop, and the drop is at most
  // H times the largest centre speed. With the speed of any point |v| + a |omega| <=
  // sqrt(2 E kappa), kappa = 1/m + a^2/J, that gives V^2 <= 2 kappa (E0 + m g H V): V is at
  // most the positive root. While the stem holds, its tension stays below the detachment
  // force, so the centre also cannot drop below the anchor by more than the stem reaches: the
  // smaller of the two bounds holds. Past a break, gravity adds g t.
  const PedicelModel& p = k.pedicel;
  const double g = t.g_mps2;
  const Vec2 r = rotated(z[2], p.p_KP_K);
  const double stretch_m = (z.head<2>() + r - p.p_WA_W).norm() - p.rest_length_m;
  const double a = k.semi_axis_a_m;
  const double kappa = 1.0 / k.mass_kg + a * a / k.inertia_kgm2;
  const double e0_J = 0.5 * k.mass_kg * u.head<2>().squaredNorm() +
                      0.5 * k.inertia_kgm2 * u[2] * u[2] +
                      0.5 * p.stiffness_Npm * stretch_m * stretch_m;
  t.weight_N = k.mass_kg * g;
  t.kappa_pkg = kappa;
  t.two_kappa_e0 = 2.0 * kappa * e0_J;
  const double reach_m =
      p.rest_length_m + 2.0 * p.detachment_force_N / p.stiffness_Npm + p.p_KP_K.norm();
  const Vec2 down = g > 0 ? Vec2(m.gravity_mps2 / g) : Vec2::Zero();
  const double drop_m = std::max(0.0, reach_m - down.dot(z.head<2>() - p.p_WA_W));
  t.v_long_mps = std::sqrt(2.0 * kappa * (e0_J + k.mass_kg * g * drop_m));
  return t;
}

double lazySpeedBound(const Model& m, const Data& d, const AsyncState& as, int i,
                      double horizon_s) {
  return lazySpeedBoundAt(lazySpeedTerms(m, d, as, i), horizon_s);
}

void advanceFreeTooth(const Model& m, Data* d, AsyncState* as, int k, double h_s) {
  const ToothModel& tm = m.teeth[k];
  if (tm.n_modes == 0 || !(h_s > 0)) return;
  ToothPropagator& prop = as->prop[k];
  SmallVec q1(tm.n_modes), qd1(tm.n_modes);
  propagateTooth(&prop, h_s, d->z.segment(tm.dof_offset, tm.n_modes),
                 d->u.segment(tm.dof_offset, tm.n_modes), q1, qd1);
  d->z.segment(tm.dof_offset, tm.n_modes) = q1;
  d->u.segment(tm.dof_offset, tm.n_modes) = qd1;
  ++as->counters.tooth_advances;
}

namespace {
// Half the rod's moment of inertia about the drum axis at configuration cfg: its kinetic energy
// at rest on the drum turning at 1 rad/s [kg m^2].
double rodHalfInertia(const ToothModel& tm, const LdConfig& cfg, const double* q) {
  const LdVec rest = LdVec::Zero(tm.n_modes);
  double half_inertia = 0.0;
  ldDynamics(tm, cfg, q, rest.data(), 1.0, 0.0, nullptr, nullptr, &half_inertia, nullptr);
  return half_inertia;
}

// Bound on the distance of the rod's centreline from its undeformed line while it moves freely
// at the drum's constant speed [m]. Its Jacobi energy in the drum frame,
// H = 1/2 qd^T M(q) qd + 1/2 q^T K q + 1/2 Omega^2 (I(0) - I(q)) (relative kinetic, bending,
// centrifugal potential against the straight rod: I(q) <= I(0), a bent rod's nodes are nearer
// the drum axis), does not grow then (Coriolis does no work, D damps). The bending energy
// bounds the section angle, |theta(s)| <= sqrt(s int theta'^2) = sqrt(2 s V / EI), and the
// centreline's distance |r(s) - r_0(s)| <= int_0^s |theta| <= 2/3 s^3/2 sqrt(2 V / EI), largest at
// the tip. (Every point of the rod is also within L of its root: the caller caps it there.)
double rodDeflectionBound(const ToothModel& tm, const Data& d) {
  const int n = tm.n_modes;
  const double* q = d.z.data() + tm.dof_offset;
  const double* qd = d.u.data() + tm.dof_offset;
  LdConfig cfg;
  ldConfigure(tm, q, &cfg);
  double relative_kinetic_J = 0.0;
  ldDynamics(tm, cfg, q, qd, 0.0, 0.0, nullptr, nullptr, &relative_kinetic_J, nullptr);
  const double w2 = d.omega_radps * d.omega_radps;
  const double bent_half_inertia = rodHalfInertia(tm, cfg, q);
  const LdVec straight = LdVec::Zero(n);
  ldConfigure(tm, straight.data(), &cfg);
  const double straight_half_inertia = rodHalfInertia(tm, cfg, straight.data());
  const double jacobi_J = relative_kinetic_J + ldElasticEnergy(tm, q) +
                          w2 * std::max(0.0, straight_half_inertia - bent_half_inertia);
  const double EI_Nm2 = tm.ld_K(0, 0) * tm.length_m;  // K_11 = EI / L
  const double L = tm.length_m;
  return 2.0 / 3.0 * L * std::sqrt(L * 2.0 * jacobi_J / EI_Nm2);
}
}  // namespace

double toothDeflectionBound(const Model& m, const Data& d, const AsyncState& as, int k) {
  const ToothModel& tm = m.teeth[k];
  const int n = tm.n_modes;
  if (n == 0) return 0.0;
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return rodDeflectionBound(tm, d);
  // S = Lambda + Omega^2 (K_G - I); the modal energy E = 1/2 qd^T qd + 1/2 q^T S q does not
  // grow while the tooth is free at constant speed, and |phi^T q| <= sqrt(2 E phi^T S^-1 phi).
  // S and the largest phi^T S^-1 phi over the stations are kept per drum speed.
  ToothBound& b = as.tooth_bound[k];
  if (b.omega_radps != d.omega_radps) {
    const double w2 = d.omega_radps * d.omega_radps;
    b.S = w2 * tm.K_G;
    b.S.diagonal().array() += tm.omega0_sq.array() - w2;
    const Eigen::LLT<MatX> llt(b.S);
    b.worst = -1.0;  // not positive definite: no bound from energy
    if (llt.info() == Eigen::Success) {
      b.worst = 0.0;
      for (int s = 0; s < tm.n_stations; ++s) {
        const VecX phi = tm.phi_s.row(s).transpose();
        b.worst = std::max(b.worst, phi.dot(llt.solve(phi)));
      }
    }
    b.omega_radps = d.omega_radps;
  }
  if (b.worst < 0.0) return 0.1 * tm.length_m;
  const auto q = d.z.segment(tm.dof_offset, n);
  const auto qd = d.u.segment(tm.dof_offset, n);
  double qSq = 0.0;  // q^T S q without a temporary
  for (int j = 0; j < n; ++j) qSq += q[j] * b.S.col(j).dot(q);
  const double energy = 0.5 * qd.squaredNorm() + 0.5 * qSq;
  return std::sqrt(2.0 * std::max(energy, 0.0) * b.worst);
}

}  // namespace internal
}  // namespace threshing_sim
