// Per-kernel outcomes from the run statistics, the event stream and contact samples.
#include "threshing_sim/scene/outcomes.h"

#include <algorithm>
#include <cmath>

namespace threshing_sim {
namespace {

// The kernels a pair acts on (one, or two for kernel-kernel pairs).
std::vector<int> kernelsOf(const PairId& p) {
  switch (p.kind) {
    case PairKind::kToothKernel:
      return {p.b};
    case PairKind::kKernelKernel:
      return {p.a, p.b};
    case PairKind::kKernelObstacle:
      return {p.a};
  }
  return {};
}

// Mass that meets the approach speed in an impact: the kernel's own against a tooth or an
// obstacle (both far heavier), the reduced mass of two kernels [kg].
double impactMass(const Model& m, const PairId& p) {
  if (p.kind == PairKind::kKernelKernel) {
    const double ma = m.kernels[p.a].mass_kg, mb = m.kernels[p.b].mass_kg;
    return ma * mb / (ma + mb);
  }
  return m.kernels[kernelsOf(p).front()].mass_kg;
}

}  // namespace

const char* toString(DamageClass c) {
  switch (c) {
    case DamageClass::kNone:
      return "none";
    case DamageClass::kPlastic:
      return "plastic";
    case DamageClass::kFracture:
      return "fracture";
  }
  return "?";
}

DamageClass classifyDamage(double peak_normal_force_N, const DamageThresholds& thresholds) {
  if (peak_normal_force_N >= thresholds.fracture_force_N) return DamageClass::kFracture;
  if (peak_normal_force_N >= thresholds.plastic_force_N) return DamageClass::kPlastic;
  return DamageClass::kNone;
}

OutcomeTracker::OutcomeTracker(const Model& model, const DamageThresholds& thresholds)
    : model_(model), thresholds_(thresholds), kernels_(model.kernels.size()) {}

void OutcomeTracker::addEvents(const std::vector<ContactEvent>& events) {
  for (const ContactEvent& e : events) {
    if (!e.is_impact) continue;
    impulses_[e.pair].events_Ns += e.impulse_normal_Ns;
    // Impacts and impact energy count for every kernel of the pair.
    const double energy_J = 0.5 * impactMass(model_, e.pair) * e.vn_before_mps * e.vn_before_mps;
    for (const int k : kernelsOf(e.pair)) {
      KernelTally& tally = kernels_[k];
      ++tally.impacts;
      tally.max_impact_energy_J = std::max(tally.max_impact_energy_J, energy_J);
    }
    // Sub-collisions are counted per tooth-kernel macro-collision.
    if (e.pair.kind == PairKind::kToothKernel && e.macro_collision >= 0) {
      ++kernels_[e.pair.b].subs_per_macro[{e.pair.a, e.macro_collision}];
    }
  }
}

void OutcomeTracker::sample(const Data& data) {
  for (const ContactInfo& c : data.contacts) {
    PairImpulse& impulse = impulses_[c.pair];
    impulse.sampled_Ns = std::max(impulse.sampled_Ns, c.impulse_normal_Ns);
  }
}

std::vector<KernelOutcome> OutcomeTracker::outcomes(const Data& data) const {
  const RunStats& stats = data.stats;
  std::vector<KernelOutcome> out(kernels_.size());
  for (size_t i = 0; i < kernels_.size(); ++i) {
    const KernelTally& tally = kernels_[i];
    KernelOutcome& o = out[i];

    // Tooth force peaks and their times: the core's, at every accepted force evaluation.
    if (i < stats.kernel_tooth_peaks.size()) {
      const KernelToothPeaks& peaks = stats.kernel_tooth_peaks[i];
      o.peak_normal_force_N = peaks.normal_force_N;
      o.time_of_peak_normal_s = peaks.time_of_normal_s;
      o.peak_tangential_force_N = peaks.tangential_force_N;
      o.time_of_peak_tangential_s = peaks.time_of_tangential_s;
    }
    if (o.time_of_peak_normal_s >= 0 && o.time_of_peak_tangential_s >= 0) {
      o.peak_separation_s = o.time_of_peak_tangential_s - o.time_of_peak_normal_s;
    }

    // Impacts and collisions.
    o.impacts = tally.impacts;
    o.max_impact_energy_J = tally.max_impact_energy_J;
    o.macro_collisions = static_cast<int>(tally.subs_per_macro.size());
    for (const auto& macro : tally.subs_per_macro) {
      o.sub_collisions += macro.second;
      o.max_sub_collisions = std::max(o.max_sub_collisions, macro.second);
    }

    // Largest normal force of any contact on the kernel (the core's statistic).
    o.max_contact_force_N =
        i < stats.kernel_peak_normal_force_N.size() ? stats.kernel_peak_normal_force_N[i] : 0.0;

    // Detachment and damage.
    o.detach_time_s = i < stats.kernel_detach_time_s.size() ? stats.kernel_detach_time_s[i] : -1;
    o.detached = o.detach_time_s >= 0;
    o.damage = classifyDamage(o.max_contact_force_N, thresholds_);
  }

  // Impulses: each pair's larger estimate, to each of its kernels.
  for (const auto& entry : impulses_) {
    const double impulse_Ns = std::max(entry.second.events_Ns, entry.second.sampled_Ns);
    for (const int k : kernelsOf(entry.first)) out[k].total_normal_impulse_Ns += impulse_Ns;
  }
  return out;
}

}  // namespace threshing_sim
