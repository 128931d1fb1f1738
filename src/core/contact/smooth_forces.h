// threshing_sim core, private: the smooth generalised forces, everything but the contacts
// (src/core/contact/smooth_forces.cc).
#pragma once

#include "../drive.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

// Smooth generalised forces without contacts: tooth damping, stiffness and drum-acceleration
// load; kernel gravity and pedicels.
void smoothForces(const Model& m, const Data& d, const VecX& z, const VecX& u, const Drive& drive,
                  VecX* f);
// Pedicel spring-damper force on kernel i (world, at its attachment point) [N] and that point,
// at time t_s [s] (a moving anchor's place and velocity, PedicelModel::v_WA_W_mps).
Vec2 pedicelForce(const Model& m, const VecX& z, const VecX& u, int i, double t_s, Vec2* p_WP);
// Kernel i's pedicel anchor at time t_s, world [m].
inline Vec2 pedicelAnchor(const PedicelModel& p, double t_s) {
  return p.v_WA_W_mps.isZero() ? p.p_WA_W : Vec2(p.p_WA_W + t_s * p.v_WA_W_mps);
}

}  // namespace internal
}  // namespace threshing_sim
