// threshing_sim core: the smooth generalised forces (smooth_forces.h): the teeth's elastic,
// damping and drum-acceleration loads, the kernels' gravity and pedicels.
#include "smooth_forces.h"

#include "../internal.h"
#include "planar.h"

namespace threshing_sim {
namespace internal {

Vec2 pedicelForce(const Model& m, const VecX& z, const VecX& u, int i, double t_s, Vec2* p_WP) {
  const KernelModel& k = m.kernels[i];
  const Vec2 c = z.segment<2>(k.dof_offset);
  const Vec2 r = rotate(z[k.dof_offset + 2], k.pedicel.p_KP_K);
  *p_WP = c + r;
  // The attachment point's velocity relative to the anchor (a moving anchor: v_A).
  const Vec2 v = u.segment<2>(k.dof_offset) + u[k.dof_offset + 2] * perp(r) - k.pedicel.v_WA_W_mps;
  const Vec2 d = *p_WP - pedicelAnchor(k.pedicel, t_s);
  const double len = d.norm();
  if (len <= 0.0) return Vec2::Zero();
  const Vec2 dir = d / len;
  // Linear spring on the stem's elongation, viscous damper on its rate.
  const double tension = k.pedicel.stiffness_Npm * (len - k.pedicel.rest_length_m) +
                         k.pedicel.damping_Nspm * dir.dot(v);
  return -tension * dir;
}

void smoothForces(const Model& m, const Data& d, const VecX& z, const VecX& u, const Drive& drive,
                  VecX* f) {
  f->setZero(m.n_dof);
  // Teeth: -D qdot - [Lambda + Omega^2 (K_G - I)] q - dOmega/dt p.
  const double w2 = drive.omega_radps * drive.omega_radps;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    const ToothModel& tm = m.teeth[k];
    const int n = tm.n_modes;
    if (n == 0) continue;
    const auto q = z.segment(tm.dof_offset, n);
    const auto qd = u.segment(tm.dof_offset, n);
    auto out = f->segment(tm.dof_offset, n);
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      // The rod's elastic, damping and inertial (centrifugal, Coriolis, Euler) forces.
      LdVec fr;
      ldDynamics(tm, ldConfigOf(m, static_cast<int>(k), z, d.ws.get()), q.data(), qd.data(),
                 drive.omega_radps, drive.alpha_radps2, nullptr, &fr, nullptr, nullptr);
      out = fr;
      continue;
    }
    // -Omega^2 K_G q and the diagonal terms by plain loops (dynamic-size Eigen expressions
    // cost more than the arithmetic at a few modes); the operations of the array expression
    // they replace, in its order.
    for (int i = 0; i < n; ++i) {
      double kq = 0.0;
      for (int j = 0; j < n; ++j) kq += tm.K_G(i, j) * q[j];
      out[i] = -w2 * kq + ((-(tm.omega0_sq[i] - w2) * q[i] - tm.damping_coeff[i] * qd[i]) -
                           drive.alpha_radps2 * tm.p_inertia[i]);
    }
  }
  // Kernels: gravity, and the pedicel while it holds.
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    // A retired pool slot (core/feed.h) is parked: no force moves it.
    if (!d.kernel_active[i]) continue;
    f->segment<2>(k.dof_offset) += k.mass_kg * m.gravity_mps2;
    if (k.pedicel.present && d.kernel_attached[i]) {
      Vec2 p_WP;
      const Vec2 F = pedicelForce(m, z, u, static_cast<int>(i), drive.t_s, &p_WP);
      f->segment<2>(k.dof_offset) += F;
      (*f)[k.dof_offset + 2] += cross(p_WP - z.segment<2>(k.dof_offset), F);
    }
  }
}

}  // namespace internal
}  // namespace threshing_sim
