// Asynchronous core, stage "islands": sub-systems of the bodies that can touch.
// An island's Model holds copies of its bodies' compiled models (teeth and kernels in
// ascending global order, so that local pair order is global pair order) and every obstacle;
// its Data holds their state, its own clock, steps, events, pair memory and integrator
// workspace. The global integrator (integrator.islands: false) advances it. What it reports
// (events, statistics, contacts) is mapped back to global indices here.
#include <algorithm>
#include <cstdio>

#include "async.h"

namespace threshing_sim {
namespace internal {
namespace {

PairId pairOfKey(std::uint64_t key) {
  return PairId{static_cast<PairKind>(key >> 60), static_cast<int>((key >> 30) & 0x3fffffff),
                static_cast<int>(key & 0x3fffffff)};
}

// Whether what a workspace derives from tooth a alone (its free-tooth propagator, its
// time-stepping iteration matrices) holds for tooth b: their inputs are equal.
bool sameDerivedInputs(const ToothModel& a, const ToothModel& b) {
  auto same = [](const auto& x, const auto& y) {
    return x.rows() == y.rows() && x.cols() == y.cols() && x == y;
  };
  return a.beam_model == b.beam_model && a.n_modes == b.n_modes && same(a.omega0_sq, b.omega0_sq) &&
         same(a.K_G, b.K_G) && same(a.damping_coeff, b.damping_coeff) && same(a.ld_K, b.ld_K);
}

// The sub-model of an island: the full model's constants, the members' compiled models. The
// constants, the teeth and the obstacles are copied only into a system that does not hold
// those of m yet (a new one, or its first build after a set-up); the kernels on every build.
// Returns whether the teeth and the integrator's parameters are those the system held (what
// its workspace derived from them still holds).
bool buildSubModel(const Model& m, IslandSystem* sys, const std::vector<int>& kernels) {
  Model& sm = sys->model;
  int offset = 0;
  bool alike = true;
  if (sys->teeth_of != &m) {
    alike = sm.integrator.type == m.integrator.type && sm.integrator.theta == m.integrator.theta &&
            sm.integrator.modal_split == m.integrator.modal_split &&
            sm.teeth.size() == sys->teeth.size();
    sm.drum = m.drum;
    for (int p = 0; p < 3; ++p) sm.contact[p] = m.contact[p];
    sm.gravity_mps2 = m.gravity_mps2;
    sm.integrator = m.integrator;
    sm.integrator.islands = false;
    sm.duration_s = m.duration_s;
    sm.broadphase_margin_m = m.broadphase_margin_m;
    sm.hc_min_impact_speed_mps = m.hc_min_impact_speed_mps;
    sm.macro_collision_gap_s = m.macro_collision_gap_s;
    sm.deflection_validity_fraction = m.deflection_validity_fraction;
    sm.obstacles = m.obstacles;
    sm.teeth.resize(sys->teeth.size());
    // Whether some tooth is a rod: the integrators then take its configuration-dependent mass
    // matrix (compileModel derives it for the full model; the sub-model is not compiled).
    sm.has_large_deflection = false;
    for (size_t l = 0; l < sys->teeth.size(); ++l) {
      const ToothModel& tg = m.teeth[sys->teeth[l]];
      alike = alike && sameDerivedInputs(sm.teeth[l], tg);
      sm.teeth[l] = tg;
      sm.teeth[l].dof_offset = offset;
      offset += sm.teeth[l].n_modes;
      if (tg.beam_model == ToothBeamModel::kLargeDeflection) sm.has_large_deflection = true;
    }
    sm.kernels.resize(kernels.size());
    sys->teeth_of = &m;
  } else {
    for (const ToothModel& tl : sm.teeth) offset += tl.n_modes;
  }
  for (size_t l = 0; l < kernels.size(); ++l) {
    sm.kernels[l] = m.kernels[kernels[l]];
    sm.kernels[l].dof_offset = offset;
    offset += 3;
  }
  sm.n_dof = offset;
  sm.compiled = true;
  return alike;
}

// A free system of the shape (teeth, number of kernels) from the pool, the first in pool order
// (so that a run that repeats another's islands uses the same systems), or a new one.
IslandSystem* takeSystem(AsyncState* as, const std::vector<int>& teeth, size_t n_kernels) {
  for (const std::unique_ptr<IslandSystem>& sys : as->systems) {
    if (!sys->in_use && sys->n_kernels == static_cast<int>(n_kernels) && sys->teeth == teeth) {
      sys->in_use = true;
      return sys.get();
    }
  }
  as->systems.push_back(std::make_unique<IslandSystem>());
  IslandSystem* sys = as->systems.back().get();
  sys->teeth = teeth;
  sys->n_kernels = static_cast<int>(n_kernels);
  sys->in_use = true;
  return sys;
}

PairId localToGlobal(const Island& isl, const PairId& p) {
  switch (p.kind) {
    case PairKind::kToothKernel:
      return PairId{p.kind, isl.teeth[p.a], isl.kernels[p.b]};
    case PairKind::kKernelKernel:
      return PairId{p.kind, isl.kernels[p.a], isl.kernels[p.b]};
    default:
      return PairId{p.kind, isl.kernels[p.a], p.b};
  }
}

// Energy minus drive work of an island's sub-system [J]: what an episode's energy_before_J is
// measured against (beginEpisode, endEpisode). It depends on the sub-system's bodies and on
// the drive work since its reset, so a stored episode keeps its energy relative to it.
double islandNetEnergy(const Island& isl) {
  return mechanicalEnergy(isl.model(), isl.data()) - isl.data().stats.drive_work_J;
}

// Stored pair memory of the island's pairs, into its workspace under local keys. An episode's
// energy at its start was stored relative to the net energy of the island it began in
// (dissolveIsland): it is measured against this island's from here, so that the energy an
// impact reports lost is the change over the episode whichever islands it spanned.
void loadPairMemory(const Model& m, AsyncState* as, Island* isl) {
  PairTable& local = isl->data().ws->memory;
  const int T = static_cast<int>(isl->teeth.size()), K = static_cast<int>(isl->kernels.size());
  const double e_net = islandNetEnergy(*isl);
  auto load = [&](const PairId& p_local) {
    const PairMemory* mem = as->stored_memory.find(pairKey(localToGlobal(*isl, p_local)));
    if (mem == nullptr) return;
    PairMemory& l = local[pairKey(p_local)];
    l = *mem;
    l.energy_before_J += e_net;
  };
  for (int b = 0; b < K; ++b) {
    for (int a = 0; a < T; ++a) load(PairId{PairKind::kToothKernel, a, b});
    for (int a = 0; a < b; ++a) load(PairId{PairKind::kKernelKernel, a, b});
    for (size_t o = 0; o < m.obstacles.size(); ++o)
      load(PairId{PairKind::kKernelObstacle, b, static_cast<int>(o)});
  }
}

bool worthKeeping(const PairMemory& mem) {
  return mem.state != ContactState::kSeparated || mem.macro_index >= 0 ||
         mem.impulse_n_acc != 0.0 || mem.impulse_t_acc != 0.0;
}

// Warnings of an island name its local tooth index: rewritten to the global one.
std::string globalWarning(const Island& isl, const std::string& text) {
  size_t local = 0;
  int used = 0;
  if (std::sscanf(text.c_str(), "tooth %zu:%n", &local, &used) == 1 && used > 0 &&
      local < isl.teeth.size())
    return "tooth " + std::to_string(isl.teeth[local]) + ":" + text.substr(used);
  return text;
}

void mergeCounters(Data* d, AsyncState* as, Island* isl) {
  const RunStats& s = isl->data().stats;
  RunStats& g = d->stats;
  g.impacts += s.impacts - isl->merged_impacts;
  g.contact_episodes += s.contact_episodes - isl->merged_episodes;
  g.numerical_recoveries += s.numerical_recoveries - isl->merged_recoveries;
  g.rejected_steps += s.rejected_steps - isl->merged_rejected;
  g.depth_corrections += s.depth_corrections - isl->merged_depth_corrections;
  g.total_normal_impulse_Ns += s.total_normal_impulse_Ns - isl->merged_impulse_Ns;
  g.drive_work_J += s.drive_work_J - isl->merged_drive_work_J;
  d->steps += isl->data().steps - isl->merged_steps;
  as->counters.island_steps += isl->data().steps - isl->merged_steps;
  isl->merged_impacts = s.impacts;
  isl->merged_episodes = s.contact_episodes;
  isl->merged_recoveries = s.numerical_recoveries;
  isl->merged_rejected = s.rejected_steps;
  isl->merged_depth_corrections = s.depth_corrections;
  isl->merged_impulse_Ns = s.total_normal_impulse_Ns;
  isl->merged_drive_work_J = s.drive_work_J;
  isl->merged_steps = isl->data().steps;
}

void mergePeaks(Data* d, Island* isl) {
  const RunStats& s = isl->data().stats;
  RunStats& g = d->stats;
  if (s.peak_normal_force_N > g.peak_normal_force_N) {
    g.peak_normal_force_N = s.peak_normal_force_N;
    g.time_of_peak_normal_s = s.time_of_peak_normal_s;
  }
  if (s.peak_tangential_force_N > g.peak_tangential_force_N) {
    g.peak_tangential_force_N = s.peak_tangential_force_N;
    g.time_of_peak_tangential_s = s.time_of_peak_tangential_s;
  }
  g.max_penetration_m = std::max(g.max_penetration_m, s.max_penetration_m);
  g.max_energy_gain_at_impact_J =
      std::max(g.max_energy_gain_at_impact_J, s.max_energy_gain_at_impact_J);
  g.max_tip_deflection_ratio = std::max(g.max_tip_deflection_ratio, s.max_tip_deflection_ratio);
  if (s.deflection_warning_time_s >= 0 &&
      (g.deflection_warning_time_s < 0 ||
       s.deflection_warning_time_s < g.deflection_warning_time_s))
    g.deflection_warning_time_s = s.deflection_warning_time_s;
  for (; isl->merged_warnings < s.warnings.size(); ++isl->merged_warnings) {
    const std::string w = globalWarning(*isl, s.warnings[isl->merged_warnings]);
    if (std::find(g.warnings.begin(), g.warnings.end(), w) == g.warnings.end())
      g.warnings.push_back(w);
  }
}

void mergeKernelStats(Data* d, Island* isl) {
  const RunStats& s = isl->data().stats;
  RunStats& g = d->stats;
  for (size_t l = 0; l < isl->kernels.size(); ++l) {
    const int i = isl->kernels[l];
    g.kernel_peak_normal_force_N[i] =
        std::max(g.kernel_peak_normal_force_N[i], s.kernel_peak_normal_force_N[l]);
    g.kernel_impacts[i] += s.kernel_impacts[l] - isl->merged_kernel_impacts[l];
    isl->merged_kernel_impacts[l] = s.kernel_impacts[l];
    if (s.kernel_detach_time_s[l] >= 0 && g.kernel_detach_time_s[i] < 0)
      g.kernel_detach_time_s[i] = s.kernel_detach_time_s[l];
    const KernelToothPeaks& p = s.kernel_tooth_peaks[l];
    KernelToothPeaks& q = g.kernel_tooth_peaks[i];
    if (p.normal_force_N > q.normal_force_N) {
      q.normal_force_N = p.normal_force_N;
      q.time_of_normal_s = p.time_of_normal_s;
    }
    if (p.tangential_force_N > q.tangential_force_N) {
      q.tangential_force_N = p.tangential_force_N;
      q.time_of_tangential_s = p.time_of_tangential_s;
    }
  }
}

}  // namespace

void buildIsland(const Model& m, Data* d, AsyncState* as, int s, const std::vector<int>& teeth,
                 const std::vector<int>& kernels) {
  Island& isl = as->islands[s];
  isl.alive = true;
  isl.teeth = teeth;
  isl.kernels = kernels;
  // The pair memory outside islands (kept when an island dissolves) is sized at the first
  // island for every pair of the model: later islands find it reserved (no allocation).
  as->stored_memory.reserve(m.kernels.size() * (m.teeth.size() + 8) + 64);
  IslandSystem* sys = takeSystem(as, teeth, kernels.size());
  isl.sys = sys;
  const Model& sm = sys->model;
  Data& sd = sys->data;
  // What the system's workspace derived from its teeth alone is kept while the teeth stay
  // alike, though the reset would have it rebuilt on first use (each is rebuilt anyway at
  // another drum speed or step): the free-tooth propagators (set aside across the reset) and
  // the time-stepping iteration matrices (their keys restored).
  const bool alike = buildSubModel(m, sys, kernels);
  const double iteration_omega = sd.ws->ts.iteration_omega;
  const double iteration_basis_h = sd.ws->ts.iteration_basis_h;
  std::swap(sys->kept_prop, sd.ws->ed.prop);
  if (!alike) sys->kept_prop.clear();
  resetData(sm, &sd);
  std::swap(sys->kept_prop, sd.ws->ed.prop);
  if (alike) {
    sd.ws->ts.iteration_omega = iteration_omega;
    sd.ws->ts.iteration_basis_h = iteration_basis_h;
  }
  sd.ws->ed.memo.valid = false;  // the system's model now holds other kernels
  sd.t_s = d->t_s;
  sd.theta_rad = d->theta_rad;
  sd.omega_radps = d->omega_radps;
  sd.omega_target_radps = d->omega_target_radps;
  sd.alpha_radps2 = d->alpha_radps2;
  for (size_t l = 0; l < teeth.size(); ++l) {
    const ToothModel& tg = m.teeth[teeth[l]];
    const ToothModel& tl = sm.teeth[l];
    sd.z.segment(tl.dof_offset, tl.n_modes) = d->z.segment(tg.dof_offset, tg.n_modes);
    sd.u.segment(tl.dof_offset, tl.n_modes) = d->u.segment(tg.dof_offset, tg.n_modes);
    as->tooth_island[teeth[l]] = s;
  }
  for (size_t l = 0; l < kernels.size(); ++l) {
    const int i = kernels[l];
    sd.z.segment<3>(sm.kernels[l].dof_offset) = d->z.segment<3>(m.kernels[i].dof_offset);
    sd.u.segment<3>(sm.kernels[l].dof_offset) = d->u.segment<3>(m.kernels[i].dof_offset);
    sd.kernel_attached[l] = d->kernel_attached[i];
    sd.stats.kernel_detach_time_s[l] = d->stats.kernel_detach_time_s[i];
    KernelClock& kc = as->kernels[i];
    heapRemove(as, i);
    gridRemove(as, i);
    kc.motion = KernelMotion::kIsland;
    kc.island = s;
  }
  sd.stats.energy_initial_J = mechanicalEnergy(sm, sd);
  loadPairMemory(m, as, &isl);
  isl.merged_impacts = isl.merged_episodes = isl.merged_recoveries = isl.merged_rejected =
      isl.merged_depth_corrections = isl.merged_steps = 0;
  isl.merged_impulse_Ns = isl.merged_drive_work_J = 0;
  isl.merged_kernel_impacts.assign(kernels.size(), 0);
  isl.merged_warnings = 0;
  ++as->counters.islands_built;
}

void storeIslandState(const Model& m, Data* d, const AsyncState& as, int s) {
  const Island& isl = as.islands[s];
  const Model& sm = isl.model();
  const Data& sd = isl.data();
  for (size_t l = 0; l < isl.teeth.size(); ++l) {
    const ToothModel& tg = m.teeth[isl.teeth[l]];
    const ToothModel& tl = sm.teeth[l];
    d->z.segment(tg.dof_offset, tg.n_modes) = sd.z.segment(tl.dof_offset, tl.n_modes);
    d->u.segment(tg.dof_offset, tg.n_modes) = sd.u.segment(tl.dof_offset, tl.n_modes);
  }
  for (size_t l = 0; l < isl.kernels.size(); ++l) {
    const int i = isl.kernels[l];
    d->z.segment<3>(m.kernels[i].dof_offset) = sd.z.segment<3>(sm.kernels[l].dof_offset);
    d->u.segment<3>(m.kernels[i].dof_offset) = sd.u.segment<3>(sm.kernels[l].dof_offset);
    d->kernel_attached[i] = sd.kernel_attached[l];
  }
}

void dissolveIsland(const Model& m, Data* d, AsyncState* as, int s) {
  Island& isl = as->islands[s];
  storeIslandState(m, d, *as, s);
  // Episodes keep their start energy relative to this island's net energy (see loadPairMemory).
  const double e_net = islandNetEnergy(isl);
  for (auto& entry : isl.data().ws->memory) {
    if (!worthKeeping(entry.second)) continue;
    PairMemory& stored = as->stored_memory[pairKey(localToGlobal(isl, pairOfKey(entry.first)))];
    stored = entry.second;
    stored.energy_before_J -= e_net;
  }
  for (int k : isl.teeth) as->tooth_island[k] = -1;
  for (int i : isl.kernels) {
    KernelClock& kc = as->kernels[i];
    kc.motion = m.kernels[i].pedicel.present && d->kernel_attached[i] ? KernelMotion::kPedicel
                                                                      : KernelMotion::kFree;
    kc.island = -1;
    kc.t_s = isl.data().t_s;
    kc.h_s = 0;
  }
  isl.alive = false;
  isl.sys->in_use = false;
  isl.sys = nullptr;
  ++as->counters.islands_dissolved;
}

void mergeIslandResults(const Model& m, Data* d, AsyncState* as, int s) {
  (void)m;
  Island& isl = as->islands[s];
  for (const ContactEvent& ev : isl.data().events) {
    as->window_events.push_back(ev);
    as->window_events.back().pair = localToGlobal(isl, ev.pair);
  }
  isl.data().events.clear();
  mergeCounters(d, as, &isl);
  mergePeaks(d, &isl);
  mergeKernelStats(d, &isl);
}

void beginIslandObservation(const Model& m, Data* d, AsyncState* as, int s, double t1) {
  if (d->observer == nullptr) return;
  IslandStepHook& hook = as->observe_hook;
  hook.model = &m;
  hook.observer = d->observer;
  hook.as = as;
  hook.island = s;
  hook.t_window_end_s = t1;
  as->islands[s].data().ws->step_hook = &hook;
}

void endIslandObservation(AsyncState* as, int s) {
  Island& isl = as->islands[s];
  if (isl.sys != nullptr) isl.data().ws->step_hook = nullptr;
}

void IslandStepHook::afterStep(const Data& sd) const {
  const Island& isl = as->islands[island];
  as->observed_contacts.clear();
  for (const ContactInfo& c : sd.contacts) {
    as->observed_contacts.push_back(c);
    as->observed_contacts.back().pair = localToGlobal(isl, c.pair);
  }
  as->observed_events.clear();
  for (const ContactEvent& e : sd.events) {
    as->observed_events.push_back(e);
    as->observed_events.back().pair = localToGlobal(isl, e.pair);
  }
  IslandStep step;
  // The island's last step lands on the window's end or an ulp past it (integrateIslands puts
  // its clock on the end afterwards).
  step.t_s = std::min(sd.t_s, t_window_end_s);
  step.theta_rad = sd.theta_rad;
  step.omega_radps = sd.omega_radps;
  step.teeth = &isl.teeth;
  step.kernels = &isl.kernels;
  step.contacts = &as->observed_contacts;
  step.events = &as->observed_events;
  step.island_model = &isl.model();
  step.island_z = &sd.z;
  step.island_u = &sd.u;
  observer->islandStep(*model, step);
}

bool islandInContact(AsyncState* as, int s) {
  for (auto& entry : as->islands[s].data().ws->memory)
    if (entry.second.state != ContactState::kSeparated) return true;
  return false;
}

void publishIslandContacts(const AsyncState& as, std::vector<ContactInfo>* out) {
  for (const Island& isl : as.islands) {
    if (!isl.alive) continue;
    for (const ContactInfo& c : isl.data().contacts) {
      out->push_back(c);
      out->back().pair = localToGlobal(isl, c.pair);
    }
  }
}

}  // namespace internal

void IslandStep::writeState(const Model& model, VecX* z, VecX* u) const {
  const Model& sm = *island_model;
  for (size_t l = 0; l < teeth->size(); ++l) {
    const ToothModel& tg = model.teeth[(*teeth)[l]];
    const ToothModel& tl = sm.teeth[l];
    z->segment(tg.dof_offset, tg.n_modes) = island_z->segment(tl.dof_offset, tl.n_modes);
    u->segment(tg.dof_offset, tg.n_modes) = island_u->segment(tl.dof_offset, tl.n_modes);
  }
  for (size_t l = 0; l < kernels->size(); ++l) {
    const int i = (*kernels)[l];
    z->segment<3>(model.kernels[i].dof_offset) = island_z->segment<3>(sm.kernels[l].dof_offset);
    u->segment<3>(model.kernels[i].dof_offset) = island_u->segment<3>(sm.kernels[l].dof_offset);
  }
}

}  // namespace threshing_sim
