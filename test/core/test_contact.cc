// Unit tests of the contact kinematics (src/core/contact/): gap, normal, Jacobians and
// rheonomic terms checked by finite differences of the geometry along the motion; the broad
// phase; the Hertz constant. Uses the internal header (the core's narrow phase is not public).
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

#include "../../src/core/internal.h"
#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using internal::ContactGeom;
using internal::Drive;
using testutil::fmt;
using testutil::makeKernel;

inline Vec2 rot(double angle_rad, const Vec2& v) {
  const double c = std::cos(angle_rad), s = std::sin(angle_rad);
  return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y());
}

// Evaluates one pair of a compiled model at configuration z, velocity u and drum angle and
// speed (theta, omega) with the library's narrow phase.
ContactGeom evaluate(const Model& m, const VecX& z, const VecX& u, double theta, double omega,
                     const PairId& pair) {
  Workspace ws;
  internal::updateStations(m, z, theta, &ws);
  Drive dr;
  dr.theta_rad = theta;
  dr.omega_radps = omega;
  ContactGeom g;
  internal::evaluateContact(m, z, u, dr, pair, &ws, &g);
  return g;
}

// The state moved along the motion by dt: z + dt u, theta + dt omega (u and omega frozen).
struct Motion {
  VecX z, u;
  double theta, omega;
  double gapAt(const Model& m, const PairId& pair, double dt) const {
    const VecX zz = z + dt * u;
    return evaluate(m, zz, u, theta + dt * omega, omega, pair).gap_m;
  }
};

// Velocity of the kernel's material point that sits at p_W now [m/s]: by central differences
// of its body-fixed position along the motion.
Vec2 kernelPointVelocityFd(const Model& m, const Motion& mo, int kernel, const Vec2& p_W,
                           double eps) {
  const int o = m.kernels[kernel].dof_offset;
  const Vec2 c = mo.z.segment<2>(o);
  const Vec2 r_body = rot(-mo.z[o + 2], p_W - c);
  auto at = [&](double dt) {
    const VecX zz = mo.z + dt * mo.u;
    return Vec2(zz.segment<2>(o) + rot(zz[o + 2], r_body));
  };
  return (at(eps) - at(-eps)) / (2 * eps);
}

// Velocity of the tooth's material surface point at (x*, p_W) [m/s]: the centreline point at x*
// moves with the drum and the modes; the surface offset p_W - r(x*) turns with the drum and
// with the section's slope w'(x*) = phi'(x*) q. Evaluated with the public mode shapes
// (beam.h), not with the narrow phase.
Vec2 toothPointVelocityFd(const Model& m, const Motion& mo, int tooth, double x_m, const Vec2& p_W,
                          double eps) {
  const ToothModel& tm = m.teeth[tooth];
  const int n = tm.n_modes;
  VecX phi = VecX::Zero(n), dphi = VecX::Zero(n);
  MatX H = MatX::Zero(n, n);
  if (n > 0) {
    evaluateModes(tm, x_m, &phi, &dphi);
    interpolateH(tm, x_m, &H);
  }
  auto centre = [&](const VecX& q, double theta) {
    const double w = n > 0 ? phi.dot(q) : 0.0;
    const double wc = n > 0 ? -0.5 * q.dot(H * q) : 0.0;
    return rot(theta, Vec2(tm.p_DR_D + (x_m + wc) * tm.e1_D + w * tm.e2_D));
  };
  const VecX q0 = mo.z.segment(tm.dof_offset, n);
  const Vec2 offset = p_W - centre(q0, mo.theta);
  auto at = [&](double dt) {
    const VecX q = q0 + dt * mo.u.segment(tm.dof_offset, n);
    const double turn = dt * mo.omega + (n > 0 ? dphi.dot(q - q0) : 0.0);
    return Vec2(centre(q, mo.theta + dt * mo.omega) + rot(turn, offset));
  };
  return (at(eps) - at(-eps)) / (2 * eps);
}

// Moves kernel `kernel` along the contact normal of `pair` until the gap is gap_m (3 passes of
// a fixed-point iteration: the normal barely turns over such small moves).
void placeAtGap(const Model& m, Motion* mo, const PairId& pair, int kernel, double gap_m) {
  const int o = m.kernels[kernel].dof_offset;
  for (int it = 0; it < 3; ++it) {
    const ContactGeom g = evaluate(m, mo->z, mo->u, mo->theta, mo->omega, pair);
    mo->z.segment<2>(o) += (gap_m - g.gap_m) * g.n;
  }
}

// A model with one nylon tooth (n modes) on the drum, one elongated kernel and the two
// obstacle kinds, compiled. Obstacles are far from the tooth.
Model contactModel(int n_modes,
                   ToothSectionRotation rotation = ToothSectionRotation::kShearCorrected) {
  Model m;
  m.drum.radius_m = 0.20;
  m.drum.initial_speed_radps = 83.78;
  m.teeth = {testutil::nylonTooth(n_modes)};
  m.teeth[0].section_rotation = rotation;
  m.kernels = {makeKernel(5.0e-3, 1.3e-3, Vec2(0.235, 0.012)),
               makeKernel(4.0e-3, 1.5e-3, Vec2(0.0, -0.4)),
               makeKernel(5.0e-3, 1.3e-3, Vec2(0.0, -0.27))};
  m.obstacles = {testutil::planeObstacle(Vec2(0.0, -0.5), Vec2(0.3, 1.0)),
                 testutil::circleObstacle(Vec2(0.0, -0.28), 0.005)};
  compileModel(&m);
  return m;
}

// ---------------------------------------------------------------------------------------------
// Jacobians by finite differences.
//
// dg_N/dt reported by the narrow phase (w_N^T u + w~_N) must equal the derivative of the gap
// along the motion; dg_T/dt must equal the relative velocity of the two material points at the
// contact along t. Central differences with eps = 1e-7 s move the bodies by ~1e-6 m: the
// truncation error is ~eps^2 g''' ~ 1e-10 m/s and the rounding error of the distance queries
// (~1e-15 m, Eberly bisection to machine precision) / eps ~ 1e-8 m/s. Tolerances are set
// per check below.

constexpr double kEps = 1e-7;

struct FdResult {
  ContactGeom g;
  double vn_fd_gap;  // d gap / dt by central differences [m/s]
  double vn_fd_pts;  // (v1 - v0) . n from material point velocities [m/s]
  double vt_fd_pts;  // (v1 - v0) . t [m/s]
};

FdResult checkByFd(const Model& m, const Motion& mo, const PairId& pair) {
  FdResult r;
  r.g = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
  r.vn_fd_gap = (mo.gapAt(m, pair, kEps) - mo.gapAt(m, pair, -kEps)) / (2 * kEps);
  const int kb = pair.kind == PairKind::kKernelObstacle ? pair.a : pair.b;
  const Vec2 v1 = kernelPointVelocityFd(m, mo, kb, r.g.p1, kEps);
  Vec2 v0 = Vec2::Zero();
  if (pair.kind == PairKind::kToothKernel)
    v0 = toothPointVelocityFd(m, mo, pair.a, r.g.tooth_x_m, r.g.p0, kEps);
  else if (pair.kind == PairKind::kKernelKernel)
    v0 = kernelPointVelocityFd(m, mo, pair.a, r.g.p0, kEps);
  r.vn_fd_pts = (v1 - v0).dot(r.g.n);
  r.vt_fd_pts = (v1 - v0).dot(r.g.t);
  return r;
}

