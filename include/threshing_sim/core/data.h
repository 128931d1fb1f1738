// threshing_sim core: all mutable simulation state (cf. MuJoCo mjData, Pinocchio Data).
//
// Generalised coordinates z (size model.n_dof) are laid out tooth by tooth (n modal
// coordinates each, mass-normalised so their mass matrix is the identity; unit sqrt(kg) m),
// then kernel by kernel (c_x [m], c_y [m], psi [rad]). u = dz/dt has the matching units per
// second. The drum angle and speed are rheonomic (prescribed by the drive), not in z.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "threshing_sim/core/failure.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// The four contact states of docs/model.md §7.
enum class ContactState : std::uint8_t { kSeparated = 0, kImpact = 1, kStick = 2, kSlip = 3 };
const char* toString(ContactState s);
const char* toString(PairKind k);

// Identity of a potential contact pair.
//   tooth_kernel:    a = tooth index,  b = kernel index
//   kernel_kernel:   a < b, kernel indices
//   kernel_obstacle: a = kernel index, b = obstacle index
struct PairId {
  PairKind kind = PairKind::kToothKernel;
  int a = 0;
  int b = 0;
  bool operator==(const PairId& o) const { return kind == o.kind && a == o.a && b == o.b; }
  bool operator<(const PairId& o) const;
};

// One pair that survived the broad phase in the last step: geometry, state and forces.
struct ContactInfo {
  PairId pair;
  ContactState state = ContactState::kSeparated;
  double gap_m = 0;                // signed gap g_N; negative = penetration [m]
  Vec2 p_W = Vec2::Zero();         // contact point (midway between the closest points), world [m]
  Vec2 n_W = Vec2::UnitY();        // unit normal towards the kernel b (from the tooth, the kernel a
                                   // or the obstacle), world [-]
  double tooth_x_m = 0;            // tooth contacts: material coordinate of the contact [m]
  double normal_velocity_mps = 0;  // dg_N/dt (positive = separating) [m/s]
  double slip_velocity_mps = 0;    // dg_T/dt along t = J n [m/s]
  double normal_force_N = 0;       // lambda_N on the kernel (impulse / h under time stepping) [N]
  double tangential_force_N = 0;   // lambda_T on the kernel along t = J n [N]
  double impulse_normal_Ns = 0;    // normal impulse of this pair since reset (running sum) [N s]
  double impulse_tangential_Ns = 0;  // tangential impulse likewise [N s]
};

// One impact (initial contact) or state transition of a pair.
struct ContactEvent {
  double t_s = 0;  // simulation time [s]
  PairId pair;
  ContactState from = ContactState::kSeparated;
  ContactState to = ContactState::kImpact;
  bool is_impact = false;  // true for a completed impact (rigid: the jump; compliant: the episode)
  double vn_before_mps = 0;      // normal relative velocity before [m/s] (negative = approaching)
  double vn_after_mps = 0;       // after [m/s]
  double vt_before_mps = 0;      // tangential relative velocity before [m/s]
  double vt_after_mps = 0;       // after [m/s]
  double impulse_normal_Ns = 0;  // normal impulse of the impact [N s]
  double impulse_tangential_Ns = 0;  // tangential impulse [N s]
  double energy_lost_J = 0;  // kinetic energy lost net of drive work (>= 0 when dissipative) [J]
  double peak_normal_force_N = 0;  // compliant episodes: peak normal force [N]
  int macro_collision = -1;        // index of the macro-collision of this pair (0-based)
  int sub_collision = -1;          // index of this impact within its macro-collision (0-based)
};

// Peak tooth contact forces on one kernel over a run, and when they occurred. Updated at every
// force evaluation an integrator accepts: at the end of every accepted step, and at a located
// event both before and after the contact modes switch (time stepping: once per step).
struct KernelToothPeaks {
  double normal_force_N = 0;         // largest normal force of any tooth on the kernel [N]
  double time_of_normal_s = -1;      // when it first occurred; < 0 = no tooth force yet [s]
  double tangential_force_N = 0;     // largest |tangential force| (at most mu times the normal
                                     // force) of any tooth (knead force) [N]
  double time_of_tangential_s = -1;  // when it first occurred; < 0 = none yet [s]
};

