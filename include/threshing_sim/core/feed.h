// threshing_sim core: a continuous feed (issue 34). Kernels on pedicels whose anchors ride a
// straw mat along the concave at a set speed arrive at a set rate, with seeded scatter, for as
// long as the run lasts; each leaves the simulation when it passes through the grate
// (separated), past the concave's exit (carried over: detached, or still on its pedicel =
// unthreshed) or out of a bounding circle, and its outcome is final then.
//
// Bodies live in a pool: the feed appends `capacity` kernel slots to the Model before it is
// compiled (addFeedPool); a slot is either occupied by a fed kernel (Data::kernel_active 1) or
// parked (0: far from every body, at rest, no force on it, its pedicel released). A kernel
// entering takes the slot that has been free longest; a slot is reused only after the
// integrator took a step with it parked, so no pair memory of its last kernel is in use. At a
// step boundary updateFeed retires the kernels that left, then places the kernels due. The
// occupant's own values (mass, detachment force, anchor) are written into its slot's
// KernelModel there: the Model changes only at step boundaries and only through this file.
// Global scheme only (integrator.islands: false): the island scheme's bounds assume fixed
// pedicel anchors; the island scheme never sees a pool.
//
// Geometry (world frame W, drum axis at the origin, the drum turning with Omega > 0 so that its
// bottom moves along +x): the concave is taken flat under the drum (its curvature neglected
// over the span): the grate is the line y = grate_y from x = inlet_x to x = exit_x; the mat
// carries the anchors along +x at mat_speed at heights anchor_y +- mat_thickness / 2, each
// kernel hanging below its anchor.
#pragma once

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/uniform.h"

