// threshing_sim ROS layer: validation of a dynamic_reconfigure request.
//
// dynamic_reconfigure clamps each value into its cfg range, but NaN passes the clamp (every
// comparison with it is false). sanitizeConfig() checks every double of the request against
// the cfg's own minimum and maximum (ThreshingSimConfig::__getMin__/__getMax__), NaN and inf
// included, and puts the last good value back in place of each bad one. The node then hands
// the repaired configuration back to the server (the callback's argument is what the server
// keeps), so that the server never holds a value the node refused.
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include "threshing_sim/ThreshingSimConfig.h"

namespace threshing_sim {

// Replaces every value of *config outside [min, max] of the cfg, or not finite, by the value in
// last_good; returns "name = value" for each replaced one (empty: the request was good).
inline std::vector<std::string> sanitizeConfig(ThreshingSimConfig* config,
                                               const ThreshingSimConfig& last_good) {
  struct Field {
    const char* name;
    double ThreshingSimConfig::*member;
  };
  static const Field kFields[] = {
      {"tooth_kernel_restitution", &ThreshingSimConfig::tooth_kernel_restitution},
      {"tooth_kernel_friction", &ThreshingSimConfig::tooth_kernel_friction},
      {"kernel_kernel_restitution", &ThreshingSimConfig::kernel_kernel_restitution},
      {"kernel_kernel_friction", &ThreshingSimConfig::kernel_kernel_friction},
      {"kernel_obstacle_restitution", &ThreshingSimConfig::kernel_obstacle_restitution},
      {"kernel_obstacle_friction", &ThreshingSimConfig::kernel_obstacle_friction},
      {"contact_state_rate", &ThreshingSimConfig::contact_state_rate},
      {"state_rate", &ThreshingSimConfig::state_rate},
      {"marker_rate", &ThreshingSimConfig::marker_rate},
  };
  const ThreshingSimConfig& lo = ThreshingSimConfig::__getMin__();
  const ThreshingSimConfig& hi = ThreshingSimConfig::__getMax__();
  std::vector<std::string> refused;
  for (const Field& f : kFields) {
    const double value = config->*f.member;
    if (std::isfinite(value) && value >= lo.*f.member && value <= hi.*f.member) continue;
    refused.push_back(std::string(f.name) + " = " + std::to_string(value));
    config->*f.member = last_good.*f.member;
  }
  return refused;
}

}  // namespace threshing_sim
