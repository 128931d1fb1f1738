// Cross-checks of the stepping API (simulator.h, src/core/simulator.cc) on the default scene
// (config/default_scene.yaml, built in code by testutil::defaultSceneModel): the two
// integrators agree as dt -> 0; the compliant law converges as tooth modes are added and the
// rigid law does not; a rigid and a spring-steel tooth give the same kernel exit velocity; a
// Hertz impact against the closed form; advanceTo, resetBodiesKeepTime, setDrumTarget and the
// non-finite guard.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "sim_test_util.h"
#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using testutil::fmt;
using testutil::kG;

constexpr IntegratorType kED = IntegratorType::kEventDriven;
constexpr IntegratorType kTS = IntegratorType::kTimeStepping;

// The kernel's velocity at the end of the default scene (0.01 s; it leaves the tooth at
// ~0.32 ms and flies free afterwards, so this is its exit velocity plus g t).
Vec2 exitVelocity(Model m) {
  compileModel(&m);
  Data d;
  resetData(m, &d);
  EXPECT_EQ(advanceTo(m, &d, m.duration_s), StepStatus::kOk);
  EXPECT_EQ(d.stats.impacts, 1) << "the default scene has one strike";
  return testutil::kernelVelocity(m, d, 0);
}

Model edScene(int n_modes, ContactLaw law) {
  Model m = testutil::defaultSceneModel(kED);
  m.integrator.tolerance = 1e-9;
  m.teeth[0].n_modes = n_modes;
  m.contact[static_cast<int>(PairKind::kToothKernel)].law = law;
  return m;
}

// ---------------------------------------------------------------------------------------------
// Event-driven and time stepping agree as dt -> 0.
//
// Reference: event-driven at tolerance 1e-9 (its exit velocity moves by 5e-8 m/s when the
// tolerance goes to 1e-11). Time stepping is first order, so the error must fall about 10x per
// decade of dt. Measured: 0.586, 0.0190, 0.00178 m/s at dt = 1e-5, 1e-6, 1e-7 (observed
// orders 1.49 and 1.03). Asserted: each decade divides the error by at least 5 (order >= 0.7),
// the last pair's order is first order within [0.8, 1.5], and at 1e-7 the two agree to
// 1e-4 of the exit speed (~28 m/s).
TEST(Simulator, EventDrivenAndTimeSteppingAgreeAsDtShrinks) {
  const Vec2 v_ref = exitVelocity(edScene(4, ContactLaw::kCompliant));
  std::vector<double> errors;
  for (double dt : {1e-5, 1e-6, 1e-7}) {
    Model m = testutil::defaultSceneModel(kTS);
    m.integrator.dt_s = dt;
    const Vec2 v = exitVelocity(m);
    errors.push_back((v - v_ref).norm());
    RecordProperty("error_mps_dt" + fmt(dt), fmt(errors.back()));
  }
  EXPECT_LT(errors[1], errors[0] / 5);
  EXPECT_LT(errors[2], errors[1] / 5);
  const double order = std::log10(errors[1] / errors[2]);
  RecordProperty("observed_order", fmt(order));
  EXPECT_GE(order, 0.8);
  EXPECT_LE(order, 1.5);
  EXPECT_LT(errors[2], 1e-4 * v_ref.norm());
  RecordProperty("v_ref_x", fmt(v_ref.x()));
  RecordProperty("v_ref_y", fmt(v_ref.y()));
}

