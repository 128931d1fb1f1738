// The continuous feed (core/feed.h, issue 34): the accounting balance at every step boundary of
// a long run, determinism, the fates by geometry, the pool's limits and hostile values.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "sim_test_util.h"
#include "threshing_sim/core/failure.h"
#include "threshing_sim/core/feed.h"

namespace threshing_sim {
namespace {

using testutil::fmt;
using testutil::sameBits;

// The default scene's drum and tooth (event-driven, tolerance 1e-6, global scheme) and a
// floor; the feed's straw mat under the drum, its kernels 5 mm inside the tooth tip circle.
FeedSpec defaultSpec() {
  FeedSpec s;
  s.rate_per_s = 200;
  s.mat_speed_mps = 1.0;
  s.start_s = 0;
  s.seed = 7;
  s.capacity = 114;     // 1.5 x rate x (span + 2 scatter) / speed + 16
  s.inlet_x_m = -0.16;  // arriving kernels clear of the tooth (tip circle 0.26 m)
  s.exit_x_m = 0.16;
  s.base.semi_axis_a_m = 5e-3;
  s.base.semi_axis_b_m = 1.3e-3;
  s.base.youngs_modulus_Pa = 2.8e8;
  s.base.pedicel.stiffness_Npm = 200;
  s.base.pedicel.damping_Nspm = 0.002;
  s.pedicel_length_m = 0.003;
  // Kernel centres at 0.255 m below the axis (5 mm inside the 0.26 m tip circle).
  s.anchor_y_m = -0.255 + s.base.semi_axis_a_m + s.pedicel_length_m;
  s.mat_thickness_m = 0.01;
  s.grate_y_m = -0.27;
  s.bound_radius_m = 0.5;
  return s;
}

Model feedModel(const FeedSpec& spec, IntegratorType type = IntegratorType::kEventDriven) {
  Model m = testutil::defaultSceneModel(type);
  m.kernels.clear();
  m.integrator.islands = false;
  m.integrator.tolerance = 1e-6;
  m.obstacles = {testutil::planeObstacle(Vec2(0, -0.5), Vec2(0, 1))};
  // Every pair compliant, as config/scenes/feed.yaml.
  m.contact[static_cast<int>(PairKind::kKernelKernel)] = {ContactLaw::kCompliant, 0.34, 0.66};
  m.contact[static_cast<int>(PairKind::kKernelObstacle)] = {ContactLaw::kCompliant, 0.47, 0.47};
  addFeedPool(spec, &m);
  compileModel(&m);
  return m;
}

struct FeedRun {
  FeedSpec spec;
  Model model;
  Data data;
  FeedState state;
  long records = 0;             // records drained so far
  double tooth_peak_sum_N = 0;  // the drained records' peak tooth normal forces [N]
  long steps_checked = 0;       // step boundaries at which the balance was checked
  double interval_s = 1e-4;     // feed update interval [s]
  explicit FeedRun(const FeedSpec& s, IntegratorType type = IntegratorType::kEventDriven)
      : spec(s), model(feedModel(s, type)) {
    resetData(model, &data);
    startFeed(spec, model, &data, &state);
  }
};

// Active slots of the pool.
long activeSlots(const FeedRun& r) {
  long n = 0;
  for (int slot = 0; slot < r.state.capacity; ++slot)
    n += r.data.kernel_active[r.state.first_slot + slot];
  return n;
}

// Runs to t_end_s: one step at a time (every step boundary is a feed boundary), the balance
// checked at each; ASSERTs inside.
void runFeed(FeedRun* r, double t_end_s) {
  ASSERT_TRUE(updateFeed(r->spec, &r->model, &r->data, &r->state)) << r->state.error;
  constexpr long kMaxSteps = 50'000'000;
  for (long n = 0; r->data.t_s < t_end_s && n < kMaxSteps; ++n) {
    const double t_next_s = std::min(t_end_s, r->data.t_s + r->interval_s);
    ASSERT_NE(advancePast(r->model, &r->data, t_next_s, t_end_s), StepStatus::kFailed)
        << describe(r->data.stats.failure);
    ASSERT_TRUE(updateFeed(r->spec, &r->model, &r->data, &r->state)) << r->state.error;
    const FeedCounts& c = r->state.counts;
    ASSERT_TRUE(c.balanced()) << "t = " << r->data.t_s << ": fed " << c.fed << ", in drum "
                              << c.in_drum << ", separated " << c.separated << ", detached "
                              << c.carried_detached << ", unthreshed " << c.carried_unthreshed
                              << ", out " << c.out_of_bounds;
    ASSERT_EQ(c.in_drum, activeSlots(*r)) << "t = " << r->data.t_s;
    r->records += static_cast<long>(r->state.retired.size());
    for (const FeedRecord& rec : r->state.retired) r->tooth_peak_sum_N += rec.peak_normal_N;
    r->state.retired.clear();
    ASSERT_EQ(r->records, c.fed - c.in_drum);
    r->data.events.clear();
    ++r->steps_checked;
  }
}

// The kernels fed by t: every arrival start + n / rate <= t.
long arrivalsBy(const FeedSpec& s, double t_s) {
  return static_cast<long>(std::floor((t_s - s.start_s) * s.rate_per_s + 1e-9)) + 1;
}

// A long run, 10 s of simulated time: fed = in drum + separated + carried over (both) + out of
// bounds after every step (each step end is a feed boundary); kernels threshed; every arrival
// fed. Time stepping at dt = 1e-6 s (the event-driven integrator chattered between stick and
// slip on a pair of kernels in a pile at 1.55 s: docs/model.md, "Continuous feed"); about 2 min.
constexpr double kBalanceRun_s = 10.0;

TEST(Feed, BalanceHoldsAfterEveryStepOfALongRun) {
  FeedSpec spec = defaultSpec();
  FeedRun r(spec, IntegratorType::kTimeStepping);
  r.interval_s = r.model.integrator.dt_s;  // one step per advancePast
  const auto start = std::chrono::steady_clock::now();
  runFeed(&r, kBalanceRun_s);
  if (HasFatalFailure()) return;
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const FeedCounts& c = r.state.counts;
  RecordProperty("simulated_s", fmt(r.data.t_s));
  RecordProperty("wall_s", fmt(wall_s));
  RecordProperty("fed", std::to_string(c.fed));
  RecordProperty("boundaries_checked", std::to_string(r.steps_checked));
  std::printf(
      "feed balance run: %.3g s simulated in %.3g s wall, %ld boundaries; fed %ld, in "
      "drum %ld, separated %ld, carried over detached %ld, unthreshed %ld, out of bounds "
      "%ld\n",
      r.data.t_s, wall_s, r.steps_checked, c.fed, c.in_drum, c.separated, c.carried_detached,
      c.carried_unthreshed, c.out_of_bounds);
  EXPECT_EQ(c.fed, arrivalsBy(r.spec, r.data.t_s));
  EXPECT_GT(c.fed - c.in_drum, c.fed / 2);  // most have left
  // The drum threshes: kernels leave off their pedicels, and some pass the grate.
  EXPECT_GT(c.separated + c.carried_detached + c.out_of_bounds, 0);
  EXPECT_GT(r.data.stats.impacts, 0);
}

TEST(Feed, SameSeedSameFeedBitForBit) {
  FeedRun a(defaultSpec()), b(defaultSpec());
  runFeed(&a, 0.15);
  runFeed(&b, 0.15);
  if (HasFatalFailure()) return;
  EXPECT_TRUE(sameBits(a.data.z, b.data.z));
  EXPECT_TRUE(sameBits(a.data.u, b.data.u));
  EXPECT_EQ(a.state.counts.fed, b.state.counts.fed);
  EXPECT_EQ(a.state.counts.separated, b.state.counts.separated);
  // Another seed feeds other kernels.
  FeedSpec other = defaultSpec();
  other.seed = 8;
  FeedRun c(other);
  runFeed(&c, 0.15);
  if (HasFatalFailure()) return;
  EXPECT_FALSE(sameBits(a.data.z, c.data.z));
}

// Kernels hung below the tooth tip circle are never struck: each rides the mat to the exit and
// is carried over unthreshed, after span / speed.
TEST(Feed, UnstruckKernelsAreCarriedOverUnthreshed) {
  FeedSpec s = defaultSpec();
  s.anchor_y_m = -0.275 + s.base.semi_axis_a_m + s.pedicel_length_m;  // centres 15 mm outside
  s.mat_thickness_m = 0.002;
  s.grate_y_m = -0.29;
  s.angle_scatter_rad = 0.05;
  FeedRun r(s);
  runFeed(&r, 0.5);
  if (HasFatalFailure()) return;
  const FeedCounts& c = r.state.counts;
  EXPECT_EQ(c.separated + c.carried_detached + c.out_of_bounds, 0);
  // Arrivals at least (span + scatter) / speed ago have left; later ones are still in.
  const double ride_s = (s.exit_x_m - s.inlet_x_m + s.position_scatter_m) / s.mat_speed_mps;
  EXPECT_GE(c.carried_unthreshed, arrivalsBy(s, 0.5 - ride_s - 1e-3));
  EXPECT_LE(c.carried_unthreshed, arrivalsBy(s, 0.5 - (ride_s - 2 * s.position_scatter_m)));
  // No tooth touched a kernel (the kernels may touch each other as they swing).
  for (int slot = 0; slot < r.state.capacity; ++slot)
    EXPECT_EQ(r.data.stats.kernel_tooth_peaks[r.state.first_slot + slot].normal_force_N, 0.0);
  EXPECT_EQ(r.tooth_peak_sum_N, 0.0);
}

TEST(Feed, FatesFollowTheGeometry) {
  const FeedSpec s = defaultSpec();
  EXPECT_EQ(feedFate(s, Vec2(0.0, -0.25), true), KernelFate::kInDrum);
  EXPECT_EQ(feedFate(s, Vec2(0.0, -0.28), false), KernelFate::kSeparated);
  EXPECT_EQ(feedFate(s, Vec2(0.0, -0.28), true), KernelFate::kSeparated);
  EXPECT_EQ(feedFate(s, Vec2(0.17, -0.25), true), KernelFate::kCarriedUnthreshed);
  EXPECT_EQ(feedFate(s, Vec2(0.17, -0.25), false), KernelFate::kCarriedDetached);
  EXPECT_EQ(feedFate(s, Vec2(0.2, -0.3), false), KernelFate::kOutOfBounds);
  EXPECT_EQ(feedFate(s, Vec2(0.0, 0.6), false), KernelFate::kOutOfBounds);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_EQ(feedFate(s, Vec2(nan, nan), false), KernelFate::kOutOfBounds);
}

TEST(Feed, AFullPoolFailsNamingTheCapacity) {
  FeedSpec s = defaultSpec();
  s.capacity = 5;
  FeedRun r(s);
  ASSERT_TRUE(updateFeed(r.spec, &r.model, &r.data, &r.state));
  bool ok = true;
  for (int n = 0; n < 1000 && ok; ++n) {
    ASSERT_NE(advancePast(r.model, &r.data, r.data.t_s + 1e-4, 1.0), StepStatus::kFailed);
    ok = updateFeed(r.spec, &r.model, &r.data, &r.state);
  }
  ASSERT_FALSE(ok);
  EXPECT_NE(r.state.error.find("feed.capacity 5"), std::string::npos) << r.state.error;
  EXPECT_EQ(r.state.counts.fed, 5);
}

// Parked slots are inert: no force, no motion, no pair, no energy.
TEST(Feed, ParkedSlotsStayPut) {
  FeedSpec s = defaultSpec();
  s.start_s = 1.0;  // nothing arrives
  FeedRun r(s);
  const VecX z0 = r.data.z;
  const double e0 = mechanicalEnergy(r.model, r.data);
  ASSERT_NE(advancePast(r.model, &r.data, 0.01, 0.01), StepStatus::kFailed);
  const int o = r.model.kernels[r.state.first_slot].dof_offset;
  EXPECT_TRUE(
      sameBits(VecX(z0.segment(o, 3 * s.capacity)), VecX(r.data.z.segment(o, 3 * s.capacity))));
  EXPECT_EQ(r.data.contacts.size(), 0u);
  EXPECT_NEAR(e0, mechanicalEnergy(r.model, r.data), 1e-3);  // the tooth's energy only
  EXPECT_LT(std::abs(e0), 10.0);  // no parked kernel's 1 km of height in it
}

// Feed rate commands at step boundaries: 0 stops the feed, a new rate spaces the arrivals
// after the last one; hostile commands are refused naming the value and change nothing; the
// same commands at the same boundaries give the same run bit for bit.
void runWithCommands(FeedRun* r) {
  runFeed(r, 0.1);
  ASSERT_EQ(setFeedRate(0.0, r->data.t_s, &r->spec, &r->state), "");
  runFeed(r, 0.2);
  ASSERT_EQ(setFeedRate(300.0, r->data.t_s, &r->spec, &r->state), "");
  runFeed(r, 0.3);
}

TEST(Feed, RateCommandsAtStepBoundaries) {
  FeedRun r(defaultSpec());
  runFeed(&r, 0.1);
  if (HasFatalFailure()) return;
  const long fed_at_stop = r.state.counts.fed;
  EXPECT_EQ(fed_at_stop, arrivalsBy(r.spec, r.data.t_s));
  const double last_s = r.state.last_arrival_s;
  ASSERT_EQ(setFeedRate(0.0, r.data.t_s, &r.spec, &r.state), "");
  runFeed(&r, 0.2);
  if (HasFatalFailure()) return;
  EXPECT_EQ(r.state.counts.fed, fed_at_stop);  // stopped
  // Hostile commands: refused, naming the value; nothing changes.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double bad : {-1.0, nan, 1e12, std::numeric_limits<double>::infinity(), 1e6}) {
    const std::string why = setFeedRate(bad, r.data.t_s, &r.spec, &r.state);
    char text[32];
    std::snprintf(text, sizeof(text), "%.17g", bad);
    EXPECT_NE(why.find(std::string("feed rate ") + text + " 1/s refused"), std::string::npos)
        << why;
    EXPECT_EQ(r.spec.rate_per_s, 0.0);
  }
  EXPECT_NE(setFeedRate(1e6, 0.2, &r.spec, &r.state).find("feed.capacity"), std::string::npos);
  const double t_cmd_s = r.data.t_s;
  ASSERT_EQ(setFeedRate(300.0, t_cmd_s, &r.spec, &r.state), "");
  EXPECT_GT(last_s + 1.0 / 300.0, 0.0);
  EXPECT_EQ(nextFeedArrival(r.spec, r.state), std::max(t_cmd_s, last_s + 1.0 / 300.0));
  runFeed(&r, 0.3);
  if (HasFatalFailure()) return;
  // 300/s from the command on.
  const long after = r.state.counts.fed - fed_at_stop;
  long due = 0;  // arrivals t_cmd + k / 300 at or before the end, as the feed computes them
  while (t_cmd_s + static_cast<double>(due) / 300.0 <= r.data.t_s) ++due;
  EXPECT_EQ(after, due);
  EXPECT_GE(after, 30);
  EXPECT_TRUE(r.state.counts.balanced());
  // The same commands at the same boundaries: the same run.
  FeedRun a(defaultSpec()), b(defaultSpec());
  runWithCommands(&a);
  runWithCommands(&b);
  if (HasFatalFailure()) return;
  EXPECT_TRUE(sameBits(a.data.z, b.data.z));
  EXPECT_EQ(a.state.counts.fed, r.state.counts.fed);
}

// The node's path (node_feed.cc): updateFeed's two stages, retireFeedKernels then
// placeFeedKernels, give updateFeed's run bit for bit; FeedSeries' rows (simulate --feed-series,
// feed_throughput) add up to the counts and the totals; checkFeedRate is setFeedRate's test.
TEST(Feed, TwoStagesAndTheSeriesAgreeWithUpdateFeed) {
  constexpr double kRun_s = 0.25;  // kernels retire from about 0.16 s on
  FeedRun a(defaultSpec()), b(defaultSpec());
  runFeed(&a, kRun_s);
  if (HasFatalFailure()) return;
  FeedSeries series;
  series.start(b.data, b.state.counts, b.spec.capacity);
  std::vector<FeedIntervalRow> rows;
  ASSERT_TRUE(placeFeedKernels(b.spec, &b.model, &b.data, &b.state));
  long retired = 0;
  double peak_sum_N = 0;
  while (b.data.t_s < kRun_s) {
    const double t_next_s = std::min(kRun_s, b.data.t_s + b.interval_s);
    ASSERT_NE(advancePast(b.model, &b.data, t_next_s, kRun_s), StepStatus::kFailed);
    retireFeedKernels(b.spec, b.model, &b.data, &b.state);
    const bool due = feedKernelDue(b.spec, b.state, b.data.t_s);
    const Model before = b.model;
    ASSERT_TRUE(placeFeedKernels(b.spec, &b.model, &b.data, &b.state));
    // No kernel due: the model is left alone.
    if (!due) {
      EXPECT_EQ(before.kernels.back().mass_kg, b.model.kernels.back().mass_kg);
    }
    for (const FeedRecord& r : b.state.retired) {
      series.add(r, 139.0);
      ++retired;
      peak_sum_N += r.peak_normal_N;
    }
    b.state.retired.clear();
    b.data.events.clear();
    if (std::fmod(b.data.t_s + 1e-12, 0.01) < b.interval_s)
      rows.push_back(series.close(b.data, b.state.counts));
  }
  rows.push_back(series.close(b.data, b.state.counts));
  EXPECT_TRUE(sameBits(a.data.z, b.data.z));
  EXPECT_EQ(a.state.counts.fed, b.state.counts.fed);
  EXPECT_EQ(a.state.counts.separated, b.state.counts.separated);
  ASSERT_GT(retired, 0);
  FeedIntervalRow sum;
  double previous_end_s = 0;
  for (const FeedIntervalRow& r : rows) {
    EXPECT_EQ(r.t_start_s, previous_end_s);
    previous_end_s = r.t_end_s;
    sum.fed += r.fed;
    sum.threshed += r.threshed;
    sum.separated += r.separated;
    sum.carried_detached += r.carried_detached;
    sum.carried_unthreshed += r.carried_unthreshed;
    sum.out_of_bounds += r.out_of_bounds;
    sum.drive_work_J += r.drive_work_J;
    EXPECT_LE(r.peak_force_p50_N, r.peak_force_p90_N);
    EXPECT_LE(r.peak_force_p90_N, r.peak_force_max_N);
  }
  const FeedCounts& c = b.state.counts;
  EXPECT_EQ(sum.fed, c.fed);
  EXPECT_EQ(sum.separated, c.separated);
  EXPECT_EQ(sum.carried_detached, c.carried_detached);
  EXPECT_EQ(sum.carried_unthreshed, c.carried_unthreshed);
  EXPECT_EQ(sum.out_of_bounds, c.out_of_bounds);
  EXPECT_EQ(sum.threshed, series.totals().threshed);
  EXPECT_EQ(rows.back().in_drum, c.in_drum);
  EXPECT_EQ(series.totals().peak_count, retired);
  EXPECT_EQ(series.totals().peak_sum_N, peak_sum_N);
  EXPECT_NEAR(sum.drive_work_J, b.data.stats.drive_work_J, 1e-12);
  // checkFeedRate refuses what setFeedRate refuses, with the same words.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double rate : {-1.0, nan, 1e12, 1e6, 0.0, 300.0}) {
    FeedSpec spec = b.spec;
    FeedState state = b.state;
    EXPECT_EQ(checkFeedRate(rate, b.spec, b.state.capacity),
              setFeedRate(rate, b.data.t_s, &spec, &state));
  }
}

