// threshing_sim core, private: the feed's slot operations (src/core/feed/pool.cc), used by
// src/core/feed/feed.cc.
#pragma once

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Kernel i back to its parking place (its compiled initial position), at rest, inactive, its
// pedicel released.
void parkSlot(const Model& m, int i, Data* d);
// Places kernel k's mass, detachment force and anchor into slot i of the model and starts it
// at centre c_W, angle psi_rad, velocity v_W (no spin), attached and active, with no history.
void placeKernel(const KernelModel& k, const Vec2& c_W, double psi_rad, const Vec2& v_W, int i,
                 Model* m, Data* d);

}  // namespace internal
}  // namespace threshing_sim
