// The demo loop (demo_loop.h).
#include "threshing_sim/ros/demo_loop.h"

#include <ros/console.h>

#include <cmath>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/core/state_overlap.h"

namespace threshing_sim {
namespace {

// Overlap warnings are printed at most this often [wall s].
constexpr double kWarnPeriod_s = 2.0;

}  // namespace

DemoLoop::DemoLoop(const Model& model, int loop_revolutions, const SteadyClock& clock)
    : revolutions_(loop_revolutions), clock_(clock) {
  resetData(model, &candidate_);
}

bool DemoLoop::due(const Data& data) {
  if (revolutions_ <= 0) return false;
  const double period_rad = 2 * kPi * revolutions_;
  const long index = static_cast<long>(std::floor((data.theta_rad - anchor_rad_) / period_rad));
  if (index == index_) return false;
  index_ = index;
  return true;
}

bool DemoLoop::reseedIfClear(const Model& model, Data* data) {
  // The candidate: the current drum angle and teeth, kernels back at their initial poses.
  Data& c = candidate_;
  c.theta_rad = data->theta_rad;
  c.z = data->z;
  for (const KernelModel& kernel : model.kernels) {
    c.z.segment<2>(kernel.dof_offset) = kernel.initial_position_m;
    c.z[kernel.dof_offset + 2] = kernel.initial_angle_rad;
  }
  std::string what;
  if (bodiesOverlap(model, c, &what)) {
    const double now_s = clock_.nowSeconds();
    if (now_s - last_warn_s_ >= kWarnPeriod_s) {
      last_warn_s_ = now_s;
      ROS_WARN(
          "demo loop re-seed at t = %.6f s skipped: the reset would place bodies "
          "overlapping (%s)",
          data->t_s, what.c_str());
    }
    return false;
  }
  // resetBodiesKeepTime restores every body and the drum's target: keep the teeth and the
  // commanded speed as they are, so that only the kernels start over.
  const double target_radps = data->omega_target_radps;
  const VecX z = data->z, u = data->u;
  resetBodiesKeepTime(model, data);
  for (const ToothModel& tooth : model.teeth) {
    data->z.segment(tooth.dof_offset, tooth.n_modes) = z.segment(tooth.dof_offset, tooth.n_modes);
    data->u.segment(tooth.dof_offset, tooth.n_modes) = u.segment(tooth.dof_offset, tooth.n_modes);
  }
  setDrumTarget(model, data, target_radps);
  data->stats.energy_initial_J = mechanicalEnergy(model, *data);
  ++loops_;
  return true;
}

}  // namespace threshing_sim