namespace threshing_sim {

// How a fed kernel ended (kInDrum while it is in the simulation).
enum class KernelFate : std::uint8_t {
  kInDrum = 0,             // still in the simulation
  kSeparated = 1,          // passed through the grate
  kCarriedDetached = 2,    // past the concave's exit, off its pedicel (threshed, not separated)
  kCarriedUnthreshed = 3,  // past the concave's exit, still on its pedicel
  kOutOfBounds = 4,        // left the bounding circle (or below the grate line outside its span)
};
const char* toString(KernelFate fate);

// The feed's parameters (scene section `feed`, docs/scene_reference.md).
struct FeedSpec {
  double rate_per_s = 0;              // kernels fed per second of simulated time [1/s]
  double mat_speed_mps = 1.0;         // the straw mat's (and the anchors') speed along +x [m/s]
  double start_s = 0;                 // arrival of the first kernel at the inlet [s]
  int seed = 1;                       // seed of the scatter [-]
  int capacity = 0;                   // pool slots: kernels in the simulation at once [-]
  double inlet_x_m = -0.1;            // concave inlet: anchors arrive at this x [m]
  double exit_x_m = 0.1;              // concave exit [m]
  double anchor_y_m = 0;              // mid-height of the anchors on the mat [m]
  double mat_thickness_m = 0.01;      // anchors' heights uniform over +- half of it [m]
  double grate_y_m = -0.27;           // the grate line [m]
  double bound_radius_m = 0.5;        // kernels farther from the drum axis have left [m]
  double pedicel_length_m = 0.003;    // pedicel from the kernel's upper end to its anchor [m]
  double position_scatter_m = 0.002;  // +- along the mat at arrival [m]
  double angle_scatter_rad = 0.3;     // +- about hanging straight down [rad]
  Vec2 mass_kg{2.4e-5, 3.1e-5};       // mass range [kg]
  Vec2 detach_N{0.27, 2.6};           // detachment force range [N]
  KernelModel base;                   // semi-axes, material, pedicel stiffness and damping
  double kernel_mass_mean_kg() const { return 0.5 * (mass_kg.x() + mass_kg.y()); }
};

// A fed kernel that left the simulation: its final outcome.
struct FeedRecord {
  long id = 0;           // feed number (0 = first kernel fed) [-]
  int slot = 0;          // model kernel index it occupied [-]
  double arrival_s = 0;  // arrival at the inlet [s]
  double retired_s = 0;  // step end at which it was seen to have left [s]
  KernelFate fate = KernelFate::kInDrum;
  double mass_kg = 0;                   // [kg]
  double peak_normal_N = 0;             // largest tooth normal force on it [N]
  double peak_tangential_N = 0;         // largest |tooth tangential force| on it [N]
  double peak_contact_N = 0;            // largest normal force of any contact on it [N]
  long impacts = 0;                     // completed impacts on it, any pair [-]
  double detach_s = -1;                 // pedicel break time; < 0: never broke [s]
  Vec2 exit_position_m = Vec2::Zero();  // centre when retired, world [m]
};

// Running totals. At every step boundary after updateFeed:
// fed = in_drum + separated + carried_detached + carried_unthreshed + out_of_bounds.
struct FeedCounts {
  long fed = 0;                 // kernels placed so far [-]
  long in_drum = 0;             // kernels in the simulation now [-]
  long separated = 0;           // [-]
  long carried_detached = 0;    // [-]
  long carried_unthreshed = 0;  // [-]
  long out_of_bounds = 0;       // [-]
  bool balanced() const {
    return fed == in_drum + separated + carried_detached + carried_unthreshed + out_of_bounds;
  }
};

// The feed's running state (one per run).
struct FeedState {
  int first_slot = 0;                  // model kernel index of pool slot 0 [-]
  int capacity = 0;                    // pool slots [-]
  std::vector<long> slot_id;           // occupant's feed number, or -1 (free) [-]
  std::vector<double> slot_arrival_s;  // occupant's arrival [s]
  std::vector<long> slot_parked_step;  // Data::steps when the slot was parked [-]
  std::vector<int> free_ring;          // free slots, longest free first (a ring of capacity) [-]
  int free_head = 0, free_count = 0;   // ring read position and fill [-]
  FeedCounts counts;
  double base_t_s = 0;              // kernel n arrives at base_t + (n - base_n) / rate [s]
  long base_n = 0;                  // (the last rate command's reference) [-]
  double last_arrival_s = 0;        // arrival of the last kernel fed (none: -inf) [s]
  std::vector<FeedRecord> retired;  // kernels that left since the caller last cleared it
  Uniform uniform;                  // the scatter's numbers
  std::string error;                // why updateFeed failed ("" if it did not)
};

// Slot i's parking place: far above the drum, slots 0.05 m apart, world [m].
Vec2 feedParkingPlace(int slot);

// Checks spec (throws std::invalid_argument naming the `feed.*` key and the value) and appends
// spec.capacity parked kernel slots to model->kernels. Before compileModel.
void addFeedPool(const FeedSpec& spec, Model* model);

// After resetData: parks every slot, empties the pool and seeds the scatter.
void startFeed(const FeedSpec& spec, const Model& model, Data* data, FeedState* state);

// At a step boundary: retires the kernels that left (appending their records to
// state->retired), then places every kernel that has arrived by data->t_s. Returns false with
// state->error set when the pool has no slot for a kernel due, or a kernel cannot be placed
// clear of the others.
bool updateFeed(const FeedSpec& spec, Model* model, Data* data, FeedState* state);

// updateFeed's two stages, for a caller that must know when the model changes (the node changes
// a copy of a model its output thread may still read): retireFeedKernels leaves the model alone;
// placeFeedKernels (returns as updateFeed) writes the placed kernels' values into their slots,
// and changes nothing when no kernel is due by data->t_s (feedKernelDue).
void retireFeedKernels(const FeedSpec& spec, const Model& model, Data* data, FeedState* state);
bool placeFeedKernels(const FeedSpec& spec, Model* model, Data* data, FeedState* state);
bool feedKernelDue(const FeedSpec& spec, const FeedState& state, double t_s);

// Simulated time between two feed updates [s]: `simulate` and the node update the feed at the
// first step end at or past the next multiple of it after the last update (nextFeedUpdate), so
// that both run a fed scene with the same steps.
constexpr double kFeedUpdateStep_s = 1e-4;
// The time the next update is due after one at a step end at t_s: the next multiple of
// kFeedUpdateStep_s [s].
inline double nextFeedUpdate(double t_s) {
  return (std::floor(t_s / kFeedUpdateStep_s) + 1) * kFeedUpdateStep_s;
}

// Arrival time of the next kernel to be fed (+inf at rate 0) [s].
double nextFeedArrival(const FeedSpec& spec, const FeedState& state);

// A feed rate command, applied at a step boundary at time t_s (the caller's: a node stages it
// and applies it there): from then on kernels arrive 1 / rate_per_s apart, the next one at the
// later of t_s and the last arrival plus the new interval; 0 stops the feed. Returns "" or why
// the command was refused, naming the value (spec and state unchanged then): not finite,
// negative, above 1e6 1/s, or more kernels riding the mat than the pool holds.
std::string setFeedRate(double rate_per_s, double t_s, FeedSpec* spec, FeedState* state);

// setFeedRate's test alone, for a caller that refuses a command before staging it (the node's
// feed_rate_cmd callback): "" when rate_per_s would be accepted for spec's geometry and a pool of
// `capacity` slots, else why not, naming the value.
std::string checkFeedRate(double rate_per_s, const FeedSpec& spec, int capacity);

// The fate of a kernel at centre c (attached: its pedicel holds) under spec's geometry.
KernelFate feedFate(const FeedSpec& spec, const Vec2& c_W, bool attached);

// ---------------------------------------------------------------------------------------------
// The feed's time series (src/core/feed/series.cc): one source for `simulate --feed-series`
// and the node's feed_throughput topic.

// One interval of the series: the kernels fed and retired in it, their peak forces, the drum's
// load. Counts are of the interval, in_drum is at its end.
struct FeedIntervalRow {
  double t_start_s = 0;          // start of the interval [s]
  double t_end_s = 0;            // end (a step end) [s]
  long fed = 0;                  // kernels placed in the interval [-]
  long threshed = 0;             // retired off their pedicels [-]
  long damaged = 0;              // retired with a contact force >= the plastic force [-]
  long separated = 0;            // retired through the grate [-]
  long carried_detached = 0;     // retired past the exit, off their pedicels [-]
  long carried_unthreshed = 0;   // retired past the exit, still on their pedicels [-]
  long out_of_bounds = 0;        // retired out of bounds [-]
  long in_drum = 0;              // kernels in the simulation at the end [-]
  double peak_force_mean_N = 0;  // mean of the retired kernels' peak tooth normal forces [N]
  double peak_force_p50_N = 0;   // their median (nearest rank) [N]
  double peak_force_p90_N = 0;   // their 90th percentile (nearest rank) [N]
  double peak_force_max_N = 0;   // their largest [N]
  double drive_work_J = 0;       // work of the drum drive over the interval [J]
  double power_W = 0;            // mean power of the drive: work / length [W]
  double torque_Nm = 0;          // mean load torque: work / drum angle turned [N m]
};

// Totals since the series started.
struct FeedTotals {
  long threshed = 0;      // retired off their pedicels [-]
  long damaged = 0;       // retired with a contact force >= the plastic force [-]
  double peak_sum_N = 0;  // sum of the retired kernels' peak tooth normal forces [N]
  long peak_count = 0;    // kernels in that sum [-]
  double peakMean_N() const { return peak_count > 0 ? peak_sum_N / peak_count : 0.0; }
};

// Accumulates the retired kernels into the current interval and the totals; close() ends the
// interval and starts the next. Drum load: the drive's work over an interval (RunStats::
// drive_work_J, integrated by the integrator with the teeth's contact forces in it) over the
// interval's length is the mean power; over the drum angle turned, the mean load torque.
class FeedSeries {
 public:
  // Starts the first interval at data's time (counts c: the feed's now) and clears the totals.
  // capacity: retired kernels an interval usually holds (reserved, no allocation per step).
  void start(const Data& d, const FeedCounts& c, int capacity);
  // One retired kernel (plastic_force_N: the damage threshold [N]).
  void add(const FeedRecord& r, double plastic_force_N);
  // The row of the interval ending at d.t_s (counts c: the feed's now); the next one starts.
  FeedIntervalRow close(const Data& d, const FeedCounts& c);
  const FeedTotals& totals() const { return totals_; }
  double intervalStart_s() const { return t_start_s_; }

 private:
  double t_start_s_ = 0;             // [s]
  FeedCounts at_start_;              // the counts at the start
  long threshed_ = 0, damaged_ = 0;  // in the interval [-]
  std::vector<double> peaks_N_;      // retired kernels' peak tooth normal forces [N]
  double drive_work_start_J_ = 0;    // RunStats::drive_work_J at the start [J]
  double theta_start_rad_ = 0;       // drum angle at the start [rad]
  FeedTotals totals_;
};

// Nearest-rank percentile p in [0, 1] of sorted values (0 for none).
double feedPercentile(const std::vector<double>& sorted, double p);

}  // namespace threshing_sim