// The tooth-kernel scene used by the Jacobian checks: tooth deflected (tip ~1.5 mm) and
// vibrating in its 4 modes (tip speed ~3 m/s) on a drum at 800 rpm, turned by 0.03 rad; the
// kernel 0.15 mm off the tooth's leading side at material coordinate x_c, tilted, moving and
// spinning.
Motion toothKernelMotion(const Model& m, double x_c, double tilt_rad = 0.1) {
  Motion mo;
  mo.z = VecX::Zero(m.n_dof);
  mo.u = VecX::Zero(m.n_dof);
  const ToothModel& tm = m.teeth[0];
  const VecX q = (VecX(4) << 5e-5, -1e-5, 4e-6, -2e-6).finished();
  const VecX qd = (VecX(4) << -0.1, 0.08, -0.05, 0.03).finished();
  mo.z.segment(tm.dof_offset, 4) = q;
  mo.u.segment(tm.dof_offset, 4) = qd;
  mo.theta = 0.03;
  mo.omega = 83.78;
  const int o = m.kernels[0].dof_offset;
  VecX phi, dphi;
  evaluateModes(tm, x_c, &phi, &dphi);
  mo.z.segment<2>(o) = rot(mo.theta, Vec2(0.2 + x_c, phi.dot(q) + 0.005 + 1.3e-3 + 1.5e-4));
  mo.z[o + 2] = mo.theta + tilt_rad;
  mo.u.segment<2>(o) = Vec2(-1.5, 2.0);
  mo.u[o + 2] = 300.0;
  return mo;
}

// With Euler-Bernoulli sections the material point turns with the slope w', as
// toothPointVelocityFd moves it.
TEST(ContactJacobian, ToothKernelMatchesMaterialPointVelocities) {
  const Model m = contactModel(4, ToothSectionRotation::kEulerBernoulli);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  for (double x_c : {0.030, 0.033}) {  // at a station, and between two stations
    const Motion mo = toothKernelMotion(m, x_c);
    const FdResult r = checkByFd(m, mo, pair);
    ASSERT_GT(r.g.gap_m, 0.0);
    ASSERT_LT(r.g.gap_m, 2e-4);
    // The material point is taken at p0, rigidly attached to the section at x*: the narrow
    // phase puts p0 on the capsule around the station polyline, the Jacobian moves it with the
    // exact mode shapes at x*. The two descriptions differ by the chord error
    // delta = |p0 - (r(x*) + r_t n)| turning with the section: (|Omega| + |w'_dot(x*)|) delta.
    const ToothModel& tm = m.teeth[0];
    VecX phi, dphi;
    evaluateModes(tm, r.g.tooth_x_m, &phi, &dphi);
    Data d;
    resetData(m, &d);
    d.z = mo.z;
    d.theta_rad = mo.theta;
    const Vec2 on_curve = toothPointWorld(m, d, 0, r.g.tooth_x_m) + 0.5 * tm.diameter_m * r.g.n;
    const double delta = (r.g.p0 - on_curve).norm();
    const double slope_rate = std::abs(dphi.dot(mo.u.segment(tm.dof_offset, 4)));
    // 1e-6 m/s: the FD error (see above) on speeds of ~20 m/s.
    const double tol = 1e-6 + 1.01 * (std::abs(mo.omega) + slope_rate) * delta;
    EXPECT_NEAR(r.g.vn, r.vn_fd_pts, tol) << "x_c = " << x_c << ", delta = " << delta;
    EXPECT_NEAR(r.g.vt, r.vt_fd_pts, tol) << "x_c = " << x_c << ", delta = " << delta;
    RecordProperty("chord_error_m_x" + fmt(x_c), fmt(delta));
  }
}

// Shear-corrected sections (the default) turn by psi_i = f_i phi_i' per mode: the surface
// point's tangential velocity differs from the Euler-Bernoulli one by exactly
// -r_t sum_i (f_i - 1) phi_i'(x*) qdot_i, its normal velocity not at all (the section's turn
// moves the surface point along t).
TEST(ContactJacobian, ShearCorrectedSectionsTurnTheSurfacePointByPsi) {
  const Model eb = contactModel(4, ToothSectionRotation::kEulerBernoulli);
  const Model shear = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  for (double x_c : {0.030, 0.033}) {
    const Motion mo = toothKernelMotion(shear, x_c);
    const ContactGeom ge = evaluate(eb, mo.z, mo.u, mo.theta, mo.omega, pair);
    const ContactGeom gs = evaluate(shear, mo.z, mo.u, mo.theta, mo.omega, pair);
    const ToothModel& tm = shear.teeth[0];
    VecX phi, dphi;
    interpolateModes(tm, gs.tooth_x_m, &phi, &dphi);  // the step's phi' (the mode table)
    double turn = 0.0;
    for (int i = 0; i < 4; ++i)
      turn += (tm.rotation_factor[i] - 1.0) * dphi[i] * mo.u[tm.dof_offset + i];
    EXPECT_EQ(gs.tooth_x_m, ge.tooth_x_m);
    EXPECT_NEAR(gs.vn, ge.vn, 1e-12);
    EXPECT_NEAR(gs.vt, ge.vt - 0.5 * tm.diameter_m * turn, 1e-12) << "x_c = " << x_c;
    EXPECT_GT(std::abs(gs.vt - ge.vt), 1e-4);  // the correction is there
  }
}

// At a station the polyline through the stations moves exactly like the tooth, so there the
// gap's rate must be w_N^T u + w~_N. The tooth is straight (q = 0, so the closest point of the
// aligned kernel lies right under its centre, at the station x = 30 mm) but vibrating in all
// 4 modes on the spinning drum. 1e-5 m/s (6e-7 of |v| ~ 18 m/s): the FD error and the closest
// point's offset from the station (~1e-9 m) times the chord error's slope.
TEST(ContactJacobian, ToothKernelNormalVelocityIsGapRateAtAStation) {
  const Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  Motion mo = toothKernelMotion(m, 0.030, 0.0);
  mo.z.segment(m.teeth[0].dof_offset, 4).setZero();
  placeAtGap(m, &mo, pair, 0, 1.5e-4);
  const FdResult r = checkByFd(m, mo, pair);
  ASSERT_NEAR(r.g.tooth_x_m, 0.030, 1e-8);
  RecordProperty("vn", fmt(r.g.vn));
  RecordProperty("vn_fd_gap", fmt(r.vn_fd_gap));
  EXPECT_NEAR(r.g.vn, r.vn_fd_gap, 1e-5);
}

