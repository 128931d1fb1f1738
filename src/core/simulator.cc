// The stepping API: reset, advanceTo with its work budget and non-finite guard, failure
// descriptions and the tooth's geometry queries. The bookkeeping both integrators share
// (episodes, events, statistics) is in episodes.cc.
#include "threshing_sim/core/simulator.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <tuple>

#include "async/async.h"
#include "internal.h"
#include "threshing_sim/core/beam.h"

namespace threshing_sim {

const char* toString(ContactState s) {
  switch (s) {
    case ContactState::kSeparated:
      return "separated";
    case ContactState::kImpact:
      return "impact";
    case ContactState::kStick:
      return "stick";
    case ContactState::kSlip:
      return "slip";
  }
  return "?";
}

const char* toString(PairKind k) {
  switch (k) {
    case PairKind::kToothKernel:
      return "tooth_kernel";
    case PairKind::kKernelKernel:
      return "kernel_kernel";
    case PairKind::kKernelObstacle:
      return "kernel_obstacle";
  }
  return "?";
}

bool PairId::operator<(const PairId& o) const {
  return std::tie(kind, a, b) < std::tie(o.kind, o.a, o.b);
}

Workspace::Workspace() = default;
Workspace::~Workspace() = default;

Data::Data() : ws(std::make_unique<Workspace>()) {}
Data::~Data() = default;
Data::Data(Data&&) noexcept = default;
Data& Data::operator=(Data&&) noexcept = default;

namespace {

// Statistics back to zero, keeping the per-kernel vectors' storage (resetBodies sizes them),
// so that a reset allocates nothing once a run has warmed up (an island re-formed in the
// island scheme is such a reset).
void clearStats(RunStats* s) {
  std::vector<double> peak = std::move(s->kernel_peak_normal_force_N);
  std::vector<long> impacts = std::move(s->kernel_impacts);
  std::vector<double> detach = std::move(s->kernel_detach_time_s);
  std::vector<KernelToothPeaks> tooth = std::move(s->kernel_tooth_peaks);
  std::vector<std::string> warnings = std::move(s->warnings);
  warnings.clear();
  *s = RunStats();
  s->kernel_peak_normal_force_N = std::move(peak);
  s->kernel_impacts = std::move(impacts);
  s->kernel_detach_time_s = std::move(detach);
  s->kernel_tooth_peaks = std::move(tooth);
  s->warnings = std::move(warnings);
}

// Kernels, teeth and pedicels back to the scene's initial state (time and drum untouched).
void resetBodies(const Model& m, Data* d) {
  d->z.setZero(m.n_dof);
  d->u.setZero(m.n_dof);
  for (const KernelModel& k : m.kernels) {
    d->z.segment<2>(k.dof_offset) = k.initial_position_m;
    d->z[k.dof_offset + 2] = k.initial_angle_rad;
    d->u.segment<2>(k.dof_offset) = k.initial_velocity_mps;
    d->u[k.dof_offset + 2] = k.initial_angular_velocity_radps;
  }
  d->kernel_attached.assign(m.kernels.size(), 1);
  d->kernel_active.assign(m.kernels.size(), 1);
  // A feed's pool slots start parked (core/feed.h).
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    if (m.kernels[i].pool_slot) d->kernel_attached[i] = d->kernel_active[i] = 0;
  }
  d->omega_target_radps = m.drum.initial_speed_radps;
  d->ws->memory.clear();
  // Room for the pairs a run typically meets (each kernel with every tooth and a few kernels
  // and obstacles), so that pair memory is not allocated while stepping.
  const size_t n_kernels = m.kernels.size();
  d->ws->memory.reserve(n_kernels * (m.teeth.size() + 16) + 64);
  d->ws->prev_active.clear();
  internal::prepareBroadPhase(m, d->ws.get());
  d->ws->ts.in_contact.clear();
  d->ws->ts.in_contact_step = -2;
  d->ws->cp.end_valid = false;
  d->ws->geoms.clear();
  d->contacts.clear();
  d->stats.kernel_peak_normal_force_N.assign(m.kernels.size(), 0.0);
  d->stats.kernel_tooth_peaks.assign(m.kernels.size(), KernelToothPeaks());
  d->stats.kernel_impacts.assign(m.kernels.size(), 0);
  d->stats.kernel_detach_time_s.assign(m.kernels.size(), -1.0);
}

bool finiteState(const Data& d) {
  return d.z.allFinite() && d.u.allFinite() && std::isfinite(d.omega_radps) &&
         std::isfinite(d.theta_rad);
}

}  // namespace