// Work of the asynchronous island-local scheduler by kind (integrator.islands: true), the
// terms of its cost model: each count times its cost per occurrence is the run's cost.
struct SchedulerStats {
  long windows = 0;            // scheduling windows (islands and teeth meet at their ends)
  long island_steps = 0;       // accepted integrator steps inside islands
  long island_body_steps = 0;  // the same, each counted once per body of its island
  long islands_built = 0;      // islands formed (new, grown or merged)
  long islands_dissolved = 0;  // islands dissolved (bodies lazy again, or re-formed)
  long tooth_wakes = 0;        // lazy kernels met by a tooth's swept sector
  long kernel_wakes = 0;       // lazy kernels met by an island kernel's reach
  long predictions = 0;        // new bound circles of lazy kernels (calendar events)
  long shrinks = 0;            // lazy kernels re-predicted tighter instead of woken
  long pedicel_steps = 0;      // accepted own-clock steps of lone kernels on pedicels
  long pedicel_rejected = 0;   // rejected own-clock steps
  long sleeps = 0;             // own-clock jumps of a kernel at rest on its pedicel (no step)
  long asleep = 0;             // predictions of a kernel at rest (a circle for the longest horizon)
  long pedicel_breaks = 0;     // pedicels broken on a lone kernel's own clock
  long free_advances = 0;      // closed-form advances of free kernels
  long tooth_advances = 0;     // exact advances of free teeth
};

// Running statistics over a run (reset by resetData).
struct RunStats {
  long impacts = 0;                      // completed impacts, all pairs
  long contact_episodes = 0;             // separated -> contact transitions
  double peak_normal_force_N = 0;        // max normal force seen, any pair [N]
  double peak_tangential_force_N = 0;    // max |tangential force|, at most mu fn [N]
  double time_of_peak_normal_s = 0;      // [s]
  double time_of_peak_tangential_s = 0;  // [s]
  double total_normal_impulse_Ns = 0;    // integral of all normal forces plus impulses [N s]
  double max_penetration_m = 0;          // max of -g_N over closed contacts [m]
  double max_energy_gain_at_impact_J =
      0;                          // largest energy rise across one impact (should be ~0) [J]
  double drive_work_J = 0;        // work done by the drum drive [J]
  double energy_initial_J = 0;    // mechanical energy at reset [J]
  long numerical_recoveries = 0;  // steps redone after a non-finite result
  long rejected_steps = 0;        // event-driven: rejected trial steps
  long depth_corrections = 0;     // time stepping: position corrections of pressed rigid
                                  // contacts (sunk below their impact depth, or risen off
                                  // the surface)
  std::vector<double> kernel_peak_normal_force_N;  // per kernel, any contact [N]
  std::vector<long> kernel_impacts;                // per kernel
  std::vector<double> kernel_detach_time_s;        // per kernel; < 0 = still attached [s]
  std::vector<std::string> warnings;               // model-validity warnings (deduplicated)
  double max_tip_deflection_ratio = 0;    // largest |w(L)| / L of any tooth at a step end [-]
  double deflection_warning_time_s = -1;  // first step end with |w(L)| / L above
                                          // model.deflection_validity_fraction; < 0 = never [s]
  // Per kernel: peak tooth contact forces [N] and their times [s] (sized by resetData).
  std::vector<KernelToothPeaks> kernel_tooth_peaks;
  SchedulerStats scheduler;  // the island-local scheduler's work (zero under the global scheme)
  FailureInfo failure;       // why the last advanceTo() failed (cause kNone if it did not)
};

struct Workspace;    // integrator scratch memory, opaque
class StepObserver;  // island steps' observer (step_observer.h)

struct Data {
  double t_s = 0;                             // simulation time [s]
  long steps = 0;                             // accepted integrator steps
  double theta_rad = 0;                       // drum angle [rad]
  double omega_radps = 0;                     // drum speed Omega [rad/s]
  double omega_target_radps = 0;              // commanded drum speed [rad/s]
  double alpha_radps2 = 0;                    // current drum acceleration dOmega/dt [rad/s^2]
  VecX z;                                     // generalised positions (see file comment)
  VecX u;                                     // generalised velocities
  std::vector<std::uint8_t> kernel_attached;  // 1 while the pedicel holds [-]
  // 1 while the kernel takes part; 0: a retired slot of a feed's pool (core/feed.h), parked far
  // from every body, at rest, with no force on it (global scheme only) [-]
  std::vector<std::uint8_t> kernel_active;
  std::vector<ContactInfo> contacts;  // pairs examined in the last step
  std::vector<ContactEvent> events;   // appended by step(); the caller may clear it
  RunStats stats;
  // Not owned; if set, the island scheme reports every accepted step of its islands to it
  // (step_observer.h). Observing changes no result. Unset (nullptr) costs nothing.
  StepObserver* observer = nullptr;

  Data();
  ~Data();
  Data(Data&&) noexcept;
  Data& operator=(Data&&) noexcept;
  Data(const Data&) = delete;
  Data& operator=(const Data&) = delete;

  std::unique_ptr<Workspace> ws;  // scratch, reused across steps (no allocation after warm-up)
};

}  // namespace threshing_sim