// Regression guard (narrow_phase.cc, the tooth-kernel pair function): the gap was measured to
// the capsule around the polyline through the stations while w_N used the exact mode shapes
// phi(x*), phi'(x*), so between stations dg/dt != w_N^T u + w~_N (at x = 33 mm the modal part
// was off by 0.5 % for mode 1 up to 20 % for mode 4). The closest point is now refined on the
// exact deformed centreline, the same curve w_N describes.
// Each mode alone (drum still, kernel at rest, straight tooth vibrating in that mode only):
// the brief asks that the reported dg/dt equal the gap's derivative; 1e-3 relative is far
// above the FD error (1e-6 m/s on ~1 m/s) and far below what a consistent model gives wrong.
TEST(ContactJacobian, ToothKernelNormalVelocityIsGapRateBetweenStations) {
  Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  for (int mode = 0; mode < 4; ++mode) {
    Motion mo = toothKernelMotion(m, 0.033, 0.0);
    mo.omega = 0.0;
    mo.z.segment(m.teeth[0].dof_offset, 4).setZero();
    mo.u.setZero();
    mo.u[m.teeth[0].dof_offset + mode] = 0.1;
    placeAtGap(m, &mo, pair, 0, 1.5e-4);
    const FdResult r = checkByFd(m, mo, pair);
    RecordProperty("mode" + std::to_string(mode + 1) + "_vn", fmt(r.g.vn));
    RecordProperty("mode" + std::to_string(mode + 1) + "_vn_fd_gap", fmt(r.vn_fd_gap));
    EXPECT_NEAR(r.g.vn, r.vn_fd_gap, 1e-6 + 1e-3 * std::abs(r.g.vn))
        << "mode " << mode + 1 << " at x = " << r.g.tooth_x_m << ": ratio " << r.vn_fd_gap / r.g.vn;
  }
}

TEST(ContactJacobian, KernelKernel) {
  const Model m = contactModel(0);
  Motion mo;
  mo.z = VecX::Zero(m.n_dof);
  mo.u = VecX::Zero(m.n_dof);
  mo.theta = 0.0;
  mo.omega = 83.78;  // must not matter: no rheonomic term between two kernels
  const int o0 = m.kernels[0].dof_offset, o1 = m.kernels[1].dof_offset;
  mo.z.segment<3>(o0) << 0.0, 0.3, 0.4;
  mo.u.segment<3>(o0) << 1.0, -2.0, -250.0;
  // Kernel 1 (a 4 x 1.5 mm) crossing kernel 0 obliquely, then moved to 0.2 mm apart.
  mo.z.segment<3>(o1) << 0.0035, 0.3043, 1.9;
  mo.u.segment<3>(o1) << -0.5, 0.7, 400.0;
  const PairId pair{PairKind::kKernelKernel, 0, 1};
  placeAtGap(m, &mo, pair, 1, 2e-4);
  const FdResult r = checkByFd(m, mo, pair);
  ASSERT_GT(r.g.gap_m, 0.0);
  ASSERT_LT(r.g.gap_m, 1e-3);
  EXPECT_EQ(r.g.wtilde_n, 0.0);
  // 1e-6 m/s: FD error on relative speeds of ~3 m/s (see kEps).
  EXPECT_NEAR(r.g.vn, r.vn_fd_gap, 1e-6);
  EXPECT_NEAR(r.g.vn, r.vn_fd_pts, 1e-6);
  EXPECT_NEAR(r.g.vt, r.vt_fd_pts, 1e-6);
  // Overlapping (penetration 0.1 mm) the same must hold (the gap is signed and smooth).
  placeAtGap(m, &mo, pair, 1, -1e-4);
  const FdResult r2 = checkByFd(m, mo, pair);
  ASSERT_LT(r2.g.gap_m, 0.0);
  EXPECT_NEAR(r2.g.vn, r2.vn_fd_gap, 1e-6);
  EXPECT_NEAR(r2.g.vt, r2.vt_fd_pts, 1e-6);
}

TEST(ContactJacobian, KernelPlane) {
  const Model m = contactModel(0);
  Motion mo;
  mo.z = VecX::Zero(m.n_dof);
  mo.u = VecX::Zero(m.n_dof);
  mo.theta = 0.0;
  mo.omega = 83.78;
  const int o = m.kernels[1].dof_offset;
  // The plane through (0, -0.5) with normal (0.3, 1)/|.|; kernel 1 tilted, 0.2 mm above it.
  const Vec2 n = Vec2(0.3, 1.0).normalized();
  const Vec2 c = Vec2(0.0, -0.5) + (2.0e-3) * n + 0.01 * Vec2(-n.y(), n.x());
  mo.z.segment<3>(o) << c.x(), c.y(), 0.7;
  mo.u.segment<3>(o) << 0.8, -1.7, -150.0;
  const PairId pair{PairKind::kKernelObstacle, 1, 0};
  placeAtGap(m, &mo, pair, 1, 2e-4);
  const FdResult r = checkByFd(m, mo, pair);
  ASSERT_GT(r.g.gap_m, 0.0);
  ASSERT_LT(r.g.gap_m, 1e-3);
  // The normal is the plane's (compiled to unit length), 1e-15: rounding.
  EXPECT_NEAR(r.g.n.x(), n.x(), 1e-15);
  EXPECT_NEAR(r.g.n.y(), n.y(), 1e-15);
  EXPECT_NEAR(r.g.vn, r.vn_fd_gap, 1e-6);
  EXPECT_NEAR(r.g.vn, r.vn_fd_pts, 1e-6);
  EXPECT_NEAR(r.g.vt, r.vt_fd_pts, 1e-6);
}

TEST(ContactJacobian, KernelCircle) {
  const Model m = contactModel(0);
  Motion mo;
  mo.z = VecX::Zero(m.n_dof);
  mo.u = VecX::Zero(m.n_dof);
  mo.theta = 0.0;
  mo.omega = 83.78;
  const int o = m.kernels[2].dof_offset;
  // Kernel 2 beside the bar of radius 5 mm at (0, -0.28), long axis at 40 degrees, 0.2 mm off.
  mo.z.segment<3>(o) << 0.0055, -0.2735, 0.7;
  mo.u.segment<3>(o) << -2.0, -1.0, 500.0;
  const PairId pair{PairKind::kKernelObstacle, 2, 1};
  placeAtGap(m, &mo, pair, 2, 2e-4);
  const FdResult r = checkByFd(m, mo, pair);
  ASSERT_GT(r.g.gap_m, 0.0);
  ASSERT_LT(r.g.gap_m, 2e-3);
  EXPECT_NEAR(r.g.vn, r.vn_fd_gap, 1e-6);
  EXPECT_NEAR(r.g.vn, r.vn_fd_pts, 1e-6);
  EXPECT_NEAR(r.g.vt, r.vt_fd_pts, 1e-6);
}

// ---------------------------------------------------------------------------------------------
// Rheonomic term.

