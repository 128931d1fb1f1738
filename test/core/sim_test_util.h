// Shared fixtures for the physics and integrator tests (test_model.cc, test_contact.cc,
// test_time_stepping.cc, test_event_driven.cc, test_simulator.cc, test_physics.cc).
//
// Models are built in code, never loaded from YAML, so that these tests depend on the core
// library only. defaultSceneModel() mirrors config/default_scene.yaml key by key.
#pragma once

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace testutil {

using threshing_sim::kPi;
constexpr double kG = 9.81;  // |gravity| used by every scene here [m/s^2]

// The stepping scheme the models below use: the island-local one (the default), or with
// THRESHING_SIM_GLOBAL_SCHEME the global one, so that one test source runs under both.
#ifdef THRESHING_SIM_GLOBAL_SCHEME
constexpr bool kIslandScheme = false;
#else
constexpr bool kIslandScheme = true;
#endif
inline const char* schemeOverride() {
  return kIslandScheme ? "integrator.islands=true" : "integrator.islands=false";
}

// A value with 10 significant digits, for RecordProperty and failure messages.
inline std::string fmt(double value) {
  std::ostringstream out;
  out.precision(10);
  out << value;
  return out.str();
}

// Same law, restitution and friction for all three pair kinds.
inline void setAllContacts(Model* m, ContactLaw law, double e, double mu) {
  for (ContactParams& c : m->contact) {
    c.law = law;
    c.restitution = e;
    c.friction = mu;
  }
}

inline ObstacleModel planeObstacle(const Vec2& point, const Vec2& normal,
                                   double youngs_modulus_Pa = 2.06e11) {
  ObstacleModel o;
  o.type = ObstacleType::kPlane;
  o.point_m = point;
  o.normal = normal;
  o.youngs_modulus_Pa = youngs_modulus_Pa;
  return o;
}

inline ObstacleModel circleObstacle(const Vec2& center, double radius_m) {
  ObstacleModel o;
  o.type = ObstacleType::kCircle;
  o.center_m = center;
  o.radius_m = radius_m;
  return o;
}

// A paddy-like kernel (rice E, nu) with the given semi-axes, mass and initial state.
inline KernelModel makeKernel(double a_m, double b_m, const Vec2& position_m,
                              const Vec2& velocity_mps = Vec2::Zero(), double angle_rad = 0.0,
                              double mass_kg = 2.8e-5) {
  KernelModel k;
  k.semi_axis_a_m = a_m;
  k.semi_axis_b_m = b_m;
  k.mass_kg = mass_kg;
  k.initial_position_m = position_m;
  k.initial_velocity_mps = velocity_mps;
  k.initial_angle_rad = angle_rad;
  k.youngs_modulus_Pa = 2.8e8;
  k.poisson_ratio = 0.3;
  return k;
}

// The bench stream's kernel on its pedicel: 5 x 1.3 mm, 28 mg, a 3 mm stem of 1600 N/m and
// 0.002 N s/m that breaks at 1.6 N, attached at the end of the major axis, which hangs vertical.
constexpr double kHangRest_m = 3e-3, kHangStiffness_Npm = 1600.0, kHangMass_kg = 2.8e-5;
// The anchor's height above the centre at the static equilibrium [m].
constexpr double kHangDepth_m = kHangRest_m + kHangMass_kg * kG / kHangStiffness_Npm + 5e-3;

// That kernel under the anchor p_WA_W, its centre offset_x_m sideways from the static
// equilibrium (0: at rest; otherwise it swings), at rest.
inline KernelModel hangingKernel(const Vec2& p_WA_W, double offset_x_m = 0.0) {
  const double a_m = 5e-3;
  const Vec2 centre = p_WA_W - Vec2(offset_x_m, kHangDepth_m);
  KernelModel k = makeKernel(a_m, 1.3e-3, centre, Vec2::Zero(), kPi / 2, kHangMass_kg);
  k.pedicel.present = true;
  k.pedicel.p_WA_W = p_WA_W;
  k.pedicel.p_KP_K = Vec2(a_m, 0.0);
  k.pedicel.stiffness_Npm = kHangStiffness_Npm;
  k.pedicel.damping_Nspm = 0.002;
  k.pedicel.rest_length_m = kHangRest_m;
  k.pedicel.detachment_force_N = 1.6;
  return k;
}

// A model with no drum motion and no teeth: kernels and obstacles only.
inline Model bareModel(IntegratorType type) {
  Model m;
  m.drum.initial_speed_radps = 0.0;
  m.integrator.type = type;
  m.integrator.islands = kIslandScheme;
  m.integrator.tolerance = 1e-9;
  m.integrator.dt_s = 1e-6;
  m.gravity_mps2 = Vec2(0.0, -kG);
  return m;
}

// The nylon tooth of the default scene.
inline ToothModel nylonTooth(int n_modes) {
  ToothModel t;
  t.mount_angle_rad = 0.0;
  t.length_m = 0.06;
  t.diameter_m = 0.010;
  t.youngs_modulus_Pa = 3.0e9;
  t.density_kgpm3 = 1140.0;
  t.poisson_ratio = 0.39;
  t.n_modes = n_modes;
  t.damping_ratio = 0.02;
  return t;
}

// config/default_scene.yaml, built in code: one nylon pole tooth (4 modes) on an 800 rpm
// drum of radius 0.2 m strikes a free paddy kernel at (0.235, 0.012); compliant tooth-kernel
// law e 0.48 mu 0.53; rigid kernel-kernel (0.34, 0.66) and kernel-obstacle (0.47, 0.50);
// duration 0.01 s.
inline Model defaultSceneModel(IntegratorType type = IntegratorType::kEventDriven) {
  Model m;
  m.drum.radius_m = 0.20;
  m.drum.initial_speed_radps = 83.78;
  m.drum.max_acceleration_radps2 = 200.0;
  m.teeth = {nylonTooth(4)};
  KernelModel k = makeKernel(5.0e-3, 1.3e-3, Vec2(0.235, 0.012));
  m.kernels = {k};
  m.obstacles = {planeObstacle(Vec2(0.0, -0.5), Vec2(0.0, 1.0)),
                 circleObstacle(Vec2(0.0, -0.28), 0.005)};
  m.contact[static_cast<int>(PairKind::kToothKernel)] = {ContactLaw::kCompliant, 0.48, 0.53};
  m.contact[static_cast<int>(PairKind::kKernelKernel)] = {ContactLaw::kRigid, 0.34, 0.66};
  m.contact[static_cast<int>(PairKind::kKernelObstacle)] = {ContactLaw::kRigid, 0.47, 0.50};
  m.gravity_mps2 = Vec2(0.0, -kG);
  m.integrator.type = type;
  m.integrator.islands = kIslandScheme;
  m.integrator.tolerance = 1e-6;
  m.integrator.dt_s = 1e-6;
  m.duration_s = 0.01;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Scenes shared by the two integrator test files.

// A kernel of semi-axes (a, b) at angle psi dropped on the horizontal plane y = 0: its lowest
// point starts gap_m above the plane, moving at velocity v0 and spinning at w0. One law,
// restitution and friction for every pair.
inline Model dropModel(IntegratorType type, ContactLaw law, double e, double mu, double a_m,
                       double b_m, double gap_m, const Vec2& v0, double psi = 0.0,
                       double w0 = 0.0) {
  Model m = bareModel(type);
  // Half height of the tilted ellipse above its centre: sqrt(a^2 sin^2 psi + b^2 cos^2 psi).
  const double half = std::sqrt(a_m * a_m * std::sin(psi) * std::sin(psi) +
                                b_m * b_m * std::cos(psi) * std::cos(psi));
  KernelModel k = makeKernel(a_m, b_m, Vec2(0.0, half + gap_m), v0, psi);
  k.initial_angular_velocity_radps = w0;
  m.kernels = {k};
  m.obstacles = {planeObstacle(Vec2::Zero(), Vec2(0.0, 1.0))};
  setAllContacts(&m, law, e, mu);
  return m;
}

// Centre minus contact point, c - p, of an ellipse (a, b) at angle psi whose lowest point p
// rests on a horizontal plane [m].
inline Vec2 centreAboveContact(double a_m, double b_m, double psi) {
  const double c = std::cos(psi), s = std::sin(psi);
  const Vec2 d(-s, -c);  // the world direction (0, -1) in the body frame
  Vec2 pb(a_m * a_m * d.x(), b_m * b_m * d.y());
  pb /= std::sqrt(a_m * a_m * d.x() * d.x() + b_m * b_m * d.y() * d.y());
  return -Vec2(c * pb.x() - s * pb.y(), s * pb.x() + c * pb.y());
}

// Lean of c - p from the vertical, positive when the centre lies on the -x side [rad].
inline double leanAngle(double a_m, double b_m, double psi) {
  const Vec2 v = centreAboveContact(a_m, b_m, psi);
  return std::atan2(-v.x(), v.y());
}

// The tilt psi at which an ellipse resting on a horizontal plane has its centre leaning by
// beta (bisection; the lean is monotone in psi over [-0.3, 0.3] for a >= 1.5 b).
inline double tiltForLean(double a_m, double b_m, double beta) {
  double lo = 0.0, hi = leanAngle(a_m, b_m, 0.3) > 0 ? 0.3 : -0.3;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (leanAngle(a_m, b_m, mid) < beta ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// The friction-limit scene. The incline of angle alpha is made by tilting gravity,
// g = 9.81 (sin alpha, -cos alpha), over the horizontal plane y = 0 (downhill is +x): the
// kinematics and the contact geometry are then exactly those of the plane, and only the
// direction of gravity carries the slope.
// An elongated kernel (5 x 1.3 mm) on its flank would rock, because the contact force and
// gravity do not act along one line. The kernel is therefore tilted to its static balance:
// the reaction (-F_t, N) passes through the centre when c - p leans uphill by
// beta = alpha (sticking: F_t / N = tan alpha) or beta = atan(mu) (sliding: F_t = mu N). It
// then neither rocks nor turns and the only motion is the one the friction law allows.
// gap_m: its lowest point starts that far above the plane.
inline Model inclineModel(IntegratorType type, double alpha, double mu, double gap_m) {
  Model m = bareModel(type);
  m.gravity_mps2 = kG * Vec2(std::sin(alpha), -std::cos(alpha));
  const double a = 5.0e-3, b = 1.3e-3;
  const bool slides = std::tan(alpha) > mu;
  const double psi = tiltForLean(a, b, slides ? std::atan(mu) : alpha);
  const Vec2 cp = centreAboveContact(a, b, psi);
  m.kernels = {makeKernel(a, b, Vec2(0.0, cp.y() + gap_m), Vec2::Zero(), psi)};
  m.obstacles = {planeObstacle(Vec2::Zero(), Vec2(0.0, 1.0))};
  setAllContacts(&m, ContactLaw::kRigid, 0.5, mu);
  return m;
}

// A stationary drum (Omega = 0) with one undamped nylon tooth of n modes lying along +x; a
// sphere-like kernel (radius 1.5 mm) 0.2 mm above the tooth's side at material coordinate
// x_m, falling at 2 m/s with some sideways speed. Compliant law, e = 1, mu = 0: nothing
// dissipates and the drive does no work, so mechanicalEnergy must be constant outside contact.
inline Model toothStrikeModel(IntegratorType type, int n_modes, double x_m) {
  Model m = bareModel(type);
  m.drum.radius_m = 0.20;
  m.drum.initial_speed_radps = 0.0;
  ToothModel t = nylonTooth(n_modes);
  t.damping_ratio = 0.0;
  m.teeth = {t};
  const double r = 1.5e-3;
  KernelModel k = makeKernel(r, r, Vec2(0.20 + x_m, 0.005 + r + 2e-4), Vec2(0.3, -2.0), 0.2);
  k.initial_angular_velocity_radps = 50.0;
  m.kernels = {k};
  setAllContacts(&m, ContactLaw::kCompliant, 1.0, 0.0);
  m.integrator.theta = 0.5;
  return m;
}

// Eight elongated kernels (5 x 1.3 mm) with random poses, velocities (1-3 m/s down, up to
// 2 m/s sideways) and spins (up to 200 rad/s) in a 6 cm wide box (floor y = 0, walls at
// x = -/+3 cm): oblique impacts on the plates and against each other.
inline Model kernelPileModel(IntegratorType type, ContactLaw law, double e, double mu,
                             unsigned seed) {
  Model m = bareModel(type);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  for (int i = 0; i < 8; ++i) {
    const double x = -0.02 + 0.04 * (i % 4) / 3.0 + 0.002 * U(rng);
    const double y = 0.008 + 0.012 * (i / 4) + 0.002 * U(rng);
    const Vec2 v(4.0 * (U(rng) - 0.5), -1.0 - 2.0 * U(rng));
    KernelModel k = makeKernel(5e-3, 1.3e-3, Vec2(x, y), v, 2 * kPi * U(rng));
    k.initial_angular_velocity_radps = 400.0 * (U(rng) - 0.5);
    m.kernels.push_back(k);
  }
  m.obstacles = {planeObstacle(Vec2::Zero(), Vec2(0, 1)), planeObstacle(Vec2(-0.03, 0), Vec2(1, 0)),
                 planeObstacle(Vec2(0.03, 0), Vec2(-1, 0))};
  setAllContacts(&m, law, e, mu);
  return m;
}

// One elongated kernel (or a disc when a == b) 0.1 mm above the plate y = 0, with a random
// angle, spin (up to 200 rad/s) and oblique velocity (1-3 m/s down, up to 2 m/s sideways); no
// gravity. The random numbers are drawn in a fixed order (case by case) from rng.
inline Model obliqueImpactModel(IntegratorType type, ContactLaw law, double e, double mu,
                                double a_m, double b_m, std::mt19937* rng) {
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const double psi = kPi * U(*rng);
  const double w = 400.0 * (U(*rng) - 0.5);
  const double vx = 4.0 * (U(*rng) - 0.5);
  const double vy = -1.0 - 2.0 * U(*rng);
  Model m = dropModel(type, law, e, mu, a_m, b_m, 1e-4, Vec2(vx, vy), psi, w);
  m.gravity_mps2 = Vec2::Zero();
  return m;
}

// Velocity of kernel i's centre [m/s].
inline Vec2 kernelVelocity(const Model& m, const Data& d, int i) {
  return d.u.segment<2>(m.kernels[i].dof_offset);
}

// Runs a compiled model from its initial state to t_end; fails the test on kFailed.
inline void runTo(const Model& m, Data* d, double t_end_s) {
  resetData(m, d);
  const StepStatus s = advanceTo(m, d, t_end_s);
  ASSERT_NE(s, StepStatus::kFailed) << "advanceTo failed at t = " << d->t_s;
}

// Byte-wise equality of two vectors (bit-identical runs: no tolerance at all).
inline bool sameBits(const VecX& a, const VecX& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

inline bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof(double)) == 0; }

// Byte-wise equality of two event lists (every numeric field, not a tolerance).
inline bool sameEvents(const std::vector<ContactEvent>& a, const std::vector<ContactEvent>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    const ContactEvent& x = a[i];
    const ContactEvent& y = b[i];
    if (!(x.pair == y.pair) || x.from != y.from || x.to != y.to || x.is_impact != y.is_impact ||
        x.macro_collision != y.macro_collision || x.sub_collision != y.sub_collision)
      return false;
    const double fx[] = {x.t_s,
                         x.vn_before_mps,
                         x.vn_after_mps,
                         x.vt_before_mps,
                         x.vt_after_mps,
                         x.impulse_normal_Ns,
                         x.impulse_tangential_Ns,
                         x.energy_lost_J,
                         x.peak_normal_force_N};
    const double fy[] = {y.t_s,
                         y.vn_before_mps,
                         y.vn_after_mps,
                         y.vt_before_mps,
                         y.vt_after_mps,
                         y.impulse_normal_Ns,
                         y.impulse_tangential_Ns,
                         y.energy_lost_J,
                         y.peak_normal_force_N};
    if (std::memcmp(fx, fy, sizeof(fx)) != 0) return false;
  }
  return true;
}

}  // namespace testutil
}  // namespace threshing_sim
