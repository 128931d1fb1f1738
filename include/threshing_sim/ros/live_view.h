// threshing_sim ROS layer: what a user watches and plots, computed without ROS publishing.
//
//  - StrikeRecorder: the force history of every tooth-kernel contact episode, sampled at the
//    node's sub-steps while a pair is closed (StrikeHistory messages, the strike chart);
//  - KernelImpulses: per-kernel impulse sums by the other body's kind, kept across the core's
//    per-pair sums (KernelContactForces messages);
//  - SceneExtent: the box that holds the drum, its teeth, the concave and the kernels (camera
//    framing, where the chart and the text overlay go).
#pragma once

#include <array>
#include <map>
#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// One finished (or, when still open, running) tooth-kernel contact episode.
struct StrikeRecord {
  int tooth = 0;                           // tooth index [-]
  int kernel = 0;                          // kernel index [-]
  double sample_interval_s = 0;            // mean spacing of the samples (the integrator's
                                           // accepted steps: uneven) [s]
  double core_peak_normal_force_N = 0;     // the core's peak of the episode (its impact event:
                                           // located between samples too), 0 if none [N]
  double normal_impulse_Ns = 0;            // normal impulse of the episode [N s]
  double tangential_impulse_Ns = 0;        // tangential impulse of the episode [N s]
  bool truncated = false;                  // the sample limit cut the history short
  std::vector<double> t_s;                 // sample times [s]
  std::vector<double> normal_force_N;      // normal force on the kernel [N]
  std::vector<double> tangential_force_N;  // tangential force along t = J n [N]
  std::vector<double> gap_m;               // signed gap [m]
  double peakNormalForce() const;          // the core's peak, else the largest sample [N]
  double peakTime() const;                 // its sample time [s] (-1 if none)
};

class StrikeRecorder {
 public:
  // Longest history kept per episode [samples] (10 ms at 0.2 us).
  static constexpr size_t kMaxSamples = 50000;

  explicit StrikeRecorder(double sample_interval_s) : sample_interval_s_(sample_interval_s) {}
  // Records the tooth-kernel contacts of data at data.t_s; an episode whose pair is no longer
  // closed is finished (with the core's peak from its impact event in data.events, if there)
  // and moved to finished().
  void sample(const Data& data);
  // Forgets the open episodes (a reset moved the bodies).
  void clear() {
    open_.clear();
    apart_sums_Ns_.clear();
  }
  std::vector<StrikeRecord>& finished() { return finished_; }
  // Whether a tooth-kernel pair is closed, or closes within horizon_s at its normal velocity.
  static bool strikeNear(const Data& data, double horizon_s);

 private:
  struct Open {
    StrikeRecord record;
    Vec2 sums_at_start_Ns = Vec2::Zero();  // the core's impulse sums when it opened [N s]
  };
  double sample_interval_s_;
  std::map<std::pair<int, int>, Open> open_;           // by (tooth, kernel)
  std::map<std::pair<int, int>, Vec2> apart_sums_Ns_;  // sums when last seen apart [N s]
  std::vector<StrikeRecord> finished_;
};

// Kinds of the other body of a kernel contact: tooth, obstacle, kernel.
enum BodyKind : int { kByTooth = 0, kByObstacle = 1, kByKernel = 2 };

// Forces and impulse sums on one kernel, by the other body's kind.
struct KernelForces {
  std::array<double, 3> normal_force_N{};         // [N]
  std::array<double, 3> tangential_force_N{};     // [N]
  std::array<double, 3> normal_impulse_Ns{};      // since the last reset [N s]
  std::array<double, 3> tangential_impulse_Ns{};  // [N s]
};

class KernelImpulses {
 public:
  // Adds the impulse each pair of data.contacts gained since the previous call.
  void update(const Model& model, const Data& data);
  void clear();
  // Forces now (from data.contacts) and the impulse sums, per kernel.
  std::vector<KernelForces> forces(const Model& model, const Data& data) const;

 private:
  std::map<PairId, Vec2> last_sums_Ns_;  // the core's sums at the previous update [N s]
  std::vector<KernelForces> sums_;       // impulse sums per kernel
};

// Lower bound on the time until some tooth reaches some kernel [s]: the gap between the kernel's
// bounding circle and the undeformed tooth's capsule over the tooth tip's speed; 0 while a
// tooth-kernel pair is closed. Cheap (no ellipse queries), for pacing the view only.
double timeToStrike(const Model& model, const Data& data);

// The load torque of the teeth's contact forces about the drum axis (the origin), resisting the
// rotation when > 0: sum over the closed tooth-kernel contacts of (p x f) . z, p the contact
// point and f the force on the kernel (normal and tangential), world [N m]. Times the drum
// speed it is the power the drive gives the kernels through the teeth [W].
double contactLoadTorque(const std::vector<ContactInfo>& contacts);

// Where the view that follows the contact looks: the point of a closed tooth-kernel contact, else
// the centre of the kernel a tooth reaches first (by timeToStrike's estimate), world [m].
Vec2 strikeFocus(const Model& model, const Data& data);

// Axis-aligned box in world [m].
struct SceneExtent {
  Vec2 min_m = Vec2::Zero();
  Vec2 max_m = Vec2::Zero();
  Vec2 center() const { return 0.5 * (min_m + max_m); }
  Vec2 size() const { return max_m - min_m; }
};

// Where the strike chart goes: a box right of the scene, half the scene's height square.
SceneExtent chartBox(const SceneExtent& scene);
// The scene and the chart together: what the camera frames.
SceneExtent viewBox(const SceneExtent& scene);

// The drum with its teeth at full reach (whole circle), circle and segment obstacles, the
// points of planes nearest the drum, and the kernels' initial positions (not a feed's pool
// slots, parked far away: the feed's inlet and grate instead), plus a margin.
SceneExtent sceneExtent(const Model& model, const FeedSpec* feed = nullptr);

}  // namespace threshing_sim