// A kernel at rest touching a rigid radial tooth on a drum spinning at Omega: the tooth surface
// point p0 = (R + x, r_t) (drum angle 0) moves at Omega J p0 = Omega (-r_t, R + x), so with
// n = +y and t = J n = -x: dg_N/dt = -Omega (R + x), dg_T/dt = -Omega r_t.
TEST(ContactRheonomic, KernelAtRestOnSpinningToothClosesAtOmegaTimesRadius) {
  const double R = 0.20, x = 0.035, r_t = 0.005, omega = 83.78;
  for (int n_modes : {0, 4}) {  // an undeformed, still flexible tooth must give the same
    Model m = contactModel(n_modes);
    m.kernels[0].initial_position_m = Vec2(R + x, r_t + 1.3e-3 + 1e-5);
    compileModel(&m);
    Data d;
    resetData(m, &d);
    const ContactGeom g = evaluate(m, d.z, d.u, 0.0, omega, PairId{PairKind::kToothKernel, 0, 0});
    // Normal +y to 1e-9 (the tooth side is flat; the kernel's flank is horizontal).
    EXPECT_NEAR(g.n.y(), 1.0, 1e-9);
    // 1e-6 relative: the closest point's x on the flat side is found to ~1e-9 m.
    EXPECT_NEAR(g.vn, -omega * (R + x), 1e-6 * omega * (R + x)) << "n = " << n_modes;
    EXPECT_NEAR(g.wtilde_n, -omega * (R + x), 1e-6 * omega * (R + x));
    EXPECT_NEAR(g.vt, -omega * r_t, 1e-6 * omega * (R + x));
  }
}

// The same through the public API: one time step of a compiled model; data.contacts reports
// the pair with dg_N/dt = -Omega (R + x). The step is 1e-8 s, so the drum turns by 8e-7 rad
// and the reported values (taken at the midpoint) move by < 1e-6 relative. One step of the
// global scheme (under islands step() advances a whole scheduling window).
TEST(ContactRheonomic, ReportedThroughDataContactsAfterOneStep) {
  const double R = 0.20, x = 0.035, r_t = 0.005, omega = 83.78;
  Model m = contactModel(4);
  m.kernels[0].initial_position_m = Vec2(R + x, r_t + 1.3e-3 + 1e-5);
  m.integrator.type = IntegratorType::kTimeStepping;
  m.integrator.dt_s = 1e-8;
  m.integrator.islands = false;
  m.gravity_mps2 = Vec2::Zero();
  compileModel(&m);
  Data d;
  resetData(m, &d);
  ASSERT_EQ(step(m, &d), StepStatus::kOk);
  bool found = false;
  for (const ContactInfo& c : d.contacts) {
    if (!(c.pair == PairId{PairKind::kToothKernel, 0, 0})) continue;
    found = true;
    EXPECT_NEAR(c.normal_velocity_mps, -omega * (R + x), 1e-5 * omega * (R + x));
    EXPECT_NEAR(c.slip_velocity_mps, -omega * r_t, 1e-5 * omega * (R + x));
    EXPECT_NEAR(c.gap_m, 1e-5, 1e-6);  // moved by < vn h ~ 2e-7 m
  }
  EXPECT_TRUE(found) << "the touching pair is not in data.contacts";
}

// ---------------------------------------------------------------------------------------------
// Broad phase.

std::vector<PairId> candidates(const Model& m, const VecX& z, double theta, double margin) {
  Workspace ws;
  internal::updateStations(m, z, theta, &ws);
  internal::broadPhase(m, z, margin, &ws);
  return ws.candidates;
}

bool contains(const std::vector<PairId>& v, const PairId& p) {
  for (const PairId& q : v)
    if (q == p) return true;
  return false;
}

TEST(BroadPhase, FarPairsAreNotCandidatesNearOnesAre) {
  Model m = contactModel(4);
  compileModel(&m);
  Data d;
  resetData(m, &d);
  VecX z = d.z;
  const int o0 = m.kernels[0].dof_offset, o1 = m.kernels[1].dof_offset,
            o2 = m.kernels[2].dof_offset;
  const double margin = 2e-3;
  // Far: kernel 0 a metre from the tooth, kernels 1 and 2 far from each other and from the
  // obstacles.
  z.segment<2>(o0) = Vec2(1.0, 1.0);
  z.segment<2>(o1) = Vec2(-1.0, 0.5);
  z.segment<2>(o2) = Vec2(-1.0, 0.0);
  std::vector<PairId> c = candidates(m, z, 0.0, margin);
  EXPECT_TRUE(c.empty()) << c.size() << " candidates for bodies metres apart";
  // Near: kernel 0 1 mm above the tooth's side; kernel 1 1 mm from kernel 2's bounding
  // circle; kernel 2 1 mm above the plane... (the plane is tilted; put kernel 2 near the bar).
  z.segment<2>(o0) = Vec2(0.235, 0.005 + 1.3e-3 + 1e-3);
  z.segment<2>(o1) = Vec2(0.02, -0.28);
  z.segment<2>(o2) = Vec2(0.02 + 4e-3 + 5e-3 + 1e-3, -0.28);
  c = candidates(m, z, 0.0, margin);
  EXPECT_TRUE(contains(c, PairId{PairKind::kToothKernel, 0, 0}));
  EXPECT_TRUE(contains(c, PairId{PairKind::kKernelKernel, 1, 2}));
  EXPECT_FALSE(contains(c, PairId{PairKind::kKernelKernel, 0, 1}));
  // The tooth rotates with the drum: at theta = pi/2 it points up, away from kernel 0.
  c = candidates(m, z, testutil::kPi / 2, margin);
  EXPECT_FALSE(contains(c, PairId{PairKind::kToothKernel, 0, 0}));
  // Kernel 1 (a = 4 mm) 1 mm above the bar (r 5 mm at (0, -0.28)): candidate; 3 mm: not.
  z.segment<2>(o1) = Vec2(0.0, -0.28 + 0.005 + 4e-3 + 1e-3);
  c = candidates(m, z, 0.0, margin);
  EXPECT_TRUE(contains(c, PairId{PairKind::kKernelObstacle, 1, 1}));
  z.segment<2>(o1) = Vec2(0.0, -0.28 + 0.005 + 4e-3 + 3e-3);
  c = candidates(m, z, 0.0, margin);
  EXPECT_FALSE(contains(c, PairId{PairKind::kKernelObstacle, 1, 1}));
}

