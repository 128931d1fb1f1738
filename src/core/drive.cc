// The drum drive (drive.h): the commanded target and the ramp law over a step.
#include "drive.h"

#include <cmath>
#include <limits>

#include "threshing_sim/core/simulator.h"

namespace threshing_sim {

void setDrumTarget(const Model& model, Data* data, double omega_target_radps) {
  (void)model;
  data->omega_target_radps = omega_target_radps;
}

namespace internal {

Drive driveAt(const Model& m, const Data& d, double dt_s) {
  Drive out;
  out.t_s = d.t_s + dt_s;
  const double gap = d.omega_target_radps - d.omega_radps;
  const double a = m.drum.max_acceleration_radps2;
  const double ramp = std::abs(gap) / a;  // time left on the ramp [s]
  const double s = gap > 0 ? 1.0 : (gap < 0 ? -1.0 : 0.0);
  if (dt_s < ramp) {
    // Still ramping at the acceleration limit.
    out.alpha_radps2 = s * a;
    out.omega_radps = d.omega_radps + s * a * dt_s;
    out.theta_rad = d.theta_rad + d.omega_radps * dt_s + 0.5 * s * a * dt_s * dt_s;
  } else {
    // Ramp finished (or none): cruise at the target for the rest of the interval.
    out.alpha_radps2 = 0.0;
    out.omega_radps = d.omega_target_radps;
    out.theta_rad = d.theta_rad + d.omega_radps * ramp + 0.5 * s * a * ramp * ramp +
                    d.omega_target_radps * (dt_s - ramp);
  }
  return out;
}

double timeToTarget(const Model& m, const Data& d) {
  const double gap = std::abs(d.omega_target_radps - d.omega_radps);
  return gap > 0 ? gap / m.drum.max_acceleration_radps2 : std::numeric_limits<double>::infinity();
}

}  // namespace internal
}  // namespace threshing_sim
