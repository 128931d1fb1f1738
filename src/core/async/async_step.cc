// Asynchronous core: one window of the island-local scheme, as a list of named stages, and
// advanceTo over windows. See async.h for the scheme.
#include "async.h"

namespace threshing_sim {
namespace internal {
namespace {

// Renewals of an island's work budget within one window (each needs progress in time).
constexpr int kMaxBudgetRenewals = 1000;

bool timeStepping(const Model& m) { return m.integrator.type == IntegratorType::kTimeStepping; }

bool rampingOver(const Model& m, const Data& d) {
  (void)m;
  return d.omega_radps != d.omega_target_radps;
}

// Whether tooth k, touching nothing, needs integrating over the window instead of its exact
// free motion: the drum ramps (the stiffness changes), the option is off, or no propagator.
bool toothNeedsIntegration(const Model& m, const Data& d, AsyncState* as, int k) {
  const ToothModel& tm = m.teeth[k];
  if (tm.n_modes == 0) return false;
  if (rampingOver(m, d) || !m.integrator.exact_free_teeth) return true;
  return !buildToothPropagator(m, k, d.omega_radps, &as->prop[k]);
}

// Window end: at most the integrator's largest step and a broad-phase margin of the fastest
// motion (tooth tips, island kernels), landing on the run's end and on a drum ramp's end.
// Time stepping: a whole number of steps, the time accumulated as the steps accumulate it.
double windowEnd(const Model& m, const Data& d, const AsyncState& as, double t_end_s) {
  double v = 1e-6;
  const double omega = std::max(std::abs(d.omega_radps), std::abs(d.omega_target_radps));
  for (const ToothModel& tm : m.teeth) v = std::max(v, omega * (m.drum.radius_m + tm.length_m));
  for (const Island& isl : as.islands)
    if (isl.alive)
      for (int i : isl.kernels) v = std::max(v, kernelSpeedBound(m, d.u, i));
  double w = std::min(m.integrator.max_step_s, m.broadphase_margin_m / v);
  const double ramp = timeToTarget(m, d);
  if (ramp > 1e-12 && ramp < w) w = ramp;
  if (!timeStepping(m)) return std::min(d.t_s + w, t_end_s);
  const double h = m.integrator.dt_s;
  const long steps = std::max(1L, static_cast<long>(w / h));
  double t = d.t_s;
  for (long s = 0; s < steps && t < t_end_s - 0.5 * h; ++s) t += h;
  return t;
}

// Stage: teeth that must be integrated (drum ramp, no exact propagator) join an island.
void claimIntegratedTeeth(const Model& m, const Data& d, AsyncState* as) {
  for (int k = 0; k < static_cast<int>(m.teeth.size()); ++k)
    if (as->tooth_island[k] < 0 && toothNeedsIntegration(m, d, as, k)) as->joins.emplace_back(k, k);
}

int findRootOf(std::vector<int>* parent, int x) {
  while ((*parent)[x] != x) {
    (*parent)[x] = (*parent)[(*parent)[x]];
    x = (*parent)[x];
  }
  return x;
}

// Slot of entity id e in this window's union-find (added on first sight).
int entitySlot(AsyncState* as, int e) {
  if (as->entity_slot[e] < 0) {
    as->entity_slot[e] = static_cast<int>(as->entities.size());
    as->entities.push_back(e);
    as->uf_parent.push_back(as->entity_slot[e]);
  }
  return as->entity_slot[e];
}

int islandOfEntity(const Model& m, const AsyncState& as, int e) {
  const int T = static_cast<int>(m.teeth.size());
  return e < T ? as.tooth_island[e] : as.kernels[e - T].island;
}

void unite(AsyncState* as, int a, int b) {
  const int ra = findRootOf(&as->uf_parent, a), rb = findRootOf(&as->uf_parent, b);
  if (ra != rb) as->uf_parent[std::max(ra, rb)] = std::min(ra, rb);
}

int freeIslandSlot(AsyncState* as) {
  for (size_t s = 0; s < as->islands.size(); ++s)
    if (!as->islands[s].alive) return static_cast<int>(s);
  as->islands.emplace_back();
  return static_cast<int>(as->islands.size()) - 1;
}

// Builds the island of one union-find component (root r) unless it is an existing island
// unchanged. Returns false on a numerical failure of a lazy kernel's clock.
bool buildComponent(const Model& m, Data* d, AsyncState* as, int root) {
  const int T = static_cast<int>(m.teeth.size());
  std::vector<int>& teeth = as->comp_teeth;
  std::vector<int>& kernels = as->comp_kernels;
  teeth.clear();
  kernels.clear();
  int only_island = -2;  // -2 none seen, -1 a lazy body, >= 0 the one island of all members
  for (size_t x = 0; x < as->entities.size(); ++x) {
    if (findRootOf(&as->uf_parent, static_cast<int>(x)) != root) continue;
    const int e = as->entities[x];
    (e < T ? teeth : kernels).push_back(e < T ? e : e - T);
    const int isl = islandOfEntity(m, *as, e);
    only_island = (only_island == -2 || only_island == isl) ? isl : -1;
    if (isl < 0) only_island = -1;
  }
  if (only_island >= 0 &&
      teeth.size() + kernels.size() ==
          as->islands[only_island].teeth.size() + as->islands[only_island].kernels.size())
    return true;  // the same island: nothing to rebuild
  for (int k : teeth)
    if (as->tooth_island[k] >= 0 && as->islands[as->tooth_island[k]].alive)
      dissolveIsland(m, d, as, as->tooth_island[k]);
  for (int i : kernels) {
    const int s = as->kernels[i].island;
    if (s >= 0 && as->islands[s].alive) dissolveIsland(m, d, as, s);
    heapRemove(as, i);
    gridRemove(as, i);
    if (!advanceLazyKernel(m, d, as, i, d->t_s)) return false;
  }
  std::sort(teeth.begin(), teeth.end());
  std::sort(kernels.begin(), kernels.end());
  buildIsland(m, d, as, freeIslandSlot(as), teeth, kernels);
  return true;
}

// Stage: joins become islands. Entities of the joins, with every member of an island one of
// them belongs to, are united; each component becomes one island.
bool formIslands(const Model& m, Data* d, AsyncState* as) {
  if (as->joins.empty()) return true;
  const int T = static_cast<int>(m.teeth.size());
  as->entities.clear();
  as->uf_parent.clear();
  for (const auto& jn : as->joins) unite(as, entitySlot(as, jn.first), entitySlot(as, jn.second));
  // Whole islands come along.
  for (size_t x = 0; x < as->entities.size(); ++x) {
    const int s = islandOfEntity(m, *as, as->entities[x]);
    if (s < 0) continue;
    for (int k : as->islands[s].teeth) unite(as, static_cast<int>(x), entitySlot(as, k));
    for (int i : as->islands[s].kernels) unite(as, static_cast<int>(x), entitySlot(as, T + i));
  }
  bool ok = true;
  for (size_t x = 0; x < as->entities.size() && ok; ++x)
    if (findRootOf(&as->uf_parent, static_cast<int>(x)) == static_cast<int>(x))
      ok = buildComponent(m, d, as, static_cast<int>(x));
  for (int e : as->entities) as->entity_slot[e] = -1;
  as->joins.clear();
  return ok;
}

constexpr const char* kIslandScope = "island scheme: an island's integrator";

// An island's work so far: its steps and its trial steps [work units].
long islandWork(const Data& island_data) {
  return island_data.steps + island_data.ws->ed.trial_steps;
}

// Stage: every island advances to t1 by the global integrator on its sub-system.
StepStatus integrateIslands(const Model& m, Data* d, AsyncState* as, double t1) {
  StepStatus worst = StepStatus::kOk;
  for (size_t s = 0; s < as->islands.size(); ++s) {
    Island& isl = as->islands[s];
    if (!isl.alive) continue;
    isl.data().omega_target_radps = d->omega_target_radps;
    const long steps_before = isl.data().steps;
    // advanceTo's work budget scales with the interval; an island's interval is one window, so
    // a budget spent while time still advances is renewed, a bounded number of times, while the
    // call's own budget lasts (each advance's work is spent from it).
    StepStatus st = StepStatus::kOk;
    bool within_call = true;
    beginIslandObservation(m, d, as, static_cast<int>(s), t1);
    for (int renewal = 0; renewal <= kMaxBudgetRenewals; ++renewal) {
      const double t_before = isl.data().t_s;
      const long work_before = islandWork(isl.data());
      st = advanceTo(isl.model(), &isl.data(), t1);
      within_call = spendWork(as, islandWork(isl.data()) - work_before);
      if (st != StepStatus::kFailed ||
          isl.data().stats.failure.cause != FailureCause::kWorkBudget ||
          !(isl.data().t_s > t_before) || !within_call)
        break;
    }
    endIslandObservation(as, static_cast<int>(s));
    as->counters.island_body_steps += (isl.data().steps - steps_before) *
                                      static_cast<long>(isl.teeth.size() + isl.kernels.size());
    if (!timeStepping(m)) isl.data().t_s = t1;  // it lands on t1 or an ulp past it
    mergeIslandResults(m, d, as, static_cast<int>(s));
    storeIslandState(m, d, *as, static_cast<int>(s));
    if (st == StepStatus::kFailed) {
      d->stats.failure = isl.data().stats.failure;  // the island's cause, where it stalled
      d->stats.failure.scope = kIslandScope;
      // A budget renewal refused: the call's budget is what ran out.
      if (d->stats.failure.cause == FailureCause::kWorkBudget && !within_call)
        recordFailure(d, *as, FailureCause::kWorkBudget, kIslandScope);
      return st;
    }
    if (st == StepStatus::kRecovered) worst = st;
  }
  return worst;
}

// Stage: free teeth move exactly; the drive does the work that keeps the speed.
void advanceFreeTeeth(const Model& m, Data* d, AsyncState* as, double h_s) {
  for (int k = 0; k < static_cast<int>(m.teeth.size()); ++k) {
    const ToothModel& tm = m.teeth[k];
    if (as->tooth_island[k] >= 0 || tm.n_modes == 0) continue;
    const auto q = d->z.segment(tm.dof_offset, tm.n_modes);
    const auto qd = d->u.segment(tm.dof_offset, tm.n_modes);
    const double H0 = toothAngularMomentum(tm, q, qd, d->omega_radps);
    advanceFreeTooth(m, d, as, k, h_s);
    const double H1 = toothAngularMomentum(tm, q, qd, d->omega_radps);
    d->stats.drive_work_J += d->omega_radps * (H1 - H0);
  }
}

// Stage: the drum to t1 (piecewise-constant acceleration, known in advance).
void advanceDrum(const Model& m, Data* d, double t1) {
  const Drive end = driveAt(m, *d, t1 - d->t_s);
  d->theta_rad = end.theta_rad;
  d->omega_radps = end.omega_radps;
  d->alpha_radps2 = end.alpha_radps2;
  d->t_s = t1;
}

// One component (root r of the split union-find) of a dissolved island: a lone kernel
// becomes lazy, a lone tooth free, anything else a new island.
void rebuildComponent(const Model& m, Data* d, AsyncState* as, int root) {
  const int nT = static_cast<int>(as->split_teeth.size());
  std::vector<int>& teeth = as->comp_teeth;
  std::vector<int>& kernels = as->comp_kernels;
  teeth.clear();
  kernels.clear();
  bool pinned = false;
  for (int x = 0; x < static_cast<int>(as->split_parent.size()); ++x) {
    if (findRootOf(&as->split_parent, x) != root) continue;
    if (x < nT) {
      teeth.push_back(as->split_teeth[x]);
    } else {
      kernels.push_back(as->split_kernels[x - nT]);
    }
    pinned |= as->split_pinned[x] != 0;
  }
  if (!pinned && teeth.empty() && kernels.size() == 1) {
    predictKernel(m, *d, as, kernels[0], d->t_s, d->t_s);
  } else if (pinned || teeth.size() + kernels.size() > 1) {
    buildIsland(m, d, as, freeIslandSlot(as), teeth, kernels);
  }
}

// Stage: each island splits into the groups of its bodies that are in contact or within reach
// over the next window; a lone kernel becomes lazy again (a new bound circle), a lone tooth
// free; an island that stays whole is kept with its workspace.
void splitIslands(const Model& m, Data* d, AsyncState* as, double window_s) {
  const size_t n_slots = as->islands.size();
  for (size_t s = 0; s < n_slots; ++s) {
    Island& isl = as->islands[s];
    if (!isl.alive) continue;
    islandProximity(m, *d, *as, static_cast<int>(s), window_s, &as->split_edges, &as->split_pinned);
    const int nT = static_cast<int>(isl.teeth.size());
    for (int a = 0; a < nT; ++a)
      if (toothNeedsIntegration(m, *d, as, isl.teeth[a])) as->split_pinned[a] = 1;
    const int n = static_cast<int>(as->split_pinned.size());
    as->split_parent.resize(n);
    for (int x = 0; x < n; ++x) as->split_parent[x] = x;
    int components = n;
    for (const auto& e : as->split_edges) {
      const int ra = findRootOf(&as->split_parent, e.first);
      const int rb = findRootOf(&as->split_parent, e.second);
      if (ra == rb) continue;
      as->split_parent[std::max(ra, rb)] = std::min(ra, rb);
      --components;
    }
    // Whole (one component, and not a lone body that may leave): kept as it is.
    if (components == 1 && (n > 1 || as->split_pinned[0])) continue;
    as->split_teeth = isl.teeth;
    as->split_kernels = isl.kernels;
    dissolveIsland(m, d, as, static_cast<int>(s));
    for (int x = 0; x < n; ++x)
      if (findRootOf(&as->split_parent, x) == x) rebuildComponent(m, d, as, x);
  }
}

// Events of the window in time order (islands report theirs one after another).
void flushWindowEvents(Data* d, AsyncState* as) {
  std::vector<ContactEvent>& ev = as->window_events;
  for (size_t i = 1; i < ev.size(); ++i)
    for (size_t j = i; j > 0 && ev[j].t_s < ev[j - 1].t_s; --j) std::swap(ev[j], ev[j - 1]);
  d->events.insert(d->events.end(), ev.begin(), ev.end());
  ev.clear();
}

void setUp(const Model& m, Data* d, AsyncState* as) {
  const int K = static_cast<int>(m.kernels.size()), T = static_cast<int>(m.teeth.size());
  as->tooth_island.assign(T, -1);
  for (Island& isl : as->islands) {
    isl.alive = false;
    isl.sys = nullptr;
  }
  // The pool's systems are kept with their workspaces; their copies of the teeth are forgotten
  // (the model may be another).
  for (const std::unique_ptr<IslandSystem>& sys : as->systems) {
    sys->in_use = false;
    sys->teeth_of = nullptr;
  }
  // The pair memory of pairs outside islands: reserved by the first island (buildIsland), so
  // that a field that never forms one does not pay for a table sized for every pair.
  if (as->stored_memory.size() > 0) as->stored_memory.clear();
  as->synced.clear();  // the bodies were reset: nothing to put back
  as->field_synced = false;
  as->max_horizon_s = 1.0;
  as->entity_slot.assign(T + K, -1);
  as->prop.resize(T);
  as->tooth_bound.assign(T, ToothBound());
  for (ToothPropagator& p : as->prop) p.n_modes = -1;
  as->counters = SchedulerStats();
  as->swept_kernels = 0;
  // Every kernel listed first, so that each prediction sees all its neighbours (and leaves
  // them their half of each gap). A kernel at rest on its pedicel over the longest horizon is
  // listed asleep at once, as predictKernel would list it (its circle grown by the error scale,
  // awake again after the longest horizon), without a prediction: two sleeping kernels do not
  // move, so they cannot approach each other or an obstacle (the start poses overlap nothing:
  // checked where the scene is read), and every kernel that moves or wakes checks its own
  // circle against theirs in the grid (predictKernel, lazyNeighbours, sweepTeeth). They form
  // the sleeping field, whose cells are written only when something comes near it (listField
  // in calendar.cc, where set-up would have listed them). The others are listed with their
  // ungrown circle, then predicted.
  if (listKernelsAtSetUp(m, *d, as) > 0) {
    for (int i = 0; i < K; ++i) {
      if (as->kernels[i].heap_pos >= 0) continue;  // asleep
      gridRemove(as, i);
      predictKernel(m, *d, as, i, d->t_s, d->t_s);
    }
  }
  as->ready = true;
}

// Keeps lazy kernel i's state before a sync moves it (AsyncState::synced).
void saveSynced(const Model& m, const Data& d, AsyncState* as, int i) {
  AsyncState::SyncedKernel s;
  s.kernel = i;
  s.clock = as->kernels[i];
  const int o = m.kernels[i].dof_offset;
  s.zu << d.z.segment<3>(o), d.u.segment<3>(o);
  s.attached = d.kernel_attached[i];
  s.detach_s = d.stats.kernel_detach_time_s[i];
  as->synced.push_back(s);
}

// Puts the kernels the last sync moved back where their clocks were (the sync only observed).
void restoreSynced(const Model& m, Data* d, AsyncState* as) {
  for (auto it = as->synced.rbegin(); it != as->synced.rend(); ++it) {
    const int i = it->kernel, o = m.kernels[i].dof_offset;
    as->kernels[i] = it->clock;
    d->z.segment<3>(o) = it->zu.head<3>();
    d->u.segment<3>(o) = it->zu.tail<3>();
    d->kernel_attached[i] = it->attached;
    d->stats.kernel_detach_time_s[i] = it->detach_s;
  }
  as->synced.clear();
  if (as->field_synced) as->field_t_s = as->field_synced_from_s;
  as->field_synced = false;
}

// Brings every lazy kernel to the data's time (the caller reads the whole state); the next
// window starts from their clocks as they were (restoreSynced).
bool syncLazyKernels(const Model& m, Data* d, AsyncState* as) {
  restoreSynced(m, d, as);
  const double t_s = d->t_s;
  const int K = static_cast<int>(m.kernels.size());
  long jumps = 0;  // (counted here, added once)
  // The sleeping field: asleep until past t_s (each would have woken in the window that reached
  // its wake time), its kernels share one clock, which jumps (advanceLazyKernel's first case).
  if (as->field_unlisted > 0 && t_s > as->field_t_s) {
    jumps += as->field_unlisted;
    as->field_synced_from_s = as->field_t_s;  // put back like a kernel's clock (restoreSynced)
    as->field_synced = true;
    as->field_t_s = t_s;
  }
  bool ok = true;
  for (int i = as->field_unlisted == K ? K : 0; i < K && ok; ++i) {
    // A run of kernels asleep on their pedicels until past t_s: their clocks jump (the same
    // case, without its call), in a loop that calls nothing; the field's are passed over.
    KernelClock* kcs = as->kernels.data();
    for (; i < K && kcs[i].motion == KernelMotion::kPedicel && t_s <= kcs[i].rest_until_s; ++i) {
      if (kcs[i].listing != GridListing::kUnlisted && t_s > kcs[i].t_s) {
        saveSynced(m, *d, as, i);
        ++jumps;
        kcs[i].t_s = t_s;
      }
    }
    if (i >= K) break;
    if (kcs[i].motion != KernelMotion::kIsland && t_s > kcs[i].t_s) saveSynced(m, *d, as, i);
    ok = advanceLazyKernel(m, d, as, i, t_s);
  }
  as->counters.sleeps += jumps;
  return ok;
}

void publishContacts(Data* d, const AsyncState& as) {
  d->contacts.clear();
  publishIslandContacts(as, &d->contacts);
}

}  // namespace

void beginWork(AsyncState* as, double span_s, double t_target_s) {
  as->work_used = 0;
  as->work_allowed = std::min(1e15, kBaseWork + kWorkPerSecond * std::max(0.0, span_s));
  as->work_target_s = t_target_s;
}

void recordFailure(Data* d, const AsyncState& as, FailureCause cause, const char* scope) {
  d->stats.failure = {cause,
                      d->t_s,
                      as.work_target_s,
                      as.work_used,
                      static_cast<long>(std::min(as.work_allowed, 1e15)),
                      scope};
}

StepStatus asyncWindow(const Model& m, Data* d, double t_end_s) {
  AsyncState& as = asyncState(m, d);
  const double t0 = d->t_s;
  const double t1 = windowEnd(m, *d, as, t_end_s);
  if (!(t1 > t0)) {  // no progress: a window of zero length
    d->stats.failure = {FailureCause::kTimeStalled, t0, t_end_s, 0, 0, "island scheme: a window"};
    return StepStatus::kFailed;
  }
  // The call's budget, before the window: each window is a unit of it.
  if (!spendWork(&as, 1)) {
    recordFailure(d, as, FailureCause::kWorkBudget,
                  "island scheme: windows, islands' steps and lone kernels' clocks");
    return StepStatus::kFailed;
  }
  ++as.counters.windows;
  if (!wakeDueKernels(m, d, &as, t0, t1)) return StepStatus::kFailed;
  listIslandKernels(m, *d, &as, t1 - t0);
  sweepTeeth(m, d, &as, t0, t1);
  islandNeighbours(m, d, &as, t0, t1);
  claimIntegratedTeeth(m, *d, &as);
  if (!formIslands(m, d, &as)) return StepStatus::kFailed;
  const StepStatus status = integrateIslands(m, d, &as, t1);
  if (status == StepStatus::kFailed) return status;
  advanceFreeTeeth(m, d, &as, t1 - t0);
  advanceDrum(m, d, t1);
  checkToothDeflection(m, d);
  splitIslands(m, d, &as, t1 - t0);
  flushWindowEvents(d, &as);
  return status;
}

AsyncState& asyncState(const Model& m, Data* d) {
  Workspace& ws = *d->ws;
  if (!ws.async) ws.async = std::make_unique<AsyncState>();
  if (!ws.async->ready) setUp(m, d, ws.async.get());
  return *ws.async;
}

StepStatus asyncAdvanceTo(const Model& m, Data* d, double t_end_s, bool sync, double t_stop_s) {
  StepStatus worst = StepStatus::kOk;
  const double half_step = timeStepping(m) ? 0.5 * m.integrator.dt_s : 0.0;
  // Windows end where the motion puts them, cut short only at t_stop_s (advancePast: the run's
  // end; advanceTo: t_end_s itself).
  if (std::isnan(t_stop_s)) t_stop_s = t_end_s;
  AsyncState& as = asyncState(m, d);
  beginWork(&as, t_end_s - d->t_s, t_end_s);
  restoreSynced(m, d, &as);
  for (long w = 0; d->t_s < t_end_s - half_step; ++w) {
    const StepStatus s = asyncWindow(m, d, t_stop_s);
    if (s == StepStatus::kFailed) {
      worst = s;
      break;
    }
    if (s == StepStatus::kRecovered) worst = s;
  }
  if (sync) {
    // After a failure the sync has a budget of its own, and the window's failure is the call's.
    const bool failed = worst == StepStatus::kFailed;
    const FailureInfo failure = d->stats.failure;
    if (failed) beginWork(&as, 0.0, t_end_s);
    if (!syncLazyKernels(m, d, &as)) worst = StepStatus::kFailed;
    if (failed) d->stats.failure = failure;
  }
  publishContacts(d, as);
  d->stats.scheduler = as.counters;
  return worst;
}

StepStatus asyncSync(const Model& m, Data* d) {
  AsyncState& as = asyncState(m, d);
  beginWork(&as, 0.0, d->t_s);  // the lone clocks' spans bring their own share
  const bool ok = syncLazyKernels(m, d, &as);
  d->stats.scheduler = as.counters;
  return ok ? StepStatus::kOk : StepStatus::kFailed;
}

StepStatus asyncStep(const Model& m, Data* d) {
  AsyncState& as = asyncState(m, d);
  beginWork(&as, m.integrator.max_step_s, d->t_s + m.integrator.max_step_s);  // one window
  restoreSynced(m, d, &as);
  StepStatus s = asyncWindow(m, d, std::numeric_limits<double>::infinity());
  if (!syncLazyKernels(m, d, &as)) s = StepStatus::kFailed;
  publishContacts(d, as);
  d->stats.scheduler = as.counters;
  return s;
}

void resetAsync(Data* d) {
  if (d->ws->async) d->ws->async->ready = false;
}

}  // namespace internal
}  // namespace threshing_sim