// Sweep and prune against brute force: 60 random kernels in a 6 x 6 cm box, margin 2 mm. The
// documented criterion is "bounding shapes within margin": centre distance <= a_i + a_j +
// margin. Every pair whose true distance is <= margin must be in the set (no misses).
TEST(BroadPhase, KernelKernelMatchesBruteForce) {
  std::mt19937 rng(12345);
  std::uniform_real_distribution<double> pos(-0.03, 0.03), ang(0, 2 * testutil::kPi),
      ax(1e-3, 5e-3);
  Model m;
  for (int i = 0; i < 60; ++i) {
    const double a = ax(rng);
    m.kernels.push_back(
        makeKernel(a, 0.3 * a, Vec2(pos(rng), pos(rng) + 1.0), Vec2::Zero(), ang(rng)));
  }
  compileModel(&m);
  Data d;
  resetData(m, &d);
  const double margin = 2e-3;
  const std::vector<PairId> c = candidates(m, d.z, 0.0, margin);
  int expected = 0;
  for (int i = 0; i < 60; ++i) {
    for (int j = i + 1; j < 60; ++j) {
      const Vec2 ci = d.z.segment<2>(m.kernels[i].dof_offset);
      const Vec2 cj = d.z.segment<2>(m.kernels[j].dof_offset);
      const bool near =
          (ci - cj).norm() <= m.kernels[i].semi_axis_a_m + m.kernels[j].semi_axis_a_m + margin;
      expected += near ? 1 : 0;
      EXPECT_EQ(contains(c, PairId{PairKind::kKernelKernel, i, j}), near) << i << ", " << j;
      const double dist =
          ellipseEllipse(internal::kernelEllipse(m, d.z, i), internal::kernelEllipse(m, d.z, j))
              .distance_m;
      if (dist <= margin) {
        EXPECT_TRUE(near) << "missed a pair " << dist << " m apart";
      }
    }
  }
  EXPECT_GT(expected, 5);  // the scene does test something
  RecordProperty("near_pairs", expected);
}

// The broad phase (kernel order kept across calls, teeth and obstacles found by bisection in
// x order) against testing every pair, on random layouts: kernels scattered around a drum of
// four teeth among grate bars, plates and a plane, moved at random between calls (as steps
// would, and by jumps that reorder them wholesale). The candidate lists must be equal.
TEST(BroadPhase, CandidatesEqualBruteForceOnRandomLayouts) {
  std::mt19937 rng(20261121);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  long total = 0, by_kind[3] = {0, 0, 0};
  for (int layout = 0; layout < 20; ++layout) {
    Model m;
    m.drum.radius_m = 0.14;
    for (int k = 0; k < 4; ++k) {
      ToothModel t = testutil::nylonTooth(k % 3 + 1);
      t.mount_angle_rad = k * testutil::kPi / 2;
      m.teeth.push_back(t);
    }
    const int K = 50 + static_cast<int>(U(rng) * 250);
    for (int i = 0; i < K; ++i) {
      const double r = 0.15 + 0.15 * U(rng), phi = 2 * testutil::kPi * U(rng);
      const double a = 1e-3 + 5e-3 * U(rng);
      m.kernels.push_back(makeKernel(a, 0.3 * a, Vec2(r * std::cos(phi), r * std::sin(phi)),
                                     Vec2::Zero(), 2 * testutil::kPi * U(rng)));
    }
    for (int j = 0; j < 31; ++j) {
      const double phi = -2.618 + j * 0.0698;
      m.obstacles.push_back(testutil::circleObstacle(
          Vec2(0.215 * std::cos(phi), 0.215 * std::sin(phi)), 0.003 + 0.004 * U(rng)));
    }
    for (int j = 0; j < 3; ++j) {
      ObstacleModel o;
      o.type = ObstacleType::kSegment;
      o.point_m = Vec2(0.3 * (U(rng) - 0.5), 0.3 * (U(rng) - 0.5));
      o.point_b_m = o.point_m + Vec2(0.2 * (U(rng) - 0.5), 0.2 * (U(rng) - 0.5));
      o.radius_m = 2e-3;
      m.obstacles.push_back(o);
    }
    m.obstacles.push_back(testutil::planeObstacle(Vec2(0.0, -0.25), Vec2(0.0, 1.0)));
    compileModel(&m);
    Data d;
    resetData(m, &d);
    Workspace ws;  // one workspace across calls, as in a run
    Workspace ws_lazy_stations;
    VecX z = d.z;
    for (int call = 0; call < 12; ++call) {
      // Small random motion, and every fourth call a wholesale shuffle of a tenth of the kernels.
      for (int i = 0; i < K; ++i) {
        const int o = m.kernels[i].dof_offset;
        const bool jump = call % 4 == 3 && U(rng) < 0.1;
        const double step = jump ? 0.2 : 2e-3;
        z[o] += step * (U(rng) - 0.5);
        z[o + 1] += step * (U(rng) - 0.5);
        z[o + 2] += U(rng) - 0.5;
      }
      for (int k = 0; k < 4; ++k)
        for (int i = 0; i < m.teeth[k].n_modes; ++i)
          z[m.teeth[k].dof_offset + i] = 2e-3 * (U(rng) - 0.5);
      const double theta = 2 * testutil::kPi * U(rng), margin = 1e-3 + 3e-3 * U(rng);
      internal::updateStations(m, z, theta, &ws);
      internal::broadPhase(m, z, margin, &ws);
      const std::vector<PairId> fast = ws.candidates;
      // Stations computed by the broad phase itself, only for the teeth that need them.
      Workspace& ws_lazy = ws_lazy_stations;
      internal::layoutStations(m, &ws_lazy);
      internal::broadPhase(m, z, margin, &ws_lazy, &theta);
      ASSERT_EQ(fast.size(), ws_lazy.candidates.size()) << "layout " << layout << ", call " << call;
      for (size_t c = 0; c < fast.size(); ++c)
        ASSERT_TRUE(fast[c] == ws_lazy.candidates[c]) << "layout " << layout << ", call " << call;
      internal::broadPhaseBruteForce(m, z, margin, &ws);
      ASSERT_EQ(fast.size(), ws.candidates.size()) << "layout " << layout << ", call " << call;
      for (size_t c = 0; c < fast.size(); ++c) {
        ASSERT_TRUE(fast[c] == ws.candidates[c]) << "layout " << layout << ", call " << call;
        ++by_kind[static_cast<int>(fast[c].kind)];
      }
      total += static_cast<long>(fast.size());
    }
  }
  // The layouts test every kind of pair.
  EXPECT_GT(by_kind[0], 20);
  EXPECT_GT(by_kind[1], 200);
  EXPECT_GT(by_kind[2], 200);
  RecordProperty("candidates", static_cast<int>(total));
}

// ---------------------------------------------------------------------------------------------
// Hertz constant.

