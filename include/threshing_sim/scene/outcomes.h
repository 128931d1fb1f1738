// threshing_sim per-kernel outcomes: what a drum designer reads off a run.
//
// For each kernel: the peak normal and peak tangential (knead) force of its contacts with the
// teeth and the time between the two peaks, the largest normal force of any contact (teeth,
// other kernels, concave) and the damage class it gives against force thresholds, total normal
// impulse, impacts, tooth-kernel macro-collisions and their sub-collisions, largest impact
// energy, and detachment. Computed from three sources, none of which needs ROS:
//   - the run statistics of the core (RunStats): per kernel, the tooth force peaks with their
//     times and the largest normal force of any contact, updated at every force evaluation the
//     integrator accepts (every accepted step, and both sides of a located event), so they do
//     not depend on how often the caller looks; and the detach times;
//   - the ContactEvent stream (impacts, macro-/sub-collision indices, impulses, approach
//     speeds), fed with addEvents() before the caller clears Data::events;
//   - samples of Data::contacts taken with sample() after each advanceTo(), for the accumulated
//     impulses of pairs in persistent contact (rigid law), which have no impact event.
//
// Macro-collision rule (the core's, Model::macro_collision_gap_s, scene key
// `macro_collision_gap`): the contact episodes of one tooth-kernel pair belong to the same
// macro-collision while each starts less than the gap after the previous one ended; each episode
// (compliant law) or impact (rigid law) is one sub-collision. Only tooth-kernel pairs count.
#pragma once

#include <map>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// Thresholds on a kernel's peak normal contact force (rice: docs/model.md §10).
struct DamageThresholds {
  double plastic_force_N = 139.0;   // plastic deformation at or above this force [N]
  double fracture_force_N = 146.0;  // brittle fracture at or above this force [N]
};

enum class DamageClass { kNone = 0, kPlastic = 1, kFracture = 2 };
const char* toString(DamageClass c);

// Damage class of a peak normal force [N].
DamageClass classifyDamage(double peak_normal_force_N, const DamageThresholds& thresholds);

struct KernelOutcome {
  double peak_normal_force_N = 0;           // max normal force of a tooth on the kernel [N]
  double time_of_peak_normal_s = -1;        // time of that peak; < 0 = no tooth contact [s]
  double peak_tangential_force_N = 0;       // max |tangential force| of a tooth (knead force) [N]
  double time_of_peak_tangential_s = -1;    // time of that peak; < 0 = none [s]
  double peak_separation_s = 0;             // time_of_peak_tangential - time_of_peak_normal [s]
                                            // (0 unless both peaks exist)
  double max_contact_force_N = 0;           // max normal force of any contact on the kernel [N]
  double total_normal_impulse_Ns = 0;       // normal impulse of all contacts on the kernel [N s]
  long impacts = 0;                         // completed impacts, all pairs of the kernel
  int macro_collisions = 0;                 // tooth-kernel macro-collisions
  long sub_collisions = 0;                  // tooth-kernel sub-collisions, all macro-collisions
  int max_sub_collisions = 0;               // most sub-collisions in one macro-collision
  double max_impact_energy_J = 0;           // max of m_eff vn_before^2 / 2 over its impacts [J]
  bool detached = false;                    // the pedicel broke
  double detach_time_s = -1;                // when; < 0 = still attached (or no pedicel) [s]
  DamageClass damage = DamageClass::kNone;  // of max_contact_force_N

  // Sub-collisions per macro-collision (0 without any).
  double subCollisionsPerMacro() const {
    return macro_collisions > 0 ? static_cast<double>(sub_collisions) / macro_collisions : 0.0;
  }
};

// Accumulates events and contact samples over one run, then reports per-kernel outcomes.
// The model must outlive the tracker.
class OutcomeTracker {
 public:
  OutcomeTracker(const Model& model, const DamageThresholds& thresholds);

  // Every event of the run, in order; call before Data::events is cleared.
  void addEvents(const std::vector<ContactEvent>& events);

  // One sample of Data::contacts (accumulated impulses) at data.t_s.
  void sample(const Data& data);

  // Outcomes per kernel; data supplies the run statistics (force peaks, detach times). Pass the
  // same data the samples came from, at the end of the run.
  std::vector<KernelOutcome> outcomes(const Data& data) const;

  const DamageThresholds& thresholds() const { return thresholds_; }

 private:
  // Normal impulse of one pair: the sum over its impact events, and the largest accumulated
  // value seen in the samples (which also holds persistent-contact impulses under the rigid law).
  struct PairImpulse {
    double events_Ns = 0;
    double sampled_Ns = 0;
  };
  struct KernelTally {
    long impacts = 0;
    double max_impact_energy_J = 0;
    std::map<std::pair<int, int>, int> subs_per_macro;  // (tooth, macro index) -> sub-collisions
  };

  const Model& model_;
  DamageThresholds thresholds_;
  std::vector<KernelTally> kernels_;
  std::map<PairId, PairImpulse> impulses_;
};

}  // namespace threshing_sim
