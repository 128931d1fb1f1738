// threshing_sim core: the stepping API (free functions over Model and Data, cf. mj_step).
#pragma once

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

enum class StepStatus { kOk = 0, kRecovered = 1, kFailed = 2 };

// Puts data in the scene's initial state (time 0) and clears statistics and events.
// The model must be compiled.
void resetData(const Model& model, Data* data);

// Restores the scene's initial bodies (kernels, teeth, pedicels, drum speed target) but keeps
// time running: t_s is left as it is and the drum keeps its angle. Used by the ROS reset service.
void resetBodiesKeepTime(const Model& model, Data* data);

// Sets the drum's target speed [rad/s]; it is applied from the next step boundary, reached
// through the drum's acceleration limit.
void setDrumTarget(const Model& model, Data* data, double omega_target_radps);

// Advances the simulation to time t_end_s exactly (event-driven: by as many adaptive steps and
// events as needed; time stepping: by whole steps of model.integrator.dt_s, the last one
// landing on or past t_end_s within dt/2). Returns kRecovered if a non-finite result was caught
// and the step redone with a safer setting, kFailed if that failed too (data then holds the last
// good state).
StepStatus advanceTo(const Model& model, Data* data, double t_end_s);

// The same, but under the island scheme (integrator.islands) lone kernels stay on their own
// clocks: their entries of data.z, data.u (and what is computed from them) are stale until
// syncBodies(). For callers that step often and read the whole state seldom (the node steps at
// 1e-5 s and publishes at 100 Hz): the cost of a call then follows the events, not the kernel
// count. Under the global scheme it is advanceTo.
StepStatus advanceToLazy(const Model& model, Data* data, double t_end_s);

// Advances the simulation until data.t_s reaches t_target_s, without cutting a step there: each
// step ends where the step-size law and the events put it (event-driven: the last one ends at or
// past t_target_s, by less than one step; the island scheme: a scheduling window), and only
// t_stop_s, the run's end (+infinity for an open run), cuts a step short (t_target_s is capped at
// t_stop_s). Two callers with the same t_stop_s and the same commands at the same step ends
// therefore take the same steps, whatever times they observe the state at; observation times
// inside a step are the caller's to interpolate. Time stepping: as advanceTo (whole steps of
// dt). Status, guard and work budget as advanceTo; t_stop_s NaN fails as kBadTarget.
StepStatus advancePast(const Model& model, Data* data, double t_target_s, double t_stop_s);

// The same with advanceToLazy's rule for lone kernels (island scheme: stale until syncBodies()).
StepStatus advancePastLazy(const Model& model, Data* data, double t_target_s, double t_stop_s);

// Brings every lone kernel to data's time (after advanceToLazy; advanceTo does it itself).
// Returns kFailed if a kernel's own integrator failed.
StepStatus syncBodies(const Model& model, Data* data);

// One integrator step (time stepping: dt; event-driven: one accepted step or event).
StepStatus step(const Model& model, Data* data);

// Mechanical energy: kinetic (teeth in the inertial frame, kernels) + elastic (tooth bending,
// pedicels) + gravitational (kernels) [J].
double mechanicalEnergy(const Model& model, const Data& data);

// Kinetic energy of the kernels only [J].
double kernelKineticEnergy(const Model& model, const Data& data);

// Angular momentum of all teeth about the drum axis [kg m^2/s].
double teethAngularMomentum(const Model& model, const Data& data);

// Deformed centreline point of tooth k at material coordinate x, in world [m].
Vec2 toothPointWorld(const Model& model, const Data& data, int tooth, double x_m);
// Transverse deflection w(x) and its foreshortening w_c(x) in the tooth frame [m].
double toothDeflection(const Model& model, const Data& data, int tooth, double x_m);
double toothForeshortening(const Model& model, const Data& data, int tooth, double x_m);

// Pose of kernel i.
inline Vec2 kernelPosition(const Model& m, const Data& d, int i) {
  return d.z.segment<2>(m.kernels[i].dof_offset);
}
inline double kernelAngle(const Model& m, const Data& d, int i) {
  return d.z[m.kernels[i].dof_offset + 2];
}

// Natural frequencies of tooth k at drum speed omega [Hz], ascending (empty for a rigid tooth).
VecX toothFrequenciesHz(const ToothModel& tooth, double omega_radps);

}  // namespace threshing_sim