// A sphere-like kernel (a = b) on a flat plate: Hertz's sphere-on-flat, K = 4/3 E* sqrt(R) with
// 1/E* = (1 - nu_k^2)/E_k + (1 - nu_o^2)/E_o (Johnson, Contact Mechanics, eq. 4.22-4.23).
TEST(HertzConstant, SphereLikeKernelOnPlaneMatchesClosedForm) {
  for (double E_o : {2.06e11, 3.0e9, 1e15}) {
    Model m;
    m.kernels = {makeKernel(1.5e-3, 1.5e-3, Vec2(0.0, 1.4e-3))};
    m.obstacles = {testutil::planeObstacle(Vec2::Zero(), Vec2(0, 1), E_o)};
    m.obstacles[0].poisson_ratio = 0.25;
    compileModel(&m);
    Data d;
    resetData(m, &d);
    const ContactGeom g = evaluate(m, d.z, d.u, 0.0, 0.0, PairId{PairKind::kKernelObstacle, 0, 0});
    const double E_star = 1.0 / ((1 - 0.3 * 0.3) / 2.8e8 + (1 - 0.25 * 0.25) / E_o);
    const double K = 4.0 / 3.0 * E_star * std::sqrt(1.5e-3);
    // 1e-9 relative: the curvature radius at the contact point comes from the ellipse code,
    // exact for a circle up to rounding.
    EXPECT_NEAR(g.hertz_K, K, 1e-9 * K) << "E_o = " << E_o;
    EXPECT_NEAR(g.gap_m, -1e-4, 1e-12);
  }
}

// ---------------------------------------------------------------------------------------------
// Velocity drift (internal::contactVelocityDrift): the analytic (d/dt W)^T u + d(wtilde)/dt of
// the normal and tangential rows against central differences of the narrow phase's
// (dg_N/dt, dg_T/dt) along the motion z' = u (u frozen) with the drum accelerating at alpha:
// theta(t) = theta + Omega t + alpha t^2 / 2, Omega(t) = Omega + alpha t. Richardson-extrapolated
// central differences over eps = 1e-6 s and 2 eps: the truncation error is ~eps^4 times the
// fifth derivative (contact points sliding over curvature radii of millimetres at ~20 m/s turn
// the normal at ~4e3 rad/s: ~1e-24 x 1e19 m/s^6) and the rounding error (~1e-11 m/s of the
// velocities, through the closest points' iteration tolerances, over eps) ~1e-5 m/s^2; the
// drifts are ~1e1..1e4 m/s^2, so they must agree to ~1e-6 relative (of the drift, or of the
// centripetal terms where those cancel).

// (dg_N/dt, dg_T/dt) of `pair` at time dt along the motion.
Vec2 rowVelocities(const Model& m, const Motion& mo, double alpha, const PairId& pair, double dt,
                   ContactGeom* g_out = nullptr) {
  const VecX zz = mo.z + dt * mo.u;
  Workspace ws;
  Drive dr;
  dr.theta_rad = mo.theta + dt * mo.omega + 0.5 * alpha * dt * dt;
  dr.omega_radps = mo.omega + alpha * dt;
  dr.alpha_radps2 = alpha;
  internal::updateStations(m, zz, dr.theta_rad, &ws);
  ContactGeom g;
  internal::evaluateContact(m, zz, mo.u, dr, pair, &ws, &g);
  if (g_out) *g_out = g;
  return Vec2(g.vn, g.vt);
}

// Checks the analytic drift against the central difference; returns the relative error.
double checkDrift(const Model& m, const Motion& mo, double alpha, const PairId& pair,
                  const std::string& what) {
  Workspace ws;
  Drive dr;
  dr.theta_rad = mo.theta;
  dr.omega_radps = mo.omega;
  dr.alpha_radps2 = alpha;
  internal::updateStations(m, mo.z, dr.theta_rad, &ws);
  ContactGeom g;
  internal::evaluateContact(m, mo.z, mo.u, dr, pair, &ws, &g);
  EXPECT_FALSE(g.far) << what;
  const Vec2 drift = internal::contactVelocityDrift(m, mo.z, mo.u, dr, g, &ws);
  // Central differences over eps and 2 eps, Richardson-extrapolated (error ~eps^4).
  auto central = [&](double eps) {
    return Vec2((rowVelocities(m, mo, alpha, pair, eps) - rowVelocities(m, mo, alpha, pair, -eps)) /
                (2 * eps));
  };
  const double eps = 1e-6;
  const Vec2 fd = (4.0 * central(eps) - central(2 * eps)) / 3.0;
  // Relative to the drift, or where the terms cancel to the size of the centripetal terms
  // (the largest spin squared times a kernel's 5 mm half-length).
  double spin = std::abs(mo.omega);
  for (const KernelModel& k : m.kernels) spin = std::max(spin, std::abs(mo.u[k.dof_offset + 2]));
  const double scale = std::max(fd.norm(), spin * spin * 5e-3);
  const double rel = (drift - fd).norm() / scale;
  EXPECT_LT(rel, 2e-6) << what << ": analytic (" << drift.transpose() << "), central difference ("
                       << fd.transpose() << "), gap " << g.gap_m << ", x* " << g.tooth_x_m;
  return rel;
}

// toothKernelMotion for a tooth of any mode count (a rigid one has no modal state).
Motion toothKernelDriftMotion(const Model& m, double x_c, double tilt_rad) {
  if (m.teeth[0].n_modes == 4) return toothKernelMotion(m, x_c, tilt_rad);
  Motion mo;
  mo.z = VecX::Zero(m.n_dof);
  mo.u = VecX::Zero(m.n_dof);
  mo.theta = 0.03;
  mo.omega = 83.78;
  const int o = m.kernels[0].dof_offset;
  mo.z.segment<2>(o) = rot(mo.theta, Vec2(0.2 + x_c, 0.005 + 1.3e-3 + 1.5e-4));
  mo.z[o + 2] = mo.theta + tilt_rad;
  return mo;
}

TEST(ContactDrift, ToothKernelMatchesCentralDifferences) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  double worst = 0;
  for (int n_modes : {4, 0}) {
    const Model m = contactModel(n_modes);
    const PairId pair{PairKind::kToothKernel, 0, 0};
    const ToothModel& tm = m.teeth[0];
    for (int trial = 0; trial < 12; ++trial) {
      // Along the tooth's side (12 of them between 5 and 55 mm), penetrating or apart.
      const double x_c = 0.03 + 0.025 * uni(rng);
      Motion mo = toothKernelDriftMotion(m, x_c, 0.6 * uni(rng));
      if (n_modes > 0) {
        const VecX q = (VecX(4) << 5e-5, -1e-5, 4e-6, -2e-6).finished();
        mo.z.segment(tm.dof_offset, 4) = q * (1.0 + uni(rng));
        for (int i = 0; i < 4; ++i) mo.u[tm.dof_offset + i] = 0.1 * uni(rng) / (i + 1);
      }
      const int o = m.kernels[0].dof_offset;
      mo.u.segment<3>(o) << 5.0 * uni(rng), 5.0 * uni(rng), 500.0 * uni(rng);
      mo.omega = 83.78 * (1.0 + 0.5 * uni(rng));
      placeAtGap(m, &mo, pair, 0, 1e-4 * uni(rng));
      const double alpha = 200.0 * uni(rng);
      worst = std::max(worst, checkDrift(m, mo, alpha, pair,
                                         "modes " + std::to_string(n_modes) + " trial " +
                                             std::to_string(trial) + " x_c " + fmt(x_c)));
    }
    // Beyond the tip: the closest point stays at x = L (the round end).
    Motion mo = toothKernelDriftMotion(m, 0.055, 1.2);
    const int o = m.kernels[0].dof_offset;
    mo.z.segment<2>(o) = rot(mo.theta, Vec2(0.2 + 0.06 + 0.005 + 1.0e-3, 0.003));
    placeAtGap(m, &mo, pair, 0, 5e-5);
    ContactGeom g;
    rowVelocities(m, mo, 50.0, pair, 0.0, &g);
    EXPECT_EQ(g.tooth_x_m, tm.length_m);
    worst = std::max(worst, checkDrift(m, mo, 50.0, pair, "tip, modes " + std::to_string(n_modes)));
  }
  RecordProperty("worst_relative_error", fmt(worst));
}

