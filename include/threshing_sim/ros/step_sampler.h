// threshing_sim ROS layer: advances the core to a physics step boundary and, near a strike,
// samples the state after every step the integrator accepts, without cutting its steps.
//
// The node used to advance a physics step near a strike in advanceTo() calls 0.2 us apart
// (~strike_sample_dt): every call ended an integrator step there, which changed the steps the
// event-driven integrator took, and with them its trajectory and its work budget (the stream
// scene failed at t = 7.558 ms, which `simulate` passes; issue 24). Here the integrator takes
// the steps it chooses (core step(): one accepted step or event), and the caller's sample
// function sees the state after each: the samples are the core's own evaluations.
//
// Near a strike the last accepted step may end past the boundary (by less than one accepted
// step, a few us at most); the next boundary then continues from there. Away from strikes, for
// time stepping and for the island scheme (whose step() is a scheduling window), the boundary is
// reached by one advanceToLazy() call, as with sampling off.
#pragma once

#include <functional>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {

class StepSampler {
 public:
  // Accepted steps sampled one by one per advance() call at most; past that the call finishes
  // the interval in advanceToLazy(), whose work budget ends a run that cannot progress [-].
  static constexpr long kMaxSampledSteps = 20000;
  // Accepted steps in a row that leave the time unchanged (events at one instant) before the
  // call hands over to advanceToLazy() [-].
  static constexpr int kMaxStalledSteps = 100;

  // enabled: sample accepted steps near strikes (event-driven global scheme only, see
  // samplesSteps); horizon_s: a tooth-kernel pair closing within this is near [s].
  StepSampler(const Model& model, bool enabled, double horizon_s);

  // Whether this model's integrator is sampled step by step (event-driven, global scheme).
  static bool samplesSteps(const Model& model);
  bool enabled() const { return enabled_; }

  // Advances data to t_end_s (or, near a strike, up to one accepted step past it), calling
  // sample(data) after every accepted step near a strike and once at the end. Returns the
  // worst status (kFailed: data holds the last good state, as after advanceTo()).
  StepStatus advance(const Model& model, Data* data, double t_end_s,
                     const std::function<void(const Data&)>& sample);

  long sampledSteps() const { return sampled_steps_; }  // accepted steps sampled so far [-]
  long fallbacks() const { return fallbacks_; }  // steps redone by advanceTo (failure, NaN) [-]

 private:
  bool enabled_ = false;
  double horizon_s_ = 0;
  long sampled_steps_ = 0;
  long fallbacks_ = 0;
  // The state before the running step, restored when step() fails or leaves non-finite values
  // (advanceTo() then redoes the interval with its own recovery).
  VecX guard_z_, guard_u_;
};

}  // namespace threshing_sim