void resetData(const Model& model, Data* data) {
  data->t_s = 0;
  data->steps = 0;
  data->theta_rad = model.drum.initial_angle_rad;
  data->omega_radps = model.drum.initial_speed_radps;
  data->alpha_radps2 = 0;
  data->events.clear();
  // Events are appended while stepping: room for many before the vector must grow.
  data->events.reserve(4096);
  clearStats(&data->stats);
  data->ws->ts.iteration_omega = -1;
  data->ws->ts.iteration_basis_h = -1;  // C and mu are this model's
  data->ws->ed.h = 0;
  // The free-tooth propagators are rebuilt for this model on first use.
  for (internal::ToothPropagator& prop : data->ws->ed.prop) prop.n_modes = -1;
  // The large-deflection caches are keyed on q and z only: forget another model's.
  // The rods' configuration keys are invalidated in place (NaN matches no q), keeping their
  // storage: an island's sub-system is reset at every build and must not allocate then.
  for (VecX& key : data->ws->ld_cfg_q) key.setConstant(std::numeric_limits<double>::quiet_NaN());
  data->ws->ld_minv_valid = false;
  resetBodies(model, data);
  internal::resetAsync(data);
  data->stats.energy_initial_J = mechanicalEnergy(model, *data);
}

void resetBodiesKeepTime(const Model& model, Data* data) {
  resetBodies(model, data);
  internal::resetAsync(data);
  data->stats.failure = FailureInfo();
  data->stats.drive_work_J = 0;
  data->stats.energy_initial_J = mechanicalEnergy(model, *data);
  data->ws->ed.h = 0;
}

StepStatus step(const Model& model, Data* data) {
  if (model.integrator.islands) return internal::asyncStep(model, data);
  const double t_end = model.integrator.type == IntegratorType::kTimeStepping
                           ? data->t_s + model.integrator.dt_s
                           : std::numeric_limits<double>::infinity();
  const StepStatus s = model.integrator.type == IntegratorType::kTimeStepping
                           ? internal::timeSteppingStep(model, data, model.integrator.dt_s)
                           : internal::eventDrivenStep(model, data, t_end);
  if (s != StepStatus::kFailed) internal::checkToothDeflection(model, data);
  return s;
}

namespace {

// Accepted steps in a row that leave t_s unchanged before the call fails as kTimeStalled.
constexpr int kMaxStalledSteps = 100;

// Work done since the step and trial-step counters were at steps0, trials0.
long workSince(const Data& d, long steps0, long trials0) {
  return (d.steps - steps0) + (d.ws->ed.trial_steps - trials0);
}

StepStatus fail(Data* d, FailureCause cause, double t_end_s, long work, long budget) {
  d->stats.failure = {cause, d->t_s, t_end_s, work, budget};
  return StepStatus::kFailed;
}

}  // namespace

