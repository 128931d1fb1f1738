// threshing_sim core, private: the pair table, the memory of every contact pair carried across
// steps (contact state, episode bookkeeping for events and statistics, warm starts), stored by
// pair key (src/core/contact/pair_table.cc).
#pragma once

#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Per-pair memory carried across steps (state, episode bookkeeping for events and stats).
struct PairMemory {
  ContactState state = ContactState::kSeparated;
  bool closed = false;           // rigid law: normal constraint active
  int slip_sign = 0;             // slip direction while sliding (sign of dg_T/dt)
  bool slip_from_stick = false;  // sliding since its stick reached the friction limit, its slip
                                 // velocity not yet past the velocity error scale (the event-
                                 // driven integrator's slipReversalScale) [-]
  double v_in_mps = 0;           // compliant: approach speed at first touch [m/s]
  double hertz_K = 0;            // compliant: Hertz constant frozen at first touch, so that the
                                 // force of one episode derives from a potential [N/m^{3/2}]
  double ts_depth_m = 0;         // time stepping, rigid law: penetration the closed contact
                                 // may keep (its impact step's, at least h x zeno_velocity) [m]
  double episode_start_s = -1;   // time of first touch of the current episode [s]
  double episode_peak_N = 0;     // peak normal force within the episode [N]
  double episode_impulse_n = 0;  // normal impulse within the episode [N s]
  double episode_impulse_t = 0;  // tangential impulse within the episode [N s]
  double vn_before = 0, vt_before = 0;  // velocities at the start of the episode [m/s]
  double energy_before_J = 0;           // energy minus drive work at the start of the episode [J]
  double last_contact_end_s = -1;       // end of the previous episode [s]
  double warm_x_m = -1;       // tooth pairs: material coordinate of the last closest point (the
                              // narrow phase's warm start while in contact; -1 none) [m]
  double warm_t_s = 0;        // the time it was found at [s]
  double warm_x_prev_m = -1;  // the closest point before it (-1 none) [m]
  double warm_t_prev_s = 0;   // and its time [s]
  double warm_theta_rad =
      std::numeric_limits<double>::quiet_NaN();  // kernel-kernel pairs:
                                                 // separating direction of the last query
                                                 // (ellipseEllipse's warm start; NaN none) [rad]
  int macro_index = -1;                          // macro-collision counter of this pair
  int sub_index = -1;                            // sub-collision index within the macro-collision
  double normal_force_N = 0;                     // last force values (for ContactInfo) [N]
  double tangential_force_N = 0;
  // The contact phase (src/core/contact_phase/): the step set by this episode's Hertz time, the
  // episode start it was set for, and the forces of the step end before the last (for the
  // located force peaks).
  double cp_step_s = 0;             // [s]
  double cp_step_for_s = -1;        // [s]
  double cp_fn_before_N = 0;        // [N]
  double cp_ft_before_N = 0;        // [N]
  double cp_t_before_s = -1;        // its time (< 0: none) [s]
  // The contact phase's conservative advancement of a separated pair (event_driven/evaluate.cc,
  // SeparatedPairs::kReach): apart until cp_safe_until_s, found at cp_safe_from_s with the gap
  // (or its bound) cp_safe_gap_m at the bodies' speed bound cp_safe_speed_mps.
  double cp_safe_from_s = 0;                                         // [s]
  double cp_safe_until_s = -std::numeric_limits<double>::infinity();  // [s]
  double cp_safe_speed_mps = 0;                                      // [m/s]
  double cp_safe_gap_m = 0;                                          // [m]
  double cp_drift_mps2 = 0;         // the last step's drift changed the slip velocity at this
                                    // rate (the contact points' motion, the free modes) [m/s^2]
  double impulse_n_acc = 0;  // running sums of the impulses since reset [N s]
  double impulse_t_acc = 0;
  bool seen = false;  // touched by the broad phase in the current step
};

std::uint64_t pairKey(const PairId& p);

// Pair memory by pair key: open addressing over a dense array of entries. Lookups and inserts
// allocate nothing while the reserved capacity holds (reserve() at reset sizes it from the
// model); entries are never removed except by clear(). Iteration visits entries in insertion
// order, so it is deterministic.
class PairTable {
 public:
  using Entry = std::pair<std::uint64_t, PairMemory>;
  // Room for n entries without allocating.
  void reserve(size_t n);
  // The memory of a pair, default-constructed on first use.
  PairMemory& operator[](std::uint64_t key);
  // The memory of a pair if it has an entry, else nullptr (nothing is inserted).
  const PairMemory* find(std::uint64_t key) const;
  // Index of the entry of key in the dense array (inserting it if new).
  int indexOf(std::uint64_t key);
  Entry& entry(int index) { return entries_[index]; }
  void clear();
  size_t size() const { return entries_.size(); }
  std::vector<Entry>::iterator begin() { return entries_.begin(); }
  std::vector<Entry>::iterator end() { return entries_.end(); }

 private:
  void rehash(size_t n_slots);
  std::vector<Entry> entries_;  // dense, insertion order
  std::vector<int> slots_;      // hash table of indices into entries_ (-1 = empty), 2^k long
};

}  // namespace internal
}  // namespace threshing_sim
