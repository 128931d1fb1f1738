// threshing_sim ROS layer: states after accepted integrator steps and the cubic Hermite
// interpolant between two of them (positions z with their derivatives u = dz/dt; the drum's
// theta with omega). StrikeFrames draws a recording's strike frames with it (factor 0); a live
// node under the island scheme (factor > 0) keeps the states its last advance's sampler saw in a
// StepHistory and publishes each boundary that advance passed at the boundary's own time: one
// scheduling window (about 92 us) can hold a whole strike, and the window's end would otherwise
// be the state of every boundary inside it. The integrator's steps are never changed.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "threshing_sim/core/data.h"

namespace threshing_sim {

// The state after an accepted step (or at a step end that passed a boundary).
struct StepState {
  double t_s = 0;          // step end [s]
  double theta_rad = 0;    // drum angle [rad]
  double omega_radps = 0;  // drum speed [rad/s]
  VecX z, u;               // positions [m, rad or modal] and their derivatives [/s]
  std::vector<ContactInfo> contacts;
  bool closed = false;  // a tooth-kernel pair is closed
};

// An interpolated state (a strike's frame, or a live boundary inside a step).
struct FrameState {
  std::int64_t t_ns = 0;              // the frame's time [ns]
  double t_s = 0;                     // the same [s]
  double theta_rad = 0;               // [rad]
  double omega_radps = 0;             // [rad/s]
  VecX z, u;                          // as StepState
  std::vector<ContactInfo> contacts;  // those of the nearer accepted step, forces interpolated
};

// Copies data's step end into s (no allocation once s has data's sizes and contact capacity).
void copyStepState(const Data& data, StepState* s);

// The state at t_s in [a.t_s, b.t_s] (a.t_s < b.t_s, same layouts): cubic Hermite in z (with
// u = dz/dt) and theta (with omega), u and omega linear; the contacts of the nearer step, a pair
// closed at both ends with its point and forces interpolated. Leaves out->t_ns unchanged.
void interpolateStep(const StepState& a, const StepState& b, double t_s, FrameState* out);

// The states of one advance, in time order, in kCapacity preallocated slots: once every slot
// has seen the model's sizes and the largest contact list, adding a state allocates nothing.
// When the slots are full every other state is dropped (the first kept), so the history still
// spans the advance.
class StepHistory {
 public:
  static constexpr std::size_t kCapacity = 256;  // states kept at most [-]
  StepHistory() : states_(kCapacity) {}
  // The state the next advance starts from: the history restarts with it.
  void begin(const Data& data);
  // A state after an accepted step: kept if later than the last one (at the same time it
  // replaces it: the window's end, with lone kernels brought to it, after the island's step).
  void add(const Data& data);
  // The state at t_s into out if the history spans it: a kept state's time gives that state
  // exactly, a time between two gives their interpolant. False when t_s is outside.
  bool stateAt(double t_s, FrameState* out) const;
  void clear() { n_ = 0; }  // the bodies moved (reset): nothing to interpolate
  std::size_t size() const { return n_; }
  double lastTime() const { return n_ > 0 ? states_[n_ - 1].t_s : 0.0; }

 private:
  std::vector<StepState> states_;  // kCapacity slots, the first n_ in use
  std::size_t n_ = 0;              // states kept [-]
};

}  // namespace threshing_sim