TEST(ContactDrift, KernelPairsMatchCentralDifferences) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  Model m = contactModel(0);
  m.obstacles.push_back(testutil::planeObstacle(Vec2(0.0, -0.5), Vec2(0.3, 1.0)));
  ObstacleModel plate;
  plate.type = ObstacleType::kSegment;
  plate.point_m = Vec2(-0.02, -0.45);
  plate.point_b_m = Vec2(0.02, -0.44);
  plate.radius_m = 1e-3;
  m.obstacles.push_back(plate);
  compileModel(&m);
  double worst = 0;
  for (int trial = 0; trial < 8; ++trial) {
    const std::string tag = " trial " + std::to_string(trial);
    // Kernel 1 against kernel 0, at random relative poses, apart or overlapping.
    Motion mo;
    mo.z = VecX::Zero(m.n_dof);
    mo.u = VecX::Zero(m.n_dof);
    mo.theta = 0.0;
    mo.omega = 83.78;
    const int o0 = m.kernels[0].dof_offset, o1 = m.kernels[1].dof_offset;
    const double dir = 3.14159 * uni(rng);
    mo.z.segment<3>(o0) << 0.0, 0.3, 3.0 * uni(rng);
    mo.u.segment<3>(o0) << 2 * uni(rng), 2 * uni(rng), 400 * uni(rng);
    mo.z.segment<3>(o1) << 0.006 * std::cos(dir), 0.3 + 0.006 * std::sin(dir), 3.0 * uni(rng);
    mo.u.segment<3>(o1) << 2 * uni(rng), 2 * uni(rng), 400 * uni(rng);
    const PairId kk{PairKind::kKernelKernel, 0, 1};
    placeAtGap(m, &mo, kk, 1, 2e-4 * uni(rng));
    worst = std::max(worst, checkDrift(m, mo, 0.0, kk, "kernel-kernel" + tag));
    // Kernel 1 on the tilted plane (obstacle 2), on the bar (obstacle 1), on the plate (3).
    const struct {
      int obstacle;
      Vec2 near;
    } cases[] = {{2, Vec2(0.0, -0.5)}, {1, Vec2(0.0, -0.28)}, {3, Vec2(0.01 * uni(rng), -0.445)}};
    for (const auto& c : cases) {
      const Vec2 off(std::cos(dir), std::sin(dir));
      mo.z.segment<2>(o1) = c.near + 0.008 * (c.obstacle == 2 ? Vec2(0.3, 1.0).normalized() : off);
      const PairId ko{PairKind::kKernelObstacle, 1, c.obstacle};
      placeAtGap(m, &mo, ko, 1, 2e-4 * uni(rng));
      worst = std::max(worst,
                       checkDrift(m, mo, 0.0, ko, "obstacle " + std::to_string(c.obstacle) + tag));
    }
  }
  RecordProperty("worst_relative_error", fmt(worst));
}

}  // namespace
// ---------------------------------------------------------------------------------------------
// The contact phase's warm narrow phase (evaluateWarmToothKernel) against the full one.
//
// The tooth deflected and vibrating, the kernel pressed 50 um into it, then everything moved on
// by dt along the motion (the kernel spinning at 300 rad/s, the drum at 800 rpm): the warm path
// started from the closest point before the move must give what the full path (polyline search
// and secant refinement) gives after it. Both converge on the same root of the same condition
// (to 1e-13 L and 1e-15 L): the gap, being stationary there, agrees to rounding; the point, the
// normal and the Jacobians to ~1e-12 relative; w_r also carries the mode table's phi''
// (~1e-12 of the exact one that the full path evaluates).

// The warm path at (z, u, theta) from warm_x_m; false if its guard refused.
bool evaluateWarm(const Model& m, const Motion& mo, const PairId& pair, double warm_x_m,
                  ContactGeom* g, bool apart_ok = false) {
  Drive dr;
  dr.theta_rad = mo.theta;
  dr.omega_radps = mo.omega;
  internal::ToothFrame frame;
  frame.update(m, pair.a, mo.theta);
  return internal::evaluateWarmToothKernel(m, mo.z, mo.u, dr, pair, frame, warm_x_m, g, apart_ok);
}

// Largest relative difference of two Jacobian rows, on the scale of the larger row [-].
double rowDifference(const internal::SmallVec& a, const internal::SmallVec& b) {
  EXPECT_EQ(a.size(), b.size());
  double diff = 0.0, scale = 1e-300;
  for (int i = 0; i < a.size() && i < b.size(); ++i) {
    diff = std::max(diff, std::abs(a[i] - b[i]));
    scale = std::max({scale, std::abs(a[i]), std::abs(b[i])});
  }
  return diff / scale;
}

void expectWarmMatchesFull(const ContactGeom& w, const ContactGeom& f, const std::string& at) {
  constexpr double kRel = 1e-11;  // Jacobians, velocities, residual (seen: 5e-14) [-]
  EXPECT_FALSE(w.far) << at;
  EXPECT_NEAR(w.gap_m, f.gap_m, 1e-17) << at;          // seen: 2e-18 m
  EXPECT_NEAR(w.tooth_x_m, f.tooth_x_m, 1e-14) << at;  // seen: 9e-16 m
  EXPECT_NEAR((w.n - f.n).norm(), 0.0, 1e-12) << at;
  EXPECT_NEAR((w.t - f.t).norm(), 0.0, 1e-12) << at;
  EXPECT_NEAR((w.p0 - f.p0).norm(), 0.0, 1e-15) << at;
  EXPECT_NEAR((w.p1 - f.p1).norm(), 0.0, 1e-15) << at;
  for (int k = 0; k < 2; ++k) {
    EXPECT_EQ(w.side[k].body, f.side[k].body) << at;
    EXPECT_LT(rowDifference(w.side[k].w_n, f.side[k].w_n), kRel) << at << " side " << k;
    EXPECT_LT(rowDifference(w.side[k].w_t, f.side[k].w_t), kRel) << at << " side " << k;
    EXPECT_LT(rowDifference(w.side[k].w_r, f.side[k].w_r), kRel) << at << " side " << k;
  }
  // Velocities relative to the relative speed, the rheonomic terms to Omega |p0| (either
  // component can be a small difference of large terms).
  const double speed = std::hypot(f.vn, f.vt), drum = std::hypot(f.wtilde_n, f.wtilde_t);
  EXPECT_NEAR(w.vn, f.vn, kRel * speed) << at;
  EXPECT_NEAR(w.vt, f.vt, kRel * speed) << at;
  EXPECT_NEAR(w.wtilde_n, f.wtilde_n, kRel * drum) << at;
  EXPECT_NEAR(w.wtilde_t, f.wtilde_t, kRel * drum) << at;
  EXPECT_NEAR(w.residual_mpN, f.residual_mpN, kRel * f.residual_mpN) << at;
  EXPECT_NEAR(w.residual_dtheta_mpNprad, f.residual_dtheta_mpNprad,
              kRel * std::abs(f.residual_dtheta_mpNprad) + 1e-30)
      << at;
  EXPECT_NEAR(w.rho1_m, f.rho1_m, kRel * f.rho1_m) << at;
  EXPECT_NEAR(w.hertz_K, f.hertz_K, kRel * f.hertz_K) << at;
}

