// threshing_sim core, private: the short vector of the contact Jacobians and the mode values.
#pragma once

#include <Eigen/Core>

#include "threshing_sim/core/constants.h"

namespace threshing_sim {
namespace internal {

// A short vector that never touches the heap (a tooth has at most kMaxModes = 64 modes,
// a kernel 3 dofs).
using SmallVec = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxModes, 1>;

}  // namespace internal
}  // namespace threshing_sim