// ---------------------------------------------------------------------------------------------
// Convergence in the number of tooth modes (docs/model.md §9a).
//
// Measured (event-driven, tolerance 1e-9), kernel exit velocity [m/s] for n = 1, 2, 4, 6, 8:
//   compliant: (-2.767, 28.618) (-2.793, 28.418) (-2.722, 28.340) (-2.706, 28.395)
//              (-2.716, 28.399); successive differences 0.201, 0.106, 0.057, 0.011 m/s
//              (each step 2 modes apart shrinks the change ~2x, the last ~5x);
//   rigid:     (-2.919, 28.329) (-2.946, 28.129) (-2.937, 27.942) (-2.792, 27.662)
//              (-2.628, 27.309); successive differences 0.202, 0.188, 0.315, 0.389 m/s:
//              the speed keeps falling (1.0 m/s from n = 1 to 8) as the contact point's
//              effective mass falls, as 9a says.
// Asserted: the compliant differences shrink monotonically and |v(8) - v(6)| < 0.03 m/s
// (1e-3 of the exit speed, well inside the 1 % that 9a calls settled); the rigid law's last
// difference is > 0.1 m/s, more than 10 times the compliant one, and does not shrink.
TEST(Simulator, CompliantLawConvergesWithModesRigidLawDrifts) {
  const int modes[] = {1, 2, 4, 6, 8};
  std::vector<Vec2> compliant, rigid;
  for (int n : modes) {
    compliant.push_back(exitVelocity(edScene(n, ContactLaw::kCompliant)));
    rigid.push_back(exitVelocity(edScene(n, ContactLaw::kRigid)));
    RecordProperty("compliant_vy_n" + std::to_string(n), fmt(compliant.back().y()));
    RecordProperty("rigid_vy_n" + std::to_string(n), fmt(rigid.back().y()));
  }
  std::vector<double> dc, dr;
  for (size_t i = 1; i < compliant.size(); ++i) {
    dc.push_back((compliant[i] - compliant[i - 1]).norm());
    dr.push_back((rigid[i] - rigid[i - 1]).norm());
    RecordProperty("compliant_diff_" + std::to_string(modes[i]), fmt(dc.back()));
    RecordProperty("rigid_diff_" + std::to_string(modes[i]), fmt(dr.back()));
  }
  for (size_t i = 1; i < dc.size(); ++i)
    EXPECT_LT(dc[i], dc[i - 1]) << "compliant, n = " << modes[i + 1];
  EXPECT_LT(dc.back(), 0.03);
  EXPECT_GT(dr.back(), 0.1);
  EXPECT_GT(dr.back(), 10 * dc.back());
  EXPECT_GE(dr.back(), dr[1]) << "the rigid law's change per 2 modes does not shrink";
}

// ---------------------------------------------------------------------------------------------
// Rigid tooth (n = 0) against a spring-steel tooth (E 206 GPa, rho 7850, d 5 mm, 4 modes, the
// same material for both so that the Hertz law is the same).
//
// Bound: during the ~35 us contact the flexible tooth can take at most what an impulse would
// give its contact point: the kernel's velocity change is reduced by M_t / (M_k + M_t), with
// M_t = sum_i phi_i(x)^2 the tooth's mobility at the contact (mass-normalised modes) and
// M_k >= 1/m the kernel's (using 1/m alone, without its rotation, overestimates the ratio).
// M_t is taken as the largest over x in [30, 40] mm around the contact (x ~ 35 mm). For the
// steel tooth this is 1.34e-2 of the exit speed, 0.38 m/s. Measured difference: 0.19 m/s
// (0.67 %): the modes are slow against the contact (first mode 996 Hz, period 1 ms) and absorb
// about half the impulsive bound.
TEST(Simulator, RigidAndSteelToothGiveTheSameExitVelocity) {
  auto steel = [](int n) {
    Model m = edScene(n, ContactLaw::kCompliant);
    ToothModel& t = m.teeth[0];
    t.youngs_modulus_Pa = 206e9;
    t.density_kgpm3 = 7850;
    t.diameter_m = 0.005;
    t.poisson_ratio = 0.3;
    return m;
  };
  const Vec2 v_rigid = exitVelocity(steel(0));
  const Vec2 v_steel = exitVelocity(steel(4));
  Model ms = steel(4);
  compileModel(&ms);
  double ratio = 0;
  for (double x = 0.030; x <= 0.040 + 1e-12; x += 0.001) {
    VecX phi, dphi;
    evaluateModes(ms.teeth[0], x, &phi, &dphi);
    const double M_t = phi.squaredNorm(), M_k = 1.0 / ms.kernels[0].mass_kg;
    ratio = std::max(ratio, M_t / (M_k + M_t));
  }
  const double bound = ratio * v_rigid.norm();
  const double diff = (v_steel - v_rigid).norm();
  RecordProperty("rigid_v", fmt(v_rigid.x()) + ", " + fmt(v_rigid.y()));
  RecordProperty("steel_v", fmt(v_steel.x()) + ", " + fmt(v_steel.y()));
  RecordProperty("difference_mps", fmt(diff));
  RecordProperty("bound_mps", fmt(bound));
  EXPECT_LT(diff, bound);
  // And the steel tooth is much closer to rigid than the nylon tooth is (0.41 m/s measured).
  const Vec2 v_nylon0 = exitVelocity(edScene(0, ContactLaw::kCompliant));
  const Vec2 v_nylon4 = exitVelocity(edScene(4, ContactLaw::kCompliant));
  EXPECT_LT(diff, (v_nylon4 - v_nylon0).norm());
}