namespace {

// The global scheme's advance: steps until t_end_s is reached, each event-driven step cut short
// only at t_stop_s (advanceTo: t_stop_s = t_end_s; advancePast: the run's end).
StepStatus advanceGlobal(const Model& model, Data* data, double t_end_s, double t_stop_s) {
  StepStatus worst = StepStatus::kOk;
  const double h = model.integrator.dt_s;
  const long budget = static_cast<long>(std::min(
      1e15, internal::kBaseWork + internal::kWorkPerSecond * std::max(0.0, t_end_s - data->t_s)));
  const long steps_start = data->steps, trials_start = data->ws->ed.trial_steps;
  int stalled = 0;
  while (true) {
    const bool ts = model.integrator.type == IntegratorType::kTimeStepping;
    if (ts ? data->t_s >= t_end_s - 0.5 * h : data->t_s >= t_end_s) break;
    const long work = workSince(*data, steps_start, trials_start);
    if (work > budget) return fail(data, FailureCause::kWorkBudget, t_end_s, work, budget);
    // Keep the last good state so that a non-finite result can be undone.
    Workspace& ws = *data->ws;
    ws.guard_z = data->z;
    ws.guard_u = data->u;
    const double t0 = data->t_s, th0 = data->theta_rad, om0 = data->omega_radps;
    const long steps0 = data->steps;
    StepStatus s = ts ? internal::timeSteppingStep(model, data, h)
                      : internal::eventDrivenStep(model, data, t_stop_s);
    if (s == StepStatus::kOk && finiteState(*data)) {
      internal::checkToothDeflection(model, data);
      stalled = data->t_s > t0 ? 0 : stalled + 1;
      if (stalled >= kMaxStalledSteps)
        return fail(data, FailureCause::kTimeStalled, t_end_s, work, budget);
      if (ws.step_hook != nullptr) ws.step_hook->afterStep(*data);
      continue;
    }
    const FailureCause cause = s == StepStatus::kOk || !finiteState(*data)
                                   ? FailureCause::kNonFinite
                                   : FailureCause::kStepSizeLimit;
    // Recovery: restore, then cross the same interval with ten small time steps.
    data->z = ws.guard_z;
    data->u = ws.guard_u;
    data->t_s = t0;
    data->theta_rad = th0;
    data->omega_radps = om0;
    ++data->stats.numerical_recoveries;
    const double h_small = (ts ? h : std::min(1e-7, t_stop_s - t0)) / 10.0;
    bool ok = h_small > 0;
    for (int i = 0; i < 10 && ok; ++i) {
      ok =
          internal::timeSteppingStep(model, data, h_small) == StepStatus::kOk && finiteState(*data);
    }
    if (!ok) {
      // A NaN inside an event-driven step shows as rejected steps; the time steps reveal it.
      const FailureCause why = finiteState(*data) ? cause : FailureCause::kNonFinite;
      data->z = ws.guard_z;
      data->u = ws.guard_u;
      data->steps = steps0;
      data->t_s = t0;
      data->theta_rad = th0;
      data->omega_radps = om0;
      return fail(data, why, t_end_s, work, budget);
    }
    internal::checkToothDeflection(model, data);
    if (ws.step_hook != nullptr) ws.step_hook->afterStep(*data);
    worst = StepStatus::kRecovered;
  }
  return worst;
}

// advanceTo and advancePast, with (sync) or without the lone kernels brought to data's time.
StepStatus advanceChecked(const Model& model, Data* data, double t_end_s, double t_stop_s,
                          bool sync) {
  data->stats.failure = FailureInfo();
  if (!std::isfinite(t_end_s) || std::isnan(t_stop_s))
    return fail(data, FailureCause::kBadTarget, t_end_s, 0, 0);
  t_end_s = std::min(t_end_s, t_stop_s);
  // The island scheme: each island's advanceTo() has the budget over its own work.
  if (model.integrator.islands)
    return internal::asyncAdvanceTo(model, data, t_end_s, sync, t_stop_s);
  return advanceGlobal(model, data, t_end_s, t_stop_s);
}

}  // namespace

StepStatus advanceTo(const Model& model, Data* data, double t_end_s) {
  return advanceChecked(model, data, t_end_s, t_end_s, true);
}

StepStatus advanceToLazy(const Model& model, Data* data, double t_end_s) {
  return advanceChecked(model, data, t_end_s, t_end_s, false);
}

StepStatus advancePast(const Model& model, Data* data, double t_target_s, double t_stop_s) {
  return advanceChecked(model, data, t_target_s, t_stop_s, true);
}

