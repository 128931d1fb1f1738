// threshing_sim core: does a state put one body inside another?
//
// Used before a reset or a re-seed places bodies: the caller builds the candidate state in a
// scratch Data and asks whether any tooth (its deformed capsule), kernel or obstacle overlaps
// another. Eigen only, no allocation beyond the optional description.
#pragma once

#include <string>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// True when some pair of bodies in the state (data.theta_rad, data.z) overlaps by more than
// tolerance_m: tooth-kernel (the tooth's capsule along its deformed centreline), kernel-kernel
// and kernel-obstacle. Teeth and obstacles are never checked against each other (the drum is
// built that way). When what is given, it receives e.g. "tooth 0 and kernel 2 overlap by
// 1.3e-03 m" for the first overlapping pair found.
bool bodiesOverlap(const Model& model, const Data& data, std::string* what = nullptr,
                   double tolerance_m = 0.0);

}  // namespace threshing_sim