// ---------------------------------------------------------------------------------------------
// A Hertz impact against the closed form. A sphere-like kernel (a = b = 1.5 mm) hits a rigid
// wall (plane with E = 1e15 Pa) head on at v, with e = 1 (no damping), mu = 0 and no gravity.
// With K = 4/3 E* sqrt(R):
//   delta_max = (5 m v^2 / (4 K))^{2/5},  F_max = K delta_max^{3/2},
//   t_c = 2 delta_max / v * int_0^1 ds / sqrt(1 - s^{5/2}) = 2.943275 delta_max / v
//       = 3.21805 (m^2 / (K^2 v))^{1/5}.
// (The brief's "t_c = 2.9432 (m^2/(K^2 v))^{1/5}" drops the factor (5/4)^{2/5} = 1.0934;
// 2.9432 goes with delta_max / v. The constant is computed here from Gamma functions: the
// integral is (2/5) B(2/5, 1/2).)
struct HertzClosedForm {
  double K, delta_max, F_max, t_c;
};
HertzClosedForm hertz(double m, double r, double E_k, double nu_k, double E_w, double nu_w,
                      double v) {
  HertzClosedForm h;
  const double E_star = 1.0 / ((1 - nu_k * nu_k) / E_k + (1 - nu_w * nu_w) / E_w);
  h.K = 4.0 / 3.0 * E_star * std::sqrt(r);
  h.delta_max = std::pow(5 * m * v * v / (4 * h.K), 0.4);
  h.F_max = h.K * std::pow(h.delta_max, 1.5);
  const double integral = 0.4 * std::tgamma(0.4) * std::tgamma(0.5) / std::tgamma(0.9);
  h.t_c = 2 * integral * h.delta_max / v;
  return h;
}

Model hertzModel(IntegratorType type, double v) {
  const double r = 1.5e-3;
  Model m = testutil::dropModel(type, ContactLaw::kCompliant, 1.0, 0.0, r, r, 1e-5, Vec2(0, -v));
  m.gravity_mps2 = Vec2::Zero();
  m.obstacles[0].youngs_modulus_Pa = 1e15;
  m.obstacles[0].poisson_ratio = 0.3;
  compileModel(&m);
  return m;
}

