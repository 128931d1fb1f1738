// The asynchronous island-local scheduler (src/core/async/): its stages against closed forms and
// brute force, and the whole scheme against the global one (integrator.islands: false) on
// models built in code. Scene-file agreement: test/scene/test_islands_scenes.cc.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "../../src/core/async/async.h"
#include "sim_test_util.h"
#include "threshing_sim/core/simulator.h"

namespace threshing_sim {
namespace {

using internal::AsyncState;
using testutil::kPi;

// --- wake.cc: the swept sector -----------------------------------------------------------------

TEST(Wake, SectorDistanceClosedForms) {
  const double r_in = 0.2, r_out = 0.26;
  // Inside the angular range: radial distance to the annulus (zero inside it).
  EXPECT_DOUBLE_EQ(internal::sectorDistance(Vec2(0.23, 0.0), -0.1, 0.1, r_in, r_out), 0.0);
  EXPECT_NEAR(internal::sectorDistance(Vec2(0.30, 0.0), -0.1, 0.1, r_in, r_out), 0.04, 1e-15);
  EXPECT_NEAR(internal::sectorDistance(Vec2(0.15, 0.0), -0.1, 0.1, r_in, r_out), 0.05, 1e-15);
  // Beyond the range: distance to the nearest bounding segment (here the one at angle 0.1).
  const Vec2 p = 0.23 * Vec2(std::cos(0.1 + 0.05), std::sin(0.1 + 0.05));
  EXPECT_NEAR(internal::sectorDistance(p, -0.1, 0.1, r_in, r_out), 0.23 * std::sin(0.05), 1e-12);
  // Angles wrap: a sector across +-pi.
  EXPECT_DOUBLE_EQ(internal::sectorDistance(Vec2(-0.23, 1e-3), kPi - 0.1, kPi + 0.1, r_in, r_out),
                   0.0);
}

TEST(Wake, SectorDistanceIsTheDistanceToSampledSegments) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.4, 0.4), ang(-4.0, 4.0), span(0.0, 0.5);
  for (int n = 0; n < 500; ++n) {
    const Vec2 p(u(rng), u(rng));
    const double phi0 = ang(rng), phi1 = phi0 + span(rng);
    double best = std::numeric_limits<double>::infinity();
    for (int s = 0; s <= 2000; ++s) {
      const double phi = phi0 + (phi1 - phi0) * s / 2000.0;
      const Vec2 e(std::cos(phi), std::sin(phi));
      const double t = std::clamp(p.dot(e), 0.2, 0.26);
      best = std::min(best, (p - t * e).norm());
    }
    // Sampling the angle at 2000 points leaves at most 0.26 x span / 2000 of slack.
    const double got = internal::sectorDistance(p, phi0, phi1, 0.2, 0.26);
    EXPECT_LE(got, best + 1e-12);
    EXPECT_GE(got, best - 0.26 * (phi1 - phi0) / 2000.0 - 1e-12);
  }
}

// --- calendar.cc: heap and grid -------------------------------------------------------------

AsyncState gridState(int n, double cell_m) {
  AsyncState as;
  as.kernels.assign(n, internal::KernelClock());
  as.cell_m = cell_m;
  as.r_cap_m = 0.5 * cell_m;
  as.cell_key.assign(64, internal::kEmptyCell);
  as.cell_head.assign(64, -1);
  return as;
}

TEST(Calendar, HeapPopsByWakeTimeThenIndex) {
  AsyncState as = gridState(200, 0.01);
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> t(0, 20);
  for (int i = 0; i < 200; ++i) {
    as.kernels[i].wake_s = 1e-3 * t(rng);  // many ties
    internal::heapPush(&as, i);
  }
  for (int i = 0; i < 200; i += 7) internal::heapRemove(&as, i);  // removal from the middle
  double last_t = -1;
  int last_i = -1;
  for (int top = internal::heapTop(as); top >= 0; top = internal::heapTop(as)) {
    const double w = as.kernels[top].wake_s;
    EXPECT_TRUE(w > last_t || (w == last_t && top > last_i));
    EXPECT_NE(top % 7, 0);
    last_t = w;
    last_i = top;
    internal::heapRemove(&as, top);
  }
}

