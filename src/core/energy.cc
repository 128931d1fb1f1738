// Energy and angular momentum of the reduced model (docs/model.md §3-4).
//
// With mass-normalised modes the teeth's kinetic energy in the inertial frame is
//   T = 1/2 Omega^2 [I0 + q^T (I - K_G) q] + Omega p^T qdot + 1/2 qdot^T qdot,
// their elastic energy 1/2 q^T Lambda q, and their angular momentum about the drum axis
//   H = dT/dOmega = Omega [I0 + q^T (I - K_G) q] + p^T qdot.
#include "internal.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace internal {
namespace {

// q^T K q with the product in fixed-capacity storage (no heap temporary).
double quadraticForm(const MatX& K, const Eigen::Ref<const VecX>& q) {
  SmallVec Kq(q.size());
  Kq.noalias() = K * q;
  return q.dot(Kq);
}

// A large-deflection rod's inertial-frame kinetic plus elastic energy [J] (energy true) or
// its angular momentum about the drum axis [kg m^2/s] (energy false). The configuration is
// computed here (energy and momentum are evaluated at a few states per step only).
double rodEnergyOrMomentum(const ToothModel& tm, const Eigen::Ref<const VecX>& z,
                           const Eigen::Ref<const VecX>& u, double omega, bool energy) {
  LdConfig cfg;
  const double* q = z.data() + tm.dof_offset;
  ldConfigure(tm, q, &cfg);
  double kinetic = 0.0, momentum = 0.0;
  ldDynamics(tm, cfg, q, u.data() + tm.dof_offset, omega, 0.0, nullptr, nullptr, &kinetic,
             &momentum);
  return energy ? kinetic + ldElasticEnergy(tm, q) : momentum;
}

}  // namespace

double energyOf(const Model& m, const Data& d, const VecX& z, const VecX& u, double omega) {
  double e = 0.0;
  // Teeth: kinetic (inertial frame) plus bending energy.
  for (const ToothModel& tm : m.teeth) {
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      e += rodEnergyOrMomentum(tm, z, u, omega, true);
      continue;
    }
    double inertia = tm.I0_kgm2;
    if (tm.n_modes > 0) {
      const auto q = z.segment(tm.dof_offset, tm.n_modes);
      const auto qd = u.segment(tm.dof_offset, tm.n_modes);
      inertia += q.squaredNorm() - quadraticForm(tm.K_G, q);
      e += omega * tm.p_inertia.dot(qd) + 0.5 * qd.squaredNorm() +
           0.5 * (tm.omega0_sq.array() * q.array().square()).sum();
    }
    e += 0.5 * omega * omega * inertia;
  }
  // Kernels: translation, rotation, gravity; stretched pedicels.
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    const KernelModel& k = m.kernels[i];
    if (!d.kernel_active[i]) continue;  // a parked pool slot (core/feed.h)
    const auto c = z.segment<2>(k.dof_offset);
    const auto v = u.segment<2>(k.dof_offset);
    const double w = u[k.dof_offset + 2];
    e += 0.5 * k.mass_kg * v.squaredNorm() + 0.5 * k.inertia_kgm2 * w * w -
         k.mass_kg * m.gravity_mps2.dot(c);
    if (k.pedicel.present && d.kernel_attached[i]) {
      Vec2 p_WP;
      pedicelForce(m, z, u, static_cast<int>(i), d.t_s, &p_WP);
      const double stretch =
          (p_WP - pedicelAnchor(k.pedicel, d.t_s)).norm() - k.pedicel.rest_length_m;
      e += 0.5 * k.pedicel.stiffness_Npm * stretch * stretch;
    }
  }
  return e;
}

namespace {
// h plus one tooth's angular momentum, summed in the order of the per-model total.
double addToothMomentum(double h, const ToothModel& tm, const Eigen::Ref<const VecX>& q,
                        const Eigen::Ref<const VecX>& qd, double omega) {
  double inertia = tm.I0_kgm2;
  if (tm.n_modes > 0) {
    inertia += q.squaredNorm() - quadraticForm(tm.K_G, q);
    h += tm.p_inertia.dot(qd);
  }
  return h + omega * inertia;
}
}  // namespace

double toothAngularMomentum(const ToothModel& tm, const Eigen::Ref<const VecX>& q,
                            const Eigen::Ref<const VecX>& qd, double omega) {
  return addToothMomentum(0.0, tm, q, qd, omega);
}

double angularMomentumOf(const Model& m, const VecX& z, const VecX& u, double omega) {
  double h = 0.0;
  for (const ToothModel& tm : m.teeth) {
    if (tm.beam_model == ToothBeamModel::kLargeDeflection) {
      h += rodEnergyOrMomentum(tm, z, u, omega, false);
      continue;
    }
    h = addToothMomentum(h, tm, z.segment(tm.dof_offset, tm.n_modes),
                         u.segment(tm.dof_offset, tm.n_modes), omega);
  }
  return h;
}

}  // namespace internal

double mechanicalEnergy(const Model& model, const Data& data) {
  return internal::energyOf(model, data, data.z, data.u, data.omega_radps);
}

double kernelKineticEnergy(const Model& model, const Data& data) {
  double e = 0.0;
  for (const KernelModel& k : model.kernels) {
    e += 0.5 * k.mass_kg * data.u.segment<2>(k.dof_offset).squaredNorm() +
         0.5 * k.inertia_kgm2 * data.u[k.dof_offset + 2] * data.u[k.dof_offset + 2];
  }
  return e;
}

double teethAngularMomentum(const Model& model, const Data& data) {
  return internal::angularMomentumOf(model, data.z, data.u, data.omega_radps);
}

}  // namespace threshing_sim