// Event-driven: the contact's start and end are events located to ~1e-15 s and the contact
// phase is integrated to tolerance 1e-9, so the duration matches to 1e-6 relative (measured
// 1e-9 once the constant is exact; 2.6e-5 with the rounded 2.9432). The peak force is located
// inside its step (see HertzImpactPeakForceLocatedEventDriven): measured 4.6e-8 low at 2 m/s
// and 3.6e-8 at 20 m/s (1.1e-4 and 6.5e-5 when it was the largest value at step ends); 1e-6
// bounds it. These, not the model, limit the agreement.
TEST(Simulator, HertzImpactMatchesClosedFormEventDriven) {
  for (double v : {2.0, 20.0}) {
    const Model m = hertzModel(kED, v);
    const HertzClosedForm h = hertz(2.8e-5, 1.5e-3, 2.8e8, 0.3, 1e15, 0.3, v);
    Data d;
    testutil::runTo(m, &d, 1e-5 / v + 3 * h.t_c);
    double t_start = -1, t_end = -1, peak = 0, v_out = 0;
    for (const ContactEvent& ev : d.events) {
      if (ev.from == ContactState::kSeparated && t_start < 0) t_start = ev.t_s;
      if (ev.is_impact) {
        t_end = ev.t_s;
        peak = ev.peak_normal_force_N;
        v_out = ev.vn_after_mps;
      }
    }
    ASSERT_GE(t_start, 0.0);
    ASSERT_GT(t_end, t_start);
    EXPECT_NEAR((t_end - t_start) / h.t_c, 1.0, 1e-6) << "v = " << v;
    EXPECT_NEAR(peak / h.F_max, 1.0, 1e-6) << "v = " << v;
    EXPECT_NEAR(d.stats.max_penetration_m / h.delta_max, 1.0, 1e-3) << "v = " << v;
    EXPECT_NEAR(v_out, v, 1e-6 * v);  // e = 1
    RecordProperty("tc_rel_err_v" + fmt(v), fmt((t_end - t_start) / h.t_c - 1));
    RecordProperty("peak_rel_err_v" + fmt(v), fmt(peak / h.F_max - 1));
    RecordProperty("F_max_N_v" + fmt(v), fmt(h.F_max));
    RecordProperty("t_c_s_v" + fmt(v), fmt(h.t_c));
  }
}

// The same impact with the peak located (event_driven/peaks.cc, locateForcePeaks): the force's
// maximum inside a step is found from its rate at the step ends and probed states, so the peak
// follows the tolerance instead of the step grid (~30 steps per contact, which alone give
// 1e-4). With e = 1 the maximum is at half the contact time. Asserted: at tolerance 1e-8 the
// run statistic and the episode's peak match F_max to 1e-6 relative, and the time of the peak
// is mid-contact to 1e-4 of t_c (a flat maximum: its time is known to about sqrt(error)).
TEST(Simulator, HertzImpactPeakForceLocatedEventDriven) {
  for (double v : {2.0, 20.0}) {
    Model m = hertzModel(kED, v);
    m.integrator.tolerance = 1e-8;
    const HertzClosedForm h = hertz(2.8e-5, 1.5e-3, 2.8e8, 0.3, 1e15, 0.3, v);
    Data d;
    testutil::runTo(m, &d, 1e-5 / v + 3 * h.t_c);
    double t_start = -1, peak_episode = 0;
    for (const ContactEvent& ev : d.events) {
      if (ev.from == ContactState::kSeparated && t_start < 0) t_start = ev.t_s;
      if (ev.is_impact) peak_episode = ev.peak_normal_force_N;
    }
    ASSERT_GE(t_start, 0.0);
    EXPECT_NEAR(d.stats.peak_normal_force_N / h.F_max, 1.0, 1e-6) << "v = " << v;
    EXPECT_NEAR(peak_episode / h.F_max, 1.0, 1e-6) << "v = " << v;
    EXPECT_NEAR((d.stats.time_of_peak_normal_s - t_start) / h.t_c, 0.5, 1e-4) << "v = " << v;
    RecordProperty("located_peak_rel_err_v" + fmt(v),
                   fmt(d.stats.peak_normal_force_N / h.F_max - 1));
  }
}