TEST(Calendar, GridQueryFindsEveryCircleMeetingTheBox) {
  const int n = 400;
  AsyncState as = gridState(n, 0.02);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.3, 0.3), r(0.001, 0.01);
  for (int i = 0; i < n; ++i) {
    as.kernels[i].bound_c_W = Vec2(u(rng), u(rng));
    as.kernels[i].bound_r_m = r(rng);
    internal::gridInsert(&as, i);
  }
  for (int i = 0; i < n; i += 5) internal::gridRemove(&as, i);
  for (int q = 0; q < 200; ++q) {
    const Vec2 lo(u(rng), u(rng));
    const Vec2 hi = lo + Vec2(0.05 * std::abs(u(rng)), 0.05 * std::abs(u(rng)));
    internal::gridQuery(&as, lo, hi);
    std::vector<int> found = as.found;
    std::sort(found.begin(), found.end());
    for (int i = 0; i < n; ++i) {
      const internal::KernelClock& k = as.kernels[i];
      const Vec2 nearest = k.bound_c_W.cwiseMax(lo).cwiseMin(hi);
      const bool meets = (nearest - k.bound_c_W).norm() <= k.bound_r_m;
      const bool listed = std::binary_search(found.begin(), found.end(), i);
      if (i % 5 == 0) {
        EXPECT_FALSE(listed);
      } else if (meets) {
        EXPECT_TRUE(listed) << "kernel " << i << " query " << q;
      }
    }
  }
}

// --- body_motion.cc: lone bodies -----------------------------------------------------------

// A lone kernel on its pedicel, far from anything, under both schemes.
Model pedicelModel(IntegratorType type, bool islands) {
  Model m = testutil::bareModel(type);
  KernelModel k = testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.0, 0.0), Vec2(0.0, 0.0), 0.7);
  k.pedicel.present = true;
  k.pedicel.p_WA_W = Vec2(0.0, 0.0) + 8e-3 * Vec2(std::cos(0.7), std::sin(0.7));
  k.pedicel.p_KP_K = Vec2(5e-3, 0.0);
  k.pedicel.stiffness_Npm = 1600.0;
  k.pedicel.damping_Nspm = 0.002;
  k.pedicel.detachment_force_N = 1.6;
  m.kernels.push_back(k);
  m.integrator.islands = islands;
  m.integrator.tolerance = 1e-8;
  compileModel(&m);
  return m;
}

TEST(BodyMotion, PedicelClockAgreesWithTheGlobalIntegrator) {
  Data g, a;
  const Model mg = pedicelModel(IntegratorType::kEventDriven, false);
  const Model ma = pedicelModel(IntegratorType::kEventDriven, true);
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_EQ(advanceTo(mg, &g, 0.05), StepStatus::kOk);
  ASSERT_EQ(advanceTo(ma, &a, 0.05), StepStatus::kOk);
  // Same error control on the same equations: the states agree to the tolerance's scale.
  EXPECT_LT((g.z - a.z).norm(), 1e-9);
  EXPECT_LT((g.u - a.u).norm(), 1e-6);
  EXPECT_GT(a.stats.scheduler.pedicel_steps, 0);
  EXPECT_EQ(a.stats.scheduler.island_steps, 0);  // it never needed an island
}

TEST(BodyMotion, LazySpeedBoundHoldsAlongThePedicelTrajectory) {
  const Model m = pedicelModel(IntegratorType::kEventDriven, false);
  Data d;
  resetData(m, &d);
  AsyncState as;
  as.kernels.assign(1, internal::KernelClock());
  as.kernels[0].motion = internal::KernelMotion::kPedicel;
  const double horizon = 0.02;
  const double bound = internal::lazySpeedBound(m, d, as, 0, horizon);
  for (int s = 1; s <= 200; ++s) {
    ASSERT_EQ(advanceTo(m, &d, horizon * s / 200.0), StepStatus::kOk);
    const double v = internal::kernelSpeedBound(m, d.u, 0);
    EXPECT_LE(v, bound) << "t = " << d.t_s;
  }
}

TEST(BodyMotion, FreeKernelFliesItsParabolaExactly) {
  Model m = testutil::bareModel(IntegratorType::kEventDriven);
  m.kernels.push_back(testutil::makeKernel(5e-3, 1.3e-3, Vec2(0.1, 0.2), Vec2(3.0, 4.0), 0.3));
  m.kernels[0].initial_angular_velocity_radps = 50.0;
  m.integrator.islands = true;
  compileModel(&m);
  Data d;
  resetData(m, &d);
  const double t = 0.037;
  ASSERT_EQ(advanceTo(m, &d, t), StepStatus::kOk);
  const Vec2 c = Vec2(0.1, 0.2) + t * Vec2(3.0, 4.0) + 0.5 * t * t * m.gravity_mps2;
  EXPECT_NEAR((d.z.head<2>() - c).norm(), 0.0, 1e-15);
  EXPECT_NEAR(d.z[2], 0.3 + 50.0 * t, 1e-14);
  EXPECT_EQ(d.stats.scheduler.island_steps, 0);
}

// --- the whole scheme against the global one ---------------------------------------------

class IslandsVsGlobal : public ::testing::TestWithParam<IntegratorType> {};

