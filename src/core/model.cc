// Model compilation: validation, generalised-coordinate layout, derived constants.
#include "threshing_sim/core/model.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/large_deflection.h"
#include "threshing_sim/core/tooth_cache.h"

namespace threshing_sim {
namespace {

[[noreturn]] void fail(const std::string& field, const std::string& rule, double value) {
  std::ostringstream msg;
  msg << field << ": " << rule << " (got " << value << ")";
  throw std::invalid_argument(msg.str());
}

void requirePositive(const std::string& field, double value) {
  if (!(value > 0.0) || !std::isfinite(value)) fail(field, "must be a finite number > 0", value);
}

void requireFinite(const std::string& field, double value) {
  if (!std::isfinite(value)) fail(field, "must be finite", value);
}

// g(c) = G(c) / c^2 with G(c) = ln(1 + c) - ln(1 - c e) - c (1 + e): the phase-plane relation of
// the dimensionless Hunt-Crossley impact (see huntCrossleyFactor) for the damping factor c.
// Its power series sum_{k>=2} c^(k-2) (e^k - (-1)^k) / k where c is small (no cancellation).
double huntCrossleyRelation(double c, double e) {
  if (c < 0.125) {
    double sum = 0.0, c_pow = 1.0, e_pow = e, sign = -1.0;  // c^(k-2), e^(k-1), (-1)^(k-1)
    for (int k = 2; k <= 40; ++k) {
      e_pow *= e;
      sign = -sign;
      sum += c_pow * (e_pow - sign) / k;
      c_pow *= c;
    }
    return sum;
  }
  return (std::log1p(c) - std::log1p(-c * e) - c * (1.0 + e)) / (c * c);
}

}  // namespace

// Dimensionless impact x'' = -x^{3/2} (1 + c x'), x(0) = 0, x'(0) = 1: v dv/dx = -x^{3/2} (1 + c v)
// integrates to v/c - ln(1 + c v)/c^2 = const, so the exit speed v_out = -e satisfies
// ln(1 + c) - ln(1 - c e) = c (1 + e) (docs/model.md §4). g (above) rises through its only root
// in (0, 1/e): safeguarded Newton on it, bracketed by bisection.
double huntCrossleyFactor(double restitution) {
  if (restitution >= 1.0) return 0.0;
  const double e = std::max(restitution, kHuntCrossleyMinRestitution);
  double lo = 0.0, hi = 1.0 / e;  // g(lo) < 0 < g(hi)
  // Start: the small-c expansion g ~ -(1 - e^2)/2 + c (1 + e^3)/3, within the bracket.
  double c = std::min(1.5 * (1.0 - e * e) / (1.0 + e * e * e), 0.5 / e);
  for (int it = 0; it < 200; ++it) {
    const double g = huntCrossleyRelation(c, e);
    if (!(g < 0.0 || g > 0.0)) return c;
    (g < 0.0 ? lo : hi) = c;
    // g' = (B - 2 g) / c with B = G'(c) / c = e^2 / (1 - c e) - 1 / (1 + c).
    const double B = e * e / (1.0 - c * e) - 1.0 / (1.0 + c);
    double next = c - g * c / (B - 2.0 * g);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (std::abs(next - c) <= 4 * std::numeric_limits<double>::epsilon() * c) return next;
    c = next;
  }
  return c;
}

namespace {

// Shortest Hertz contact time [s] of a kernel of the model struck by the flank of tooth t at
// its tip speed |Omega_0| (R + L) (plus the kernel's own initial speed with
// add_kernel_speeds, an upper bound of the approach speed; at least 1 m/s): F = K delta^{3/2}
// with K = 4/3 E* sqrt(R*), the kernel's sharpest in-plane curvature b^2 / a against the flat
// flank, b against the round section across; t_c = 2.9432 delta_max / v with
// delta_max = (5 m v^2 / (4 K))^{2/5}. Infinite without kernels or with non-physical kernel
// values (validated later).
double shortestContactTime(const Model& m, const ToothModel& t, bool add_kernel_speeds = false) {
  const double v_tip = std::abs(m.drum.initial_speed_radps) * (m.drum.radius_m + t.length_m);
  const double r_t = 0.5 * t.diameter_m;
  double t_c = std::numeric_limits<double>::infinity();
  for (const KernelModel& k : m.kernels) {
    const double v =
        std::max(v_tip + (add_kernel_speeds ? k.initial_velocity_mps.norm() : 0.0), 1.0);
    const double e_star = 1.0 / ((1 - t.poisson_ratio * t.poisson_ratio) / t.youngs_modulus_Pa +
                                 (1 - k.poisson_ratio * k.poisson_ratio) / k.youngs_modulus_Pa);
    const double r_in = k.semi_axis_b_m * k.semi_axis_b_m / k.semi_axis_a_m;
    const double r_out = r_t * k.semi_axis_b_m / (r_t + k.semi_axis_b_m);
    const double K = 4.0 / 3.0 * e_star * std::sqrt(std::sqrt(r_in * r_out));
    const double delta_max = std::pow(5.0 * k.mass_kg * v * v / (4.0 * K), 0.4);
    const double tk = 2.9432 * delta_max / v;
    if (std::isfinite(tk) && tk > 0.0) t_c = std::min(t_c, tk);
  }
  return t_c;
}

// Circular frequency at rest per (beta L)^2 of the clamped-free tooth t, sqrt(EI / rho A) / L^2
// [rad/s].
double cantileverFrequencyScale(const ToothModel& t) {
  const double area = kPi * t.diameter_m * t.diameter_m / 4;
  const double EI = t.youngs_modulus_Pa * area * t.diameter_m * t.diameter_m / 16;
  return std::sqrt(EI / (t.density_kgpm3 * area)) / (t.length_m * t.length_m);
}

// The automatic mode count (teeth.*.modes: auto). A retained mode of circular frequency omega
// follows a contact pulse of duration t_c dynamically; a truncated one only through the static
// correction, which is exact for a mode much faster than the pulse and off by about
// (omega_c / omega)^2 for one that is not, omega_c = pi / t_c. Modes are retained until the
// first truncated one (at rest) has (omega_c / omega_{n+1})^2 <= eps, i.e. omega_{n+1} >=
// omega_c / sqrt(eps), with eps = max(tolerance, 2.5e-4): the truncation error is kept at the
// integrator's tolerance, but no finer than 2.5e-4 (omega_{n+1} >= 64 omega_c), which is what
// the 1 % convergence of the knead forces needs (docs/convergence.md). At least 2 modes, at most
// kMaxModes; 4 without kernels.
int chooseModeCount(const Model& m, const ToothModel& t, double t_c) {
  if (!std::isfinite(t_c)) return 4;
  const double eps = std::max(m.integrator.tolerance, 2.5e-4);
  const double omega_needed = kPi / t_c / std::sqrt(eps);
  const double scale = cantileverFrequencyScale(t);
  int n = 2;
  while (n < kMaxModes && std::pow(cantileverBetaL(n), 2) * scale < omega_needed) ++n;
  return n;
}

// The residual's cut-off (docs/model.md §9b, "When the truncated modes are not fast"). The
// static correction treats a truncated mode as a massless spring: right for a mode much faster
// than the contact pulse, which follows the force; a mode slower than the pulse's own
// frequency omega_c = pi / t_c (half its period longer than the contact) barely moves during
// it, and as a spring it would deflect by up to (omega_c / omega)^2 too much, and tilt the
// normal by as much. Such modes are left out of the correction (the tooth is stiff in them,
// as without it). Returns the number of modes the residual subtracts: n_modes, plus the
// truncated modes below omega_c (at rest, the lowest, so the cut is on the safe side), at
// most kMaxModes; t_c from the tip and kernel speeds added (the shortest contact).
int residualModeCount(const Model& m, const ToothModel& t) {
  const double t_c = shortestContactTime(m, t, true);
  if (!t.static_correction || t.n_modes <= 0 || !std::isfinite(t_c)) return t.n_modes;
  const double omega_c = kPi / t_c, scale = cantileverFrequencyScale(t);
  int n = t.n_modes;
  while (n < kMaxModes && std::pow(cantileverBetaL(n), 2) * scale < omega_c) ++n;
  return n;
}
// The drum and the global values: checked.
void checkGlobals(const Model& m) {
  requirePositive("drum.radius", m.drum.radius_m);
  requireFinite("drum.speed", m.drum.initial_speed_radps);
  requireFinite("drum.angle", m.drum.initial_angle_rad);
  requirePositive("drum.max_acceleration", m.drum.max_acceleration_radps2);
  requirePositive("drum.max_speed", m.drum.max_speed_radps);
  requireFinite("gravity.x", m.gravity_mps2.x());
  requireFinite("gravity.y", m.gravity_mps2.y());
  requirePositive("duration", m.duration_s);
  if (!(m.broadphase_margin_m >= 0.0))
    fail("broadphase_margin", "must be >= 0", m.broadphase_margin_m);
  requirePositive("integrator.tolerance", m.integrator.tolerance);
  requirePositive("integrator.dt", m.integrator.dt_s);
  requirePositive("integrator.max_step", m.integrator.max_step_s);
  requirePositive("integrator.zeno_velocity", m.integrator.zeno_velocity_mps);
  if (!(m.integrator.theta >= 0.5 && m.integrator.theta <= 1.0))
    fail("integrator.theta", "must be in [0.5, 1]", m.integrator.theta);
  // Fewer than 4 steps per Hertz contact time is beyond the explicit kick's stability.
  if (m.integrator.contact_steps != 0 &&
      !(m.integrator.contact_steps >= 4 && m.integrator.contact_steps <= 1000))
    fail("integrator.contact_steps", "must be 0 (off) or in [4, 1000]",
         m.integrator.contact_steps);
}

// A modal tooth's compiled data depend on its mount angle only through its root and axes
// (e1_D, e2_D, p_DR_D): tooth k takes the data of an earlier modal tooth equal in every other
// scene value (the teeth of a drum are usually alike), with its own angle. Returns whether it
// found one.
bool copyTwin(Model* model, size_t k) {
  ToothModel& t = model->teeth[k];
  if (t.beam_model != ToothBeamModel::kModal || !std::isfinite(t.mount_angle_rad)) return false;
  for (size_t j = 0; j < k; ++j) {
    const ToothModel& o = model->teeth[j];
    if (o.beam_model != t.beam_model || o.length_m != t.length_m || o.diameter_m != t.diameter_m ||
        o.youngs_modulus_Pa != t.youngs_modulus_Pa || o.poisson_ratio != t.poisson_ratio ||
        o.density_kgpm3 != t.density_kgpm3 || o.n_modes != t.n_modes ||
        o.damping_ratio != t.damping_ratio || o.n_stations != t.n_stations ||
        o.static_correction != t.static_correction || o.section_rotation != t.section_rotation ||
        o.modes_auto != t.modes_auto || o.quasi_static_from_mode != t.quasi_static_from_mode ||
        o.quasi_static_speedup != t.quasi_static_speedup)
      continue;
    const double angle_rad = t.mount_angle_rad;
    t = o;
    t.mount_angle_rad = angle_rad;
    t.e1_D = Vec2(std::cos(angle_rad), std::sin(angle_rad));
    t.e2_D = Vec2(-t.e1_D.y(), t.e1_D.x());
    t.p_DR_D = model->drum.radius_m * t.e1_D;
    return true;
  }
  return false;
}

// Tooth k: checked, its mode count chosen (automatic modes), its modal data and residual
// flexibility compiled (compileTooth through *cache when given). Moduli above 1e13 Pa (50x
// diamond) only make the modes uselessly stiff: use modes: 0.
void compileToothAt(Model* model, size_t k, ToothCache* cache) {
  Model& m = *model;
  if (m.teeth[k].n_stations > 65)
    fail("teeth." + std::to_string(k) + ".stations", "must be <= 65", m.teeth[k].n_stations);
  if (m.teeth[k].youngs_modulus_Pa > 1e13)
    fail("teeth." + std::to_string(k) + ".youngs_modulus",
         "must be <= 1e13 Pa (use modes: 0 for a rigid tooth)", m.teeth[k].youngs_modulus_Pa);
  ToothModel& t = m.teeth[k];
  const bool rod = t.beam_model == ToothBeamModel::kLargeDeflection;
  if (t.n_modes == kAutoModes || t.modes_auto) {
    t.modes_auto = true;
    t.contact_time_s = shortestContactTime(m, t);
    // A large-deflection rod's `modes` are the Ritz shape functions of its section angle; its
    // low frequencies are the cantilever's, so it takes the modal count within bounds
    // (large_deflection.h, docs/large_deflection.md).
    const int n = chooseModeCount(m, t, t.contact_time_s);
    t.n_modes = rod ? std::clamp(n, kLdAutoMinShapes, kLdAutoMaxShapes) : n;
  }
  // The rod truncates no modes: there is no residual flexibility to correct.
  if (rod) t.static_correction = false;
  t.residual_modes = residualModeCount(m, t);
  t.residual_contact_time_s = t.residual_modes > 0 ? shortestContactTime(m, t, true) : 0.0;
  try {
    if (!copyTwin(&m, k)) {
      if (cache != nullptr)
        cache->compile(m.drum.radius_m, &m.teeth[k]);
      else
        compileTooth(m.drum.radius_m, &m.teeth[k]);
      compileResidual(m.drum.radius_m, m.drum.initial_speed_radps, m.drum.speed_bound_radps,
                      &m.teeth[k]);
    }
  } catch (const std::invalid_argument& e) {
    // beam.cc names fields "tooth.<field>"; report them as "teeth.<k>.<field>".
    std::string what = e.what();
    if (what.rfind("tooth.", 0) == 0) what = what.substr(6);
    throw std::invalid_argument("teeth." + std::to_string(k) + "." + what);
  }
}

// Teeth: modal data, and their modal coordinates first in the generalised vector, from
// *offset on (advanced past them); compileTooth through *cache when given.
void compileTeeth(Model* model, int* offset, ToothCache* cache) {
  Model& m = *model;
  m.has_large_deflection = false;
  for (size_t k = 0; k < m.teeth.size(); ++k) {
    compileToothAt(model, k, cache);
    m.teeth[k].dof_offset = *offset;
    *offset += m.teeth[k].n_modes;
    if (m.teeth[k].beam_model == ToothBeamModel::kLargeDeflection) m.has_large_deflection = true;
  }
}

// Kernel i (fields named from f, "kernels.<i>."): checked, its pedicel's rest length (a
// negative one means "the distance at the start") and its uniform elliptic disc inertia.
void compileKernel(KernelModel* kernel, const std::string& f) {
  KernelModel& k = *kernel;
  requirePositive(f + "mass", k.mass_kg);
  requireFinite(f + "position[0]", k.initial_position_m.x());
  requireFinite(f + "position[1]", k.initial_position_m.y());
  requireFinite(f + "angle", k.initial_angle_rad);
  requireFinite(f + "velocity[0]", k.initial_velocity_mps.x());
  requireFinite(f + "velocity[1]", k.initial_velocity_mps.y());
  requireFinite(f + "angular_velocity", k.initial_angular_velocity_radps);
  requirePositive(f + "semi_axes[0]", k.semi_axis_a_m);
  requirePositive(f + "semi_axes[1]", k.semi_axis_b_m);
  if (k.semi_axis_b_m > k.semi_axis_a_m)
    fail(f + "semi_axes", "a must be >= b; b is", k.semi_axis_b_m);
  requirePositive(f + "youngs_modulus", k.youngs_modulus_Pa);
  if (!(k.poisson_ratio >= 0.0 && k.poisson_ratio < 0.5))
    fail(f + "poisson_ratio", "must be in [0, 0.5)", k.poisson_ratio);
  if (k.pedicel.present) {
    requirePositive(f + "pedicel.stiffness", k.pedicel.stiffness_Npm);
    requirePositive(f + "pedicel.detachment_force", k.pedicel.detachment_force_N);
    if (!(k.pedicel.damping_Nspm >= 0.0))
      fail(f + "pedicel.damping", "must be >= 0", k.pedicel.damping_Nspm);
    // A negative rest length means "the distance at the start".
    if (k.pedicel.rest_length_m < 0.0) {
      const double c = std::cos(k.initial_angle_rad), s = std::sin(k.initial_angle_rad);
      const Vec2 p_WP =
          k.initial_position_m + Vec2(c * k.pedicel.p_KP_K.x() - s * k.pedicel.p_KP_K.y(),
                                      s * k.pedicel.p_KP_K.x() + c * k.pedicel.p_KP_K.y());
      k.pedicel.rest_length_m = (p_WP - k.pedicel.p_WA_W).norm();
    }
  }
  k.inertia_kgm2 =
      k.mass_kg * (k.semi_axis_a_m * k.semi_axis_a_m + k.semi_axis_b_m * k.semi_axis_b_m) / 4.0;
  if (!(k.inertia_kgm2 > 0.0))
    fail(f + "mass", "gives a polar inertia that underflows to 0; mass", k.mass_kg);
}

// A moving pedicel anchor (a feed's straw mat): finite, and only under the global scheme (the
// island scheme's closed forms and bounds assume a fixed anchor).
void checkAnchorVelocity(const Model& m, const KernelModel& k, const std::string& f) {
  const Vec2& v = k.pedicel.v_WA_W_mps;
  requireFinite(f + "pedicel.anchor_velocity[0]", v.x());
  requireFinite(f + "pedicel.anchor_velocity[1]", v.y());
  if (!v.isZero() && m.integrator.islands)
    fail(f + "pedicel.anchor_velocity", "needs integrator.islands: false; speed", v.norm());
}

// Kernels: uniform elliptic disc inertia, then (c_x, c_y, psi) each, from *offset on.
void compileKernels(Model* model, int* offset) {
  Model& m = *model;
  for (size_t i = 0; i < m.kernels.size(); ++i) {
    KernelModel& k = m.kernels[i];
    compileKernel(&k, "kernels." + std::to_string(i) + ".");
    checkAnchorVelocity(m, k, "kernels." + std::to_string(i) + ".");
    k.dof_offset = *offset;
    *offset += 3;
  }
}

// Obstacles: unit normals, positive sizes.
void compileObstacles(Model* model) {
  Model& m = *model;
  for (size_t j = 0; j < m.obstacles.size(); ++j) {
    ObstacleModel& o = m.obstacles[j];
    const std::string f = "obstacles." + std::to_string(j) + ".";
    if (o.type == ObstacleType::kPlane) {
      const double n = o.normal.norm();
      if (!(n > 0.0) || !std::isfinite(n)) fail(f + "normal", "must be a non-zero vector, norm", n);
      o.normal /= n;
    } else if (o.type == ObstacleType::kCircle) {
      requirePositive(f + "radius", o.radius_m);
    } else {
      if (!((o.point_b_m - o.point_m).norm() > 0.0))
        fail(f + "point_b", "must differ from point; distance", 0.0);
      if (!(o.radius_m >= 0.0)) fail(f + "radius", "must be >= 0", o.radius_m);
    }
    requirePositive(f + "youngs_modulus", o.youngs_modulus_Pa);
  }
}

// Contact laws: Hunt-Crossley factor matched to each restitution coefficient.
void compileContactLaws(Model* model) {
  Model& m = *model;
  const char* names[3] = {"contact.tooth_kernel", "contact.kernel_kernel",
                          "contact.kernel_obstacle"};
  for (int p = 0; p < 3; ++p) {
    ContactParams& c = m.contact[p];
    if (!(c.restitution >= 0.0 && c.restitution <= 1.0))
      fail(std::string(names[p]) + ".restitution", "must be in [0, 1]", c.restitution);
    if (!(c.friction >= 0.0) || !std::isfinite(c.friction))
      fail(std::string(names[p]) + ".friction", "must be >= 0", c.friction);
    c.hc_damping_factor = huntCrossleyFactor(c.restitution);
  }
}

}  // namespace

void compileModel(Model* model) { compileModel(model, nullptr); }

void compileModel(Model* model, ToothCache* teeth) {
  Model& m = *model;
  checkGlobals(m);
  m.drum.speed_bound_radps = std::max(m.drum.max_speed_radps, std::abs(m.drum.initial_speed_radps));
  // Generalised coordinates: the teeth's modal coordinates first, then the kernels'.
  int offset = 0;
  compileTeeth(model, &offset, teeth);
  compileKernels(model, &offset);
  m.n_dof = offset;
  compileObstacles(model);
  compileContactLaws(model);
  m.compiled = true;
}

}  // namespace threshing_sim