StepStatus advancePastLazy(const Model& model, Data* data, double t_target_s, double t_stop_s) {
  return advanceChecked(model, data, t_target_s, t_stop_s, false);
}

StepStatus syncBodies(const Model& model, Data* data) {
  if (!model.integrator.islands) return StepStatus::kOk;
  return internal::asyncSync(model, data);
}

const char* toString(FailureCause cause) {
  switch (cause) {
    case FailureCause::kNone:
      return "none";
    case FailureCause::kNonFinite:
      return "non_finite";
    case FailureCause::kStepSizeLimit:
      return "step_size_limit";
    case FailureCause::kWorkBudget:
      return "work_budget";
    case FailureCause::kTimeStalled:
      return "time_stalled";
    case FailureCause::kBadTarget:
      return "bad_target";
  }
  return "?";
}

std::string describe(const FailureInfo& f) {
  const char* what = "no failure";
  switch (f.cause) {
    case FailureCause::kNone:
      break;
    case FailureCause::kNonFinite:
      what = "non-finite state, not recovered by small steps";
      break;
    case FailureCause::kStepSizeLimit:
      what = "event-driven step size below its floor (too many rejected trial steps)";
      break;
    case FailureCause::kWorkBudget:
      what = "work budget exceeded (steps, rejected steps and events)";
      break;
    case FailureCause::kTimeStalled:
      what = "time stalled (accepted steps below the rounding of t)";
      break;
    case FailureCause::kBadTarget:
      what = "target time not finite";
      break;
  }
  char text[256];
  std::snprintf(text, sizeof(text), "%s [%s] at t = %.9g s (target %.9g s, %ld of %ld work units)",
                what, toString(f.cause), f.t_s, f.t_target_s, f.work, f.budget);
  if (f.scope == nullptr) return text;
  return std::string(text) + " in " + f.scope;
}

Vec2 toothPointWorld(const Model& model, const Data& data, int tooth, double x_m) {
  const ToothModel& tm = model.teeth[tooth];
  const double w = toothDeflection(model, data, tooth, x_m);
  const double wc = toothForeshortening(model, data, tooth, x_m);
  const Vec2 p_D = tm.p_DR_D + (x_m + wc) * tm.e1_D + w * tm.e2_D;
  const double c = std::cos(data.theta_rad), s = std::sin(data.theta_rad);
  return Vec2(c * p_D.x() - s * p_D.y(), s * p_D.x() + c * p_D.y());
}

namespace {
// A large-deflection rod's centreline point at x_m from its undeformed place, in the tooth's
// axes (e1: foreshortening, e2: deflection) [m].
Vec2 rodDisplacement(const ToothModel& tm, const Data& data, double x_m) {
  LdConfig cfg;
  ldConfigure(tm, data.z.data() + tm.dof_offset, &cfg);
  return ldPoint(tm, cfg, x_m, nullptr, nullptr, nullptr) - tm.ld_root_T - Vec2(x_m, 0.0);
}
}  // namespace

double toothDeflection(const Model& model, const Data& data, int tooth, double x_m) {
  const ToothModel& tm = model.teeth[tooth];
  if (tm.n_modes == 0) return 0.0;
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return rodDisplacement(tm, data, x_m).y();
  VecX phi, dphi;
  evaluateModes(tm, x_m, &phi, &dphi);
  return phi.dot(data.z.segment(tm.dof_offset, tm.n_modes));
}

double toothForeshortening(const Model& model, const Data& data, int tooth, double x_m) {
  const ToothModel& tm = model.teeth[tooth];
  if (tm.n_modes == 0) return 0.0;
  if (tm.beam_model == ToothBeamModel::kLargeDeflection) return rodDisplacement(tm, data, x_m).x();
  MatX H;
  interpolateH(tm, x_m, &H);
  const auto q = data.z.segment(tm.dof_offset, tm.n_modes);
  return -0.5 * q.dot(H * q);
}

}  // namespace threshing_sim