// The default scene's peak forces converge with the tolerance. Reference: tolerance 1e-10 with
// steps of at most 0.1 us (~300 per contact, so even a peak sampled on the step grid would be
// within ~1e-8). Asserted: at tolerance 1e-6 (the scene's) both peaks agree with it to 1e-6
// relative, and at tolerance 1e-8 the normal peak to 2e-8. The tangential peak is reached at
// the located stick -> slip event (mu F_N there). Before the normal peak was located, it was
// the largest value at step ends, ~1e-4 low here at either tolerance.
TEST(Simulator, DefaultScenePeakForcesConvergeWithTolerance) {
  auto peaks = [](double tol, double max_step_s) {
    Model m = testutil::defaultSceneModel(kED);
    m.integrator.tolerance = tol;
    m.integrator.max_step_s = max_step_s;
    compileModel(&m);
    Data d;
    resetData(m, &d);
    EXPECT_EQ(advanceTo(m, &d, 5e-4), StepStatus::kOk);
    return Vec2(d.stats.peak_normal_force_N, d.stats.peak_tangential_force_N);
  };
  const double max_step_s = Model().integrator.max_step_s;
  const Vec2 ref = peaks(1e-10, 1e-7), p6 = peaks(1e-6, max_step_s), p8 = peaks(1e-8, max_step_s);
  EXPECT_NEAR(p6[0] / ref[0], 1.0, 1e-6);
  EXPECT_NEAR(p6[1] / ref[1], 1.0, 1e-6);
  EXPECT_NEAR(p8[0] / ref[0], 1.0, 2e-8);
  RecordProperty("normal_rel_diff_tol1e-6", fmt(p6[0] / ref[0] - 1));
  RecordProperty("tangential_rel_diff_tol1e-6", fmt(p6[1] / ref[1] - 1));
  RecordProperty("normal_rel_diff_tol1e-8", fmt(p8[0] / ref[0] - 1));
}

// Time stepping at h = 1e-8 s (3500-5600 steps per contact): the force is the Hertz force at
// each step's midpoint, so its peak is sampled within (h / t_c)^2 ~ 1e-8; the duration counts
// the steps with a positive force, known to +-1 step each end: 2 h / t_c <= 6e-4.
TEST(Simulator, HertzImpactMatchesClosedFormTimeStepping) {
  for (double v : {2.0, 20.0}) {
    Model m = hertzModel(kTS, v);
    m.integrator.dt_s = 1e-8;
    compileModel(&m);
    const HertzClosedForm h = hertz(2.8e-5, 1.5e-3, 2.8e8, 0.3, 1e15, 0.3, v);
    Data d;
    resetData(m, &d);
    double peak = 0;
    long steps_in_contact = 0;
    while (d.t_s < 1e-5 / v + 2 * h.t_c) {
      ASSERT_NE(step(m, &d), StepStatus::kFailed);
      for (const ContactInfo& c : d.contacts) {
        if (c.normal_force_N > 0) {
          ++steps_in_contact;
          peak = std::max(peak, c.normal_force_N);
        }
      }
    }
    const double duration = steps_in_contact * m.integrator.dt_s;
    EXPECT_NEAR(duration / h.t_c, 1.0, 2 * m.integrator.dt_s / h.t_c) << "v = " << v;
    EXPECT_NEAR(peak / h.F_max, 1.0, 1e-6) << "v = " << v;
    EXPECT_NEAR(d.u[1], v, 1e-4 * v);
  }
}

// ---------------------------------------------------------------------------------------------
// advanceTo, resetBodiesKeepTime, setDrumTarget.

// Event-driven: advanceTo stops exactly on t_end (the last step is cut to it), whatever the
// decimal and even inside the contact (0.3 ms is mid-strike). Time stepping: whole steps, the
// last within dt/2 of t_end.
TEST(Simulator, AdvanceToLandsOnTEnd) {
  Model m = testutil::defaultSceneModel(kED);
  compileModel(&m);
  Data d;
  resetData(m, &d);
  for (double t : {1e-4, 0.0003, 0.00031, 0.0007, 0.001, 0.0013, 0.002}) {
    ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
    EXPECT_EQ(d.t_s, t);
  }
  Model mt = testutil::defaultSceneModel(kTS);
  mt.integrator.dt_s = 3e-6;
  compileModel(&mt);
  resetData(mt, &d);
  for (double t : {1e-4, 0.0003, 0.00031, 0.0007, 0.001}) {
    ASSERT_EQ(advanceTo(mt, &d, t), StepStatus::kOk);
    EXPECT_LE(std::abs(d.t_s - t), 0.5 * mt.integrator.dt_s + 1e-15);
  }
}

