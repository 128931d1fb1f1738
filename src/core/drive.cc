// The drum drive (drive.h): the commanded target and the ramp law over a step.
#include "drive.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "internal.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {

void setDrumTarget(const Model& model, Data* data, double omega_target_radps) {
  // Within the drum's speed bound, which the residual flexibility is tabulated over.
  const double bound = model.drum.speed_bound_radps;
  data->omega_target_radps =
      bound > 0 ? std::clamp(omega_target_radps, -bound, bound) : omega_target_radps;
  // The free teeth's exact propagators at the target speed are built here, at the command, so
  // that reaching it costs the step no factorisation (they are kept per tooth, keyed on speed).
  if (!model.integrator.exact_free_teeth || !data->ws || !model.compiled) return;
  const int T = static_cast<int>(model.teeth.size());
  std::vector<internal::ToothPropagator>& prop = data->ws->ed.prop;
  if (prop.size() != static_cast<size_t>(T)) prop.resize(T);
  for (int k = 0; k < T; ++k) {
    if (model.teeth[k].n_modes > 0)
      internal::buildToothPropagator(model, k, data->omega_target_radps, &prop[k]);
  }
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
