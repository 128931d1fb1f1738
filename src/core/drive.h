// threshing_sim core, private: the drum drive. The drum is rheonomic: its speed follows the
// commanded target at the drive's acceleration limit (a ramp, then cruise), so its state at any
// time within a step is known in closed form. The path of a drum speed command:
//   node: drum_speed_cmd -> RosInterface::onDrumSpeedCommand (validate, stage)
//   node: applyStaged at the next step boundary -> setDrumTarget (drive.cc: the target)
//   integrators: driveAt / timeToTarget (drive.cc: the ramp law over a step), used by
//   event_driven/ (planStep in step_size.cc, acceptStep in accept.cc), time_stepping/
//   (beginStep in step.cc) and async/.
#pragma once

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Rheonomic drum state at one instant.
struct Drive {
  double t_s = 0;           // time [s]
  double theta_rad = 0;     // drum angle [rad]
  double omega_radps = 0;   // drum speed [rad/s]
  double alpha_radps2 = 0;  // drum acceleration [rad/s^2]
};

// Drum state after dt_s [s] from d with the current target (piecewise-constant acceleration:
// at most one switch, when the target speed is reached).
Drive driveAt(const Model& m, const Data& d, double dt_s);

// Time until the drum reaches its target speed from d (inf if it is there) [s].
double timeToTarget(const Model& m, const Data& d);

}  // namespace internal
}  // namespace threshing_sim