// advancePast cuts no step at its target, only at the stop time: the default scene advanced
// past targets 1 us apart and past targets 0.1 ms apart ends in the same state, bit for bit,
// under both schemes (advanceTo, which cuts a step at each target, does not); each call ends at
// a step end at or past its target (less than a max_step later), the last exactly on the stop
// time; a NaN stop time is a bad target.
TEST(Simulator, AdvancePastTakesTheSameStepsWhateverTheTargets) {
  for (const bool islands : {false, true}) {
    Model m = testutil::defaultSceneModel(kED);
    m.integrator.islands = islands;
    compileModel(&m);
    const double stop_s = 0.002;
    auto run = [&](double interval_s, bool past) {
      Data d;
      resetData(m, &d);
      for (long k = 1; k * interval_s < stop_s + 1e-12; ++k) {
        const double t = std::min(stop_s, k * interval_s);
        EXPECT_EQ(past ? advancePast(m, &d, t, stop_s) : advanceTo(m, &d, t), StepStatus::kOk);
        EXPECT_GE(d.t_s, t);
        EXPECT_LT(d.t_s, t + m.integrator.max_step_s);
      }
      if (past) {
        EXPECT_EQ(advancePast(m, &d, stop_s, stop_s), StepStatus::kOk);
      }
      EXPECT_EQ(d.t_s, stop_s);
      return d;
    };
    const Data fine = run(1e-6, true), coarse = run(1e-4, true);
    EXPECT_TRUE(fine.z == coarse.z && fine.u == coarse.u && fine.theta_rad == coarse.theta_rad)
        << "islands " << islands;
    EXPECT_EQ(fine.stats.peak_normal_force_N, coarse.stats.peak_normal_force_N);
    EXPECT_GT(fine.stats.impacts, 0);
    if (!islands) {
      const Data fine_cut = run(1e-6, false), coarse_cut = run(1e-4, false);
      EXPECT_FALSE(fine_cut.z == coarse_cut.z && fine_cut.u == coarse_cut.u);
    }
    Data d;
    resetData(m, &d);
    EXPECT_EQ(advancePast(m, &d, 1e-4, std::numeric_limits<double>::quiet_NaN()),
              StepStatus::kFailed);
    EXPECT_EQ(d.stats.failure.cause, FailureCause::kBadTarget);
  }
}

// After the strike, the bodies go back to the scene's start while time and the drum go on:
// t and theta are kept; the kernel is back at its initial pose, still, and then falls freely
// from there (the tooth has passed it: at t = 1 ms the drum has turned 0.084 rad, the kernel
// sits at 0.051 rad), so 1 ms later it is g t^2 / 2 lower (1e-12: DOPRI5 is exact on it).
TEST(Simulator, ResetBodiesKeepTimeKeepsTimeAndDrum) {
  Model m = testutil::defaultSceneModel(kED);
  m.integrator.tolerance = 1e-9;
  compileModel(&m);
  Data d;
  testutil::runTo(m, &d, 0.001);
  ASSERT_EQ(d.stats.impacts, 1);
  const double t = d.t_s, theta = d.theta_rad, omega = d.omega_radps;
  resetBodiesKeepTime(m, &d);
  EXPECT_EQ(d.t_s, t);
  EXPECT_EQ(d.theta_rad, theta);
  EXPECT_EQ(d.omega_radps, omega);
  const KernelModel& k = m.kernels[0];
  EXPECT_EQ(kernelPosition(m, d, 0), k.initial_position_m);
  EXPECT_EQ(testutil::kernelVelocity(m, d, 0), k.initial_velocity_mps);
  EXPECT_EQ(d.z.head(m.teeth[0].n_modes).norm(), 0.0);
  EXPECT_EQ(d.stats.drive_work_J, 0.0);
  EXPECT_NEAR(d.stats.energy_initial_J, mechanicalEnergy(m, d), 1e-15);
  ASSERT_EQ(advanceTo(m, &d, 0.002), StepStatus::kOk);
  EXPECT_NEAR(d.theta_rad, theta + omega * 0.001, 1e-12);
  const Vec2 c = kernelPosition(m, d, 0);
  EXPECT_NEAR(c.x(), k.initial_position_m.x(), 1e-12);
  EXPECT_NEAR(c.y(), k.initial_position_m.y() - 0.5 * kG * 1e-6, 1e-12);
  EXPECT_EQ(d.stats.impacts, 1);  // no second strike
}