TEST_P(IslandsVsGlobal, DefaultStrikeAgrees) {
  Model mg = testutil::defaultSceneModel(GetParam());
  mg.integrator.islands = false;
  Model ma = mg;
  ma.integrator.islands = true;
  compileModel(&mg);
  compileModel(&ma);
  Data g, a;
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_NE(advanceTo(mg, &g, mg.duration_s), StepStatus::kFailed);
  ASSERT_NE(advanceTo(ma, &a, ma.duration_s), StepStatus::kFailed);
  EXPECT_EQ(a.stats.impacts, g.stats.impacts);
  ASSERT_EQ(a.events.size(), g.events.size());
  for (size_t e = 0; e < g.events.size(); ++e) {
    EXPECT_TRUE(a.events[e].pair == g.events[e].pair);
    EXPECT_EQ(a.events[e].to, g.events[e].to);
    EXPECT_NEAR(a.events[e].t_s, g.events[e].t_s, 1e-9);
  }
  // The contact is integrated by the same scheme from the same state: agreement to round-off
  // and the step sequence's error (well inside the tolerance).
  const double tol = 1e-8;
  EXPECT_NEAR(a.stats.peak_normal_force_N, g.stats.peak_normal_force_N,
              tol * g.stats.peak_normal_force_N);
  EXPECT_LT((a.u.tail<3>() - g.u.tail<3>()).norm(), tol * g.u.tail<3>().norm());
  // The drive's work: time stepping advances a free tooth by the theta-method, the island
  // scheme exactly, so there the two differ within time stepping's own error (h against h/2).
  double drive_tol_J = 1e-9;
  if (GetParam() == IntegratorType::kTimeStepping) {
    Model mh = mg;
    mh.integrator.dt_s *= 0.5;
    Data h;
    resetData(mh, &h);
    ASSERT_NE(advanceTo(mh, &h, mh.duration_s), StepStatus::kFailed);
    drive_tol_J = std::abs(h.stats.drive_work_J - g.stats.drive_work_J);
  }
  EXPECT_NEAR(a.stats.drive_work_J, g.stats.drive_work_J, drive_tol_J);
  // Lone phases cost no island steps: fewer than the global scheme's.
  EXPECT_LT(a.steps, g.steps);
  EXPECT_GT(a.stats.scheduler.free_advances, 0);
}

TEST_P(IslandsVsGlobal, RerunsAreBitIdentical) {
  Model m = testutil::defaultSceneModel(GetParam());
  m.integrator.islands = true;
  compileModel(&m);
  Data a, b;
  resetData(m, &a);
  resetData(m, &b);
  for (int chunk = 1; chunk <= 10; ++chunk) {
    advanceTo(m, &a, m.duration_s * chunk / 10);
    advanceTo(m, &b, m.duration_s * chunk / 10);
  }
  EXPECT_EQ(0, std::memcmp(a.z.data(), b.z.data(), sizeof(double) * a.z.size()));
  EXPECT_EQ(0, std::memcmp(a.u.data(), b.u.data(), sizeof(double) * a.u.size()));
  EXPECT_EQ(a.stats.peak_normal_force_N, b.stats.peak_normal_force_N);
  // A reset replays the same run bit for bit.
  Data c;
  resetData(m, &c);
  advanceTo(m, &c, m.duration_s);
  resetData(m, &c);
  for (int chunk = 1; chunk <= 10; ++chunk) advanceTo(m, &c, m.duration_s * chunk / 10);
  EXPECT_EQ(0, std::memcmp(a.z.data(), c.z.data(), sizeof(double) * a.z.size()));
}

// The energy account (energy now against energy at the start, the drive's work and what the
// impacts dissipated; the rest is the teeth's modal damping) is the global scheme's.
double energyResidual(const Model& m, const Data& d) {
  double lost = 0.0;
  for (const ContactEvent& e : d.events) lost += e.is_impact ? e.energy_lost_J : 0.0;
  return mechanicalEnergy(m, d) - d.stats.energy_initial_J - d.stats.drive_work_J + lost;
}

TEST(IslandsEnergy, AccountMatchesTheGlobalScheme) {
  Model mg = testutil::defaultSceneModel(IntegratorType::kEventDriven);
  mg.integrator.islands = false;
  Model ma = mg;
  ma.integrator.islands = true;
  compileModel(&mg);
  compileModel(&ma);
  Data g, a;
  resetData(mg, &g);
  resetData(ma, &a);
  ASSERT_NE(advanceTo(mg, &g, mg.duration_s), StepStatus::kFailed);
  ASSERT_NE(advanceTo(ma, &a, ma.duration_s), StepStatus::kFailed);
  EXPECT_NEAR(energyResidual(ma, a), energyResidual(mg, g), 1e-9);
  EXPECT_LE(a.stats.max_energy_gain_at_impact_J, 1e-12);
}

INSTANTIATE_TEST_SUITE_P(BothIntegrators, IslandsVsGlobal,
                         ::testing::Values(IntegratorType::kEventDriven,
                                           IntegratorType::kTimeStepping),
                         [](const ::testing::TestParamInfo<IntegratorType>& info) {
                           return info.param == IntegratorType::kEventDriven
                                      ? std::string("EventDriven")
                                      : std::string("TimeStepping");
                         });

}  // namespace
}  // namespace threshing_sim
