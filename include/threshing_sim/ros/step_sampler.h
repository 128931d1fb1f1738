// threshing_sim ROS layer: advances the core to a physics step boundary and, near a strike,
// samples the state after every step the integrator takes, without cutting its steps.
//
// Every advance is advancePast(): a boundary is passed at the first step end at or past it, and
// only the run's end (~end_time; +infinity for an open run) cuts a step short. The node thus
// takes the steps `simulate` takes over the same duration (which cuts no step at its sample and
// chunk ends either), whatever its physics step, sampling or commands' boundaries: its impacts
// and peak forces are `simulate`'s (issue 24). A boundary's state is that of the step end at or
// past it (by less than one step); strike frames inside a step are interpolated (StrikeFrames).
// Near a strike (event-driven, both schemes) the sample function sees the state after every
// step. Island scheme: after every accepted step of every island (the core's StepObserver; a
// window can span a whole strike: the default strike's 33 us fall inside one 92 us window),
// then at the window's end with the lone kernels brought to it. Between sampled windows the
// islands' steps are watched too (a pair enters the contacts only with its island, and a
// strike can begin and end inside one advance): those near a strike are sampled. The islands of a
// window are integrated one after the other: their steps are recorded and, after the advance,
// sampled in time order. At an island's step the state holds that island's bodies at the
// step's end and the other bodies as of the last step replayed before (or as they were at the
// advance's first island step); the contacts are the island's then and the other islands' as
// last replayed; the events are the island's since the window began. Time stepping samples at
// its boundaries.
#pragma once

#include <functional>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/core/step_observer.h"

namespace threshing_sim {

class StepSampler {
 public:
  // Steps sampled one by one per advance() call at most; past that the call finishes the
  // interval in one advancePastLazy() call, whose work budget ends a run that cannot progress [-].
  static constexpr long kMaxSampledSteps = 20000;

  // enabled: sample accepted steps near strikes (event-driven only, see samplesSteps);
  // horizon_s: a tooth-kernel pair closing within this is near [s].
  StepSampler(const Model& model, bool enabled, double horizon_s);

  // Whether this model's integrator is sampled step by step (event-driven, either scheme).
  static bool samplesSteps(const Model& model);
  bool enabled() const { return enabled_; }

  // Advances data past t_end_s (to the first step end at or past it; t_stop_s, the run's end,
  // exactly), calling sample(data) after every step near a strike and once at the end. Returns
  // the worst status (kFailed: data holds the last good state, as after advanceTo()).
  StepStatus advance(const Model& model, Data* data, double t_end_s, double t_stop_s,
                     const std::function<void(const Data&)>& sample);

  // Steps sampled so far (island scheme: islands' steps, or the window if it had none) [-].
  long sampledSteps() const { return sampled_steps_; }
  // advance() calls that reached kMaxSampledSteps and finished in one call [-].
  long handovers() const { return handovers_; }

 private:
  // The state the sample function sees at an island's step (island scheme).
  class IslandView : public StepObserver {
   public:
    // Starts from data's state (read at the first island step), sampling with sample: every island
    // step (horizon_s < 0), or those with a tooth-kernel pair closed or closing within horizon_s
    // [s] and the first after.
    void begin(const Data& data, const std::function<void(const Data&)>* sample, double horizon_s);
    // Records an island's step (the advance's first also copies data's state).
    void islandStep(const Model& model, const IslandStep& step) override;
    // After the advance: samples the recorded steps in time order (islands of a window are
    // reported one after the other); the view then holds each island's bodies as of the step
    // replayed last and the other bodies as last replayed or as they were.
    void finish();
    long steps() const { return steps_; }      // island steps seen since begin() [-]
    long sampled() const { return sampled_; }  // of them sampled [-]

   private:
    // One recorded island step; its ranges of the shared arrays end where the next entry's begin.
    struct Entry {
      double t_s = 0, theta_rad = 0, omega_radps = 0;  // step end [s], drum [rad], [rad/s]
      size_t kernels_begin = 0, dofs_begin = 0, contacts_begin = 0, events_begin = 0;
    };
    struct Dof {
      int index = 0;        // in the full model's z and u [-]
      double z = 0, u = 0;  // position and velocity at the step's end [m, rad or modal]
    };
    void copySource();      // the view from the advance's data, as it is now
    void replay(size_t k);  // applies entry k to the view and samples it if due

    const Data* source_ = nullptr;  // the data being advanced (begin())
    Data view_;
    const std::function<void(const Data&)>* sample_ = nullptr;
    double horizon_s_ = -1;  // < 0: sample every step, else near strikes only [s]
    long steps_ = 0;
    long sampled_ = 0;
    bool was_near_ = false;              // the last step seen was near a strike
    std::vector<Entry> entries_;         // recorded steps, in report order
    std::vector<int> kernels_;           // their islands' kernels (global, ascending each)
    std::vector<Dof> dofs_;              // their islands' bodies' state
    std::vector<ContactInfo> contacts_;  // their islands' contacts (global numbers)
    std::vector<ContactEvent> events_;   // their islands' window events (global numbers)
    std::vector<size_t> order_;          // replay order (by time, ties in report order)
    VecX scratch_z_, scratch_u_;         // full-layout scratch for IslandStep::writeState
  };

  IslandView island_view_;
  bool enabled_ = false;
  double horizon_s_ = 0;
  long sampled_steps_ = 0;
  long handovers_ = 0;
};

}  // namespace threshing_sim