TEST(WarmNarrowPhase, MatchesTheFullPathOnADeformedToothAndAMovedKernel) {
  const Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  // Mid-interval, at a station, near the tip (tilted back: on the tip's end, x = L); the kernel
  // tilted both ways.
  for (double x_c : {0.0200, 0.0375, 0.0560}) {
    for (double tilt_rad : {0.1, -0.3}) {
      Motion mo = toothKernelMotion(m, x_c, tilt_rad);
      placeAtGap(m, &mo, pair, 0, -5e-5);
      const ContactGeom before = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
      ASSERT_LT(before.gap_m, 0.0);
      const double dt = 1e-6;  // a contact-phase step [s]
      mo.z += dt * mo.u;
      mo.theta += dt * mo.omega;
      const ContactGeom full = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
      ContactGeom warm;
      const std::string at = "x_c = " + fmt(x_c) + ", tilt = " + fmt(tilt_rad);
      ASSERT_TRUE(evaluateWarm(m, mo, pair, before.tooth_x_m, &warm)) << at;
      if (before.tooth_x_m < m.teeth[0].length_m) {  // the point moved (or stays at the tip)
        EXPECT_GT(std::abs(full.tooth_x_m - before.tooth_x_m), 1e-9) << at;
      }
      expectWarmMatchesFull(warm, full, at);
      RecordProperty("x_move_m_" + fmt(x_c) + "_" + fmt(tilt_rad),
                     fmt(full.tooth_x_m - before.tooth_x_m));
    }
  }
}

// A warm start as far off as the closest point's move over a few steps still converges.
TEST(WarmNarrowPhase, ConvergesFromAWarmStartAFewMicrometresOff) {
  const Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  Motion mo = toothKernelMotion(m, 0.033, 0.2);
  placeAtGap(m, &mo, pair, 0, -5e-5);
  const ContactGeom full = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
  for (double off_m : {-5e-6, 2e-6, 5e-6}) {
    ContactGeom warm;
    ASSERT_TRUE(evaluateWarm(m, mo, pair, full.tooth_x_m + off_m, &warm)) << off_m;
    expectWarmMatchesFull(warm, full, "off = " + fmt(off_m));
  }
}

// The guard: a warm start more than a quarter station interval from the closest point, a
// separated pair (the warm point says the bodies are apart: the polyline search decides), no
// warm start, and a rigid tooth all leave the pair to the full path.
TEST(WarmNarrowPhase, FallsBackToTheFullPathWhenTheWarmStartIsDoubtful) {
  const Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  Motion mo = toothKernelMotion(m, 0.033, 0.1);
  placeAtGap(m, &mo, pair, 0, -5e-5);
  const ContactGeom full = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
  ContactGeom warm;
  const double interval_m = m.teeth[0].length_m / (m.teeth[0].n_stations - 1);
  EXPECT_FALSE(evaluateWarm(m, mo, pair, full.tooth_x_m - 0.5 * interval_m, &warm));
  EXPECT_FALSE(evaluateWarm(m, mo, pair, 0.2 * m.teeth[0].length_m, &warm));
  EXPECT_FALSE(evaluateWarm(m, mo, pair, -1.0, &warm));
  Motion apart = mo;
  placeAtGap(m, &apart, pair, 0, 1e-4);
  EXPECT_FALSE(evaluateWarm(m, apart, pair, full.tooth_x_m, &warm));
  const Model rigid = contactModel(0);
  Motion mr;
  mr.z = VecX::Zero(rigid.n_dof);
  mr.u = VecX::Zero(rigid.n_dof);
  mr.z.segment<2>(rigid.kernels[0].dof_offset) = Vec2(0.233, 0.0063);
  mr.theta = 0.0;
  mr.omega = 83.78;
  EXPECT_FALSE(evaluateWarm(rigid, mr, pair, 0.033, &warm));
}

// A separated pair (the contact phase's pairs within reach) takes the warm path where the
// distance has a single minimum over the tooth (the centreline's curvature bound against the
// kernel's): the same exact geometry as the full path, apart by 0.1 to 3 mm, at mid-tooth and at
// the tip, on a tooth deflected 0.2 % of its length at the tip (the strikes: 0.1 %); deflected
// ten times more (2 %: curvature bound 8 /m against the 80 mm the guard spans) or beyond, the
// guard leaves the pair to the full path.
TEST(WarmNarrowPhase, AnswersASeparatedPairWhereTheDistanceHasOneMinimum) {
  const Model m = contactModel(4);
  const PairId pair{PairKind::kToothKernel, 0, 0};
  const int q0 = m.teeth[0].dof_offset;
  for (double x_c : {0.0300, 0.0560}) {
    for (double gap_m : {1e-4, 1e-3, 3e-3}) {
      Motion mo = toothKernelMotion(m, x_c, 0.2);
      mo.z.segment(q0, 4) *= 0.1;
      placeAtGap(m, &mo, pair, 0, gap_m);
      const ContactGeom full = evaluate(m, mo.z, mo.u, mo.theta, mo.omega, pair);
      ASSERT_GT(full.gap_m, 0.0);
      const std::string at = "x_c = " + fmt(x_c) + ", gap = " + fmt(gap_m);
      ContactGeom warm;
      EXPECT_FALSE(evaluateWarm(m, mo, pair, full.tooth_x_m + 2e-6, &warm)) << at;
      ASSERT_TRUE(evaluateWarm(m, mo, pair, full.tooth_x_m + 2e-6, &warm, true)) << at;
      expectWarmMatchesFull(warm, full, at);
    }
  }
  for (double scale : {1.0, 1e3}) {
    Motion bent = toothKernelMotion(m, 0.03, 0.2);
    bent.z.segment(q0, 4) *= scale;
    placeAtGap(m, &bent, pair, 0, 1e-3);
    const ContactGeom full = evaluate(m, bent.z, bent.u, bent.theta, bent.omega, pair);
    ContactGeom warm;
    EXPECT_FALSE(evaluateWarm(m, bent, pair, full.tooth_x_m, &warm, true)) << scale;
  }
}

}  // namespace threshing_sim