// Hostile values are refused, naming the key and the value.
void expectRefused(const FeedSpec& s, const std::string& key, const std::string& value) {
  Model m;
  try {
    addFeedPool(s, &m);
    ADD_FAILURE() << key << " = " << value << " accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(key), std::string::npos) << what;
    EXPECT_NE(what.find(value), std::string::npos) << what;
  }
}

TEST(Feed, HostileValuesAreRefused) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (double rate : {0.0, -5.0, nan, 1e12}) {
    FeedSpec s = defaultSpec();
    s.rate_per_s = rate;
    char text[32];
    std::snprintf(text, sizeof(text), "%.17g", rate);
    expectRefused(s, "feed.rate", text);
  }
  FeedSpec s = defaultSpec();
  s.mat_speed_mps = 0;
  expectRefused(s, "feed.mat_speed", "0");
  s = defaultSpec();
  s.capacity = 0;
  expectRefused(s, "feed.capacity", "0");
  s = defaultSpec();
  s.exit_x_m = s.inlet_x_m;
  expectRefused(s, "feed.exit", "-0.16");
  // A moving anchor under the island scheme.
  Model m = feedModel(defaultSpec());
  m.integrator.islands = true;
  m.compiled = false;
  EXPECT_THROW(compileModel(&m), std::invalid_argument);
}

}  // namespace
}  // namespace threshing_sim