// setDrumTarget: the drum reaches the target at exactly max_acceleration (200 rad/s^2), then
// holds it. From 83.78 to 100 rad/s takes 81.1 ms. Omega and theta follow the closed form of a
// piecewise-constant acceleration; the drive is prescribed (analytic in both integrators), so
// 1e-9 rad/s and 1e-9 rad cover rounding only. Spinning down to 0 likewise.
TEST(Simulator, SetDrumTargetRampsAtMaxAcceleration) {
  for (IntegratorType type : {kED, kTS}) {
    Model m = testutil::bareModel(type);
    m.drum.initial_speed_radps = 83.78;
    m.drum.max_acceleration_radps2 = 200.0;
    m.teeth = {testutil::nylonTooth(2)};
    m.integrator.dt_s = 1e-5;
    compileModel(&m);
    Data d;
    resetData(m, &d);
    const double w0 = 83.78, a = 200.0, w1 = 100.0;
    setDrumTarget(m, &d, w1);
    ASSERT_NE(advanceTo(m, &d, 0.05), StepStatus::kFailed);
    EXPECT_NEAR(d.omega_radps, w0 + a * d.t_s, 1e-9);
    EXPECT_NEAR(d.theta_rad, w0 * d.t_s + 0.5 * a * d.t_s * d.t_s, 1e-9);
    EXPECT_EQ(d.alpha_radps2, a);
    ASSERT_NE(advanceTo(m, &d, 0.10), StepStatus::kFailed);
    const double t_r = (w1 - w0) / a;
    EXPECT_NEAR(d.omega_radps, w1, 1e-9);
    EXPECT_NEAR(d.theta_rad, w0 * t_r + 0.5 * a * t_r * t_r + w1 * (d.t_s - t_r), 1e-9);
    EXPECT_EQ(d.alpha_radps2, 0.0);
    // Spin down to rest: 0.5 s at -200 rad/s^2.
    setDrumTarget(m, &d, 0.0);
    const double t0 = d.t_s;
    ASSERT_NE(advanceTo(m, &d, t0 + 0.2), StepStatus::kFailed);
    EXPECT_NEAR(d.omega_radps, w1 - a * (d.t_s - t0), 1e-9);
    ASSERT_NE(advanceTo(m, &d, t0 + 0.6), StepStatus::kFailed);
    EXPECT_EQ(d.omega_radps, 0.0);
  }
}

// ---------------------------------------------------------------------------------------------
// Non-finite guard. A kernel so small (semi-axes 1e-160 m) that its polar inertia underflows
// to 0 (compileModel accepts it) makes the first step compute 0/0 for its angular acceleration:
// a genuine NaN. advanceTo must report it (kFailed after the recovery attempt) and leave the
// last good state (t = 0, the initial pose), not NaN.
TEST(Simulator, NonFiniteResultIsReportedAndStateKept) {
  for (IntegratorType type : {kED, kTS}) {
    Model m = testutil::bareModel(type);
    m.kernels = {testutil::makeKernel(2e-3, 2e-3, Vec2(0, 0.3), Vec2(1, 0))};
    compileModel(&m);
    // compileModel refuses a zero inertia; corrupt the compiled model to force a NaN.
    m.kernels[0].inertia_kgm2 = 0.0;
    Data d;
    resetData(m, &d);
    const StepStatus s = advanceTo(m, &d, 1e-4);
    EXPECT_EQ(s, StepStatus::kFailed) << "type " << static_cast<int>(type);
    EXPECT_EQ(d.stats.failure.cause, FailureCause::kNonFinite) << describe(d.stats.failure);
    EXPECT_EQ(d.t_s, 0.0);
    EXPECT_TRUE(d.z.allFinite());
    EXPECT_TRUE(d.u.allFinite());
    EXPECT_EQ(d.z[1], 0.3);
    EXPECT_GE(d.stats.numerical_recoveries, 1);
  }
}

}  // namespace
}  // namespace threshing_sim
