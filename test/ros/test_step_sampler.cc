// Unit tests of StepSampler (no ROS master): strike samples are the integrator's accepted
// steps, and sampling leaves the run as `simulate` has it (issue 24 item 1). And the strike's
// frames drawn from them (StrikeFrames, issue 24 "replays that move").
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/physics_loop.h"
#include "threshing_sim/ros/step_history.h"
#include "threshing_sim/ros/step_sampler.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

constexpr double kPhysicsStep_s = 1e-5;

struct NodeRun {
  Data data;
  std::vector<StrikeRecord> strikes;
  long sampled_steps = 0;
  bool failed = false;
  long samples = 0;       // sample calls [-]
  long samples_back = 0;  // of them earlier than the one before [-]
};

// The node's stepping: boundary by boundary, sampling strikes (or not), no step cut but at
// end_s (~end_time).
NodeRun runNode(const Model& model, double end_s, bool sampling) {
  NodeRun run;
  resetData(model, &run.data);
  StepSampler sampler(model, sampling, 3 * kPhysicsStep_s);
  StrikeRecorder strikes(kPhysicsStep_s);
  double last_sample_s = 0;
  for (long k = 1; k * kPhysicsStep_s < end_s + 1e-12; ++k) {
    const StepStatus s =
        sampler.advance(model, &run.data, k * kPhysicsStep_s, end_s, [&](const Data& d) {
          run.samples_back += d.t_s < last_sample_s ? 1 : 0;
          last_sample_s = d.t_s;
          ++run.samples;
          strikes.sample(d);
        });
    run.data.events.clear();
    if (s == StepStatus::kFailed) {
      run.failed = true;
      break;
    }
  }
  run.strikes = strikes.finished();
  run.sampled_steps = sampler.sampledSteps();
  return run;
}

// `simulate`'s stepping: past targets every interval_s (its 1e-4 s chunks; 1e-6 s near contacts
// with --forces), no step cut but at end_s (its duration).
Data runSimulate(const Model& model, double end_s, double interval_s = 1e-4) {
  Data data;
  resetData(model, &data);
  for (long k = 1; k * interval_s < end_s + 1e-12; ++k)
    advancePast(model, &data, std::min(end_s, k * interval_s), end_s);
  advancePast(model, &data, end_s, end_s);
  return data;
}

// The old rule, every target cutting a step (advanceTo): the steps depend on the targets.
Data runCutting(const Model& model, double end_s, double interval_s) {
  Data data;
  resetData(model, &data);
  for (long k = 1; k * interval_s < end_s + 1e-12; ++k)
    advanceTo(model, &data, std::min(end_s, k * interval_s));
  return data;
}

bool sameState(const Data& a, const Data& b) {
  return a.t_s == b.t_s && a.z == b.z && a.u == b.u && a.theta_rad == b.theta_rad &&
         a.stats.impacts == b.stats.impacts &&
         a.stats.peak_normal_force_N == b.stats.peak_normal_force_N;
}

std::string scene(const char* name) { return std::string(THRESHING_SIM_SOURCE_DIR) + "/" + name; }

// Both schemes: under islands the strike lies inside one scheduling window, and its samples
// are the island's accepted steps (the core's StepObserver).
void expectDefaultStrikeSampledAtAcceptedSteps(bool islands) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  model.integrator.islands = islands;
  NodeRun run = runNode(model, 0.01, true);
  ASSERT_FALSE(run.failed);
  ASSERT_EQ(run.strikes.size(), 1u);
  const StrikeRecord& r = run.strikes.front();
  // 33 us of contact: the integrator accepts about 20 steps (not 3 physics steps).
  std::printf("islands %d: %zu samples, peak %.17g N\n", islands, r.t_s.size(),
              r.peakNormalForce());
  EXPECT_GT(r.t_s.size(), 15u);
  for (size_t i = 1; i < r.t_s.size(); ++i) EXPECT_GT(r.t_s[i], r.t_s[i - 1]);
  EXPECT_NEAR(r.sample_interval_s, (r.t_s.back() - r.t_s.front()) / (r.t_s.size() - 1), 1e-15);
  // The message's peak is the core's located peak, also `simulate`'s.
  const Data reference = runSimulate(model, 0.01);
  EXPECT_NEAR(r.peakNormalForce(), reference.stats.peak_normal_force_N,
              1e-5 * reference.stats.peak_normal_force_N);
  EXPECT_EQ(r.core_peak_normal_force_N, reference.stats.peak_normal_force_N);
  EXPECT_EQ(run.data.stats.impacts, reference.stats.impacts);
  if (islands) {
    // Sampling (the core's observer of the islands' steps) changes nothing: the node's run
    // without it, bit for bit; and its lone kernels, brought to the end (the node leaves them
    // on their own clocks), are `simulate`'s.
    EXPECT_TRUE(sameState(run.data, runNode(model, 0.01, false).data));
    ASSERT_EQ(syncBodies(model, &run.data), StepStatus::kOk);
  }
  EXPECT_TRUE(sameState(run.data, reference));
  if (islands) return;
  // Without sampling, one sample per physics step.
  const NodeRun coarse = runNode(model, 0.01, false);
  ASSERT_EQ(coarse.strikes.size(), 1u);
  EXPECT_LT(coarse.strikes.front().t_s.size(), 6u);
  EXPECT_EQ(coarse.sampled_steps, 0);
}

TEST(StepSampler, DefaultStrikeIsSampledAtAcceptedStepsWithTheCorePeak) {
  expectDefaultStrikeSampledAtAcceptedSteps(false);
}
TEST(StepSampler, DefaultStrikeIsSampledAtIslandStepsWithTheCorePeak) {
  expectDefaultStrikeSampledAtAcceptedSteps(true);
}

// Under islands a tooth-kernel pair is among the contacts only once its island has formed: at
// boundaries 0.2 ms apart the default strike begins and ends inside one advance, between two
// boundaries that do not see it near. The islands' steps are watched there too: the strike still
// has its history, the island's accepted steps, with `simulate`'s peak.
TEST(StepSampler, StrikeInsideOneAdvanceIsSampledUnderIslands) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  model.integrator.islands = true;
  constexpr double kStep_s = 2e-4, kEnd_s = 1e-3;
  Data data;
  resetData(model, &data);
  StepSampler sampler(model, true, 1e-6);
  StrikeRecorder strikes(kStep_s);
  long near_boundaries = 0;
  for (long k = 1; k * kStep_s < kEnd_s + 1e-12; ++k) {
    near_boundaries += StrikeRecorder::strikeNear(data, 1e-6) ? 1 : 0;
    ASSERT_NE(sampler.advance(model, &data, k * kStep_s, kEnd_s,
                              [&](const Data& d) { strikes.sample(d); }),
              StepStatus::kFailed);
  }
  EXPECT_EQ(near_boundaries, 0);  // no boundary saw it coming: it was inside one advance
  ASSERT_EQ(strikes.finished().size(), 1u);
  const StrikeRecord& r = strikes.finished().front();
  std::printf("strike inside one advance: %zu samples\n", r.t_s.size());
  EXPECT_GT(r.t_s.size(), 15u);
  const Data reference = runSimulate(model, kEnd_s);
  EXPECT_EQ(r.core_peak_normal_force_N, reference.stats.peak_normal_force_N);
  EXPECT_EQ(data.stats.impacts, reference.stats.impacts);
}

// The stream scene's first 3 ms (8 strikes, kernels bouncing on the grate), both schemes: the
// node (10 us boundaries, strikes sampled step by step) and `simulate` (1e-4 s chunks, or 1 us
// samples as with --forces) take the same steps, bit for bit. With every target cutting a
// step (the old rule), the 1 us and 100 us runs differ.
void expectStreamAsInSimulate(bool islands) {
  Model model = loadScene(scene("config/scenes/stream.yaml"));
  model.integrator.islands = islands;
  const double end_s = 0.003;
  const NodeRun run = runNode(model, end_s, true);
  ASSERT_FALSE(run.failed);
  // Global scheme: every accepted step near a strike; islands: every scheduling window.
  EXPECT_GT(run.sampled_steps, islands ? 10 : 1000);
  const Data reference = runSimulate(model, end_s);
  const Data fine = runSimulate(model, end_s, 1e-6);
  std::printf("islands %d: node %ld impacts, peak %.17g N; simulate %ld, %.17g N\n", islands,
              run.data.stats.impacts, run.data.stats.peak_normal_force_N, reference.stats.impacts,
              reference.stats.peak_normal_force_N);
  EXPECT_EQ(run.data.stats.impacts, reference.stats.impacts);
  EXPECT_EQ(run.data.stats.peak_normal_force_N, reference.stats.peak_normal_force_N);
  EXPECT_TRUE(sameState(fine, reference));
  // The samples come in time order (islands: the islands of a window are replayed by time).
  std::printf("%ld samples, %ld back in time\n", run.samples, run.samples_back);
  EXPECT_EQ(run.samples_back, 0);
  if (!islands) {
    EXPECT_TRUE(sameState(run.data, reference));
    EXPECT_FALSE(sameState(runCutting(model, end_s, 1e-6), runCutting(model, end_s, 1e-4)));
  }
}

TEST(StepSampler, StreamRunsAsInSimulate) { expectStreamAsInSimulate(false); }
TEST(StepSampler, StreamRunsAsInSimulateUnderIslands) { expectStreamAsInSimulate(true); }

// Under islands the islands of one window are integrated (and reported) one after the other:
// the sampler replays their steps in time order. The stream's first 10 ms have windows with two
// islands near strikes (replayed in report order, 2 samples went back in time).
TEST(StepSampler, StreamSamplesComeInTimeOrderUnderIslands) {
  Model model = loadScene(scene("config/scenes/stream.yaml"));
  model.integrator.islands = true;
  const NodeRun run = runNode(model, 0.01, true);
  ASSERT_FALSE(run.failed);
  std::printf("%ld samples, %ld back in time, %zu strikes\n", run.samples, run.samples_back,
              run.strikes.size());
  EXPECT_GT(run.samples, 10000);
  EXPECT_EQ(run.samples_back, 0);
}

// Time stepping takes whole steps of dt whatever the targets: the node and `simulate` agree bit
// for bit there too (single strike, both schemes).
TEST(StepSampler, TimeSteppingRunsAsInSimulate) {
  for (const bool islands : {false, true}) {
    Model model = loadScene(scene("config/scenes/single_strike.yaml"));
    model.integrator.type = IntegratorType::kTimeStepping;
    model.integrator.islands = islands;
    const double end_s = 0.002;
    const NodeRun run = runNode(model, end_s, true);
    ASSERT_FALSE(run.failed);
    const Data reference = runSimulate(model, end_s);
    EXPECT_GT(reference.stats.impacts, 0);
    EXPECT_EQ(run.data.stats.impacts, reference.stats.impacts) << islands;
    EXPECT_EQ(run.data.stats.peak_normal_force_N, reference.stats.peak_normal_force_N) << islands;
    if (!islands) {
      EXPECT_TRUE(sameState(run.data, reference));
    }
  }
}

TEST(StepSampler, EventDrivenIsSampledStepByStepInBothSchemes) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  EXPECT_TRUE(StepSampler::samplesSteps(model));
  model.integrator.islands = true;
  EXPECT_TRUE(StepSampler::samplesSteps(model));
  model.integrator.islands = false;
  model.integrator.type = IntegratorType::kTimeStepping;
  EXPECT_FALSE(StepSampler::samplesSteps(model));
  EXPECT_FALSE(StepSampler(model, true, 3e-5).enabled());
}

// The default strike's frames, as the node takes them at factor 0: at least 20 inside the
// contact (one per us of its 33 us), on the 1 us grid, within the steps that reached each
// boundary (up to the step end past it, which the boundary's snapshot draws) and increasing; the
// kernel, pushed up by the tooth, never moves back between frames (the interpolant stays between
// the accepted steps); and the run is bit for bit the run without frames.
void expectDefaultStrikeFrames(bool islands) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  model.integrator.islands = islands;
  constexpr double kEnd_s = 1e-3;
  Data data;
  resetData(model, &data);
  StepSampler sampler(model, true, 3 * kPhysicsStep_s);
  StrikeRecorder strikes(kPhysicsStep_s);
  StrikeFrames frames;
  std::vector<FrameState> got;
  std::vector<double> boundary_end_s;  // per frame: the state's time after its boundary
  for (long k = 1; k * kPhysicsStep_s < kEnd_s + 1e-12; ++k) {
    frames.start(data);
    const double t0_s = data.t_s;
    const size_t n0 = got.size();
    const StepStatus s =
        sampler.advance(model, &data, k * kPhysicsStep_s, kEnd_s, [&](const Data& d) {
          strikes.sample(d);
          frames.sample(d, [&](const FrameState& f) { got.push_back(f); });
        });
    ASSERT_NE(s, StepStatus::kFailed);
    for (size_t i = n0; i < got.size(); ++i) {
      EXPECT_GT(got[i].t_s, t0_s);
      EXPECT_LE(got[i].t_s, data.t_s);
    }
    data.events.clear();
  }
  ASSERT_EQ(strikes.finished().size(), 1u);
  const StrikeRecord& r = strikes.finished().front();
  const int o = model.kernels[0].dof_offset;
  long in_contact = 0;
  double last_y_m = -1e9;
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].t_ns % StrikeFrames::kFrame_ns, 0);
    if (i > 0) {
      EXPECT_GT(got[i].t_ns, got[i - 1].t_ns);
    }
    if (got[i].t_s < r.t_s.front() || got[i].t_s > r.t_s.back()) continue;
    ++in_contact;
    EXPECT_GE(got[i].z[o + 1], last_y_m - 1e-12) << "the kernel moved back at " << got[i].t_s;
    last_y_m = got[i].z[o + 1];
  }
  std::printf("%zu frames, %ld within the contact %.3f..%.3f us\n", got.size(), in_contact,
              r.t_s.front() * 1e6, r.t_s.back() * 1e6);
  EXPECT_GE(in_contact, 20);
  EXPECT_LT(got.size(), 60u);  // only around the strike
  const NodeRun plain = runNode(model, kEnd_s, true);
  EXPECT_TRUE(plain.data.z == data.z && plain.data.u == data.u && plain.data.t_s == data.t_s);
}

TEST(StrikeFrames, DefaultStrikeHasAFrameEveryMicrosecond) { expectDefaultStrikeFrames(false); }
TEST(StrikeFrames, DefaultStrikeHasAFrameEveryMicrosecondUnderIslands) {
  expectDefaultStrikeFrames(true);
}

bool toothKernelClosed(const std::vector<ContactInfo>& contacts) {
  return std::any_of(contacts.begin(), contacts.end(), [](const ContactInfo& c) {
    return c.pair.kind == PairKind::kToothKernel && c.state != ContactState::kSeparated;
  });
}

// The live node under islands (StepHistory): at 1 us boundaries (rviz.test's slow motion) the
// default strike lies inside one scheduling window, so the state after the advance is past every
// boundary inside it. Each such boundary's state is the cubic Hermite interpolant between the
// two accepted steps the sampler handed over around it (a step's own end gives that step's state
// exactly), and the boundaries show the strike: the tooth-kernel pair closed at more than 20 of
// them (the window's end, what the node published before, shows it at none).
TEST(StepHistory, BoundariesInsideAWindowAreTheInterpolantUnderIslands) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  model.integrator.islands = true;
  constexpr double kDt_s = 1e-6, kEnd_s = 1e-3;
  Data data;
  resetData(model, &data);
  StepSampler sampler(model, true, 3 * kDt_s);
  StepHistory history;
  std::vector<StepState> seen;  // the states handed over since the advance began
  FrameState f;
  long inside = 0, exact = 0, closed = 0, closed_at_end = 0;
  for (long k = 1; k * kDt_s < kEnd_s + 1e-12; ++k) {
    const double t_b = k * kDt_s;
    if (data.t_s < t_b) {
      ASSERT_EQ(syncBodies(model, &data), StepStatus::kOk);
      history.begin(data);
      seen.assign(1, StepState());
      copyStepState(data, &seen.back());
      ASSERT_NE(sampler.advance(model, &data, t_b, kEnd_s,
                                [&](const Data& d) {
                                  history.add(d);
                                  if (d.t_s < seen.back().t_s) return;
                                  if (d.t_s > seen.back().t_s) seen.emplace_back();
                                  copyStepState(d, &seen.back());
                                }),
                StepStatus::kFailed);
      data.events.clear();
      // A step's own end gives that step's state, bit for bit.
      for (const StepState& s : seen) {
        ASSERT_TRUE(history.stateAt(s.t_s, &f));
        EXPECT_TRUE(f.z == s.z && f.u == s.u && f.theta_rad == s.theta_rad &&
                    f.contacts.size() == s.contacts.size());
        ++exact;
      }
    }
    if (data.t_s <= t_b) continue;
    ASSERT_TRUE(history.stateAt(t_b, &f)) << t_b;
    ++inside;
    closed += toothKernelClosed(f.contacts) ? 1 : 0;
    closed_at_end += toothKernelClosed(data.contacts) ? 1 : 0;
    // The interpolant between the two handed-over states around t_b.
    size_t j = 1;
    while (seen[j].t_s < t_b) ++j;
    const StepState& a = seen[j - 1];
    const StepState& b = seen[j];
    ASSERT_LE(a.t_s, t_b);
    if (b.t_s == t_b) {
      EXPECT_TRUE(f.z == b.z && f.u == b.u);
      continue;
    }
    const double h = b.t_s - a.t_s, x = (t_b - a.t_s) / h;
    const double h00 = 2 * x * x * x - 3 * x * x + 1, h10 = x * x * x - 2 * x * x + x,
                 h01 = 3 * x * x - 2 * x * x * x, h11 = x * x * x - x * x;
    const VecX z = h00 * a.z + h10 * h * a.u + h01 * b.z + h11 * h * b.u;
    const VecX u = (1 - x) * a.u + x * b.u;
    EXPECT_LT((f.z - z).cwiseAbs().maxCoeff(), 1e-12) << t_b;
    EXPECT_LT((f.u - u).cwiseAbs().maxCoeff(), 1e-9) << t_b;
    EXPECT_EQ(f.contacts.size(), (x < 0.5 ? a : b).contacts.size());
  }
  std::printf(
      "%ld boundaries inside windows, %ld exact step ends, contact at %ld (window end: %ld)\n",
      inside, exact, closed, closed_at_end);
  EXPECT_GT(inside, 100);
  EXPECT_GE(closed, 20);
  EXPECT_EQ(closed_at_end, 0);
}

// Full: every other state is dropped (the first kept), and the history still spans its states.
TEST(StepHistory, KeepsAtMostItsCapacity) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  Data data;
  resetData(model, &data);
  StepHistory history;
  history.begin(data);
  const double t_last_s = 1000 * 1e-6;
  for (int i = 1; i <= 1000; ++i) {
    data.t_s = i * 1e-6;
    data.z[0] = i;
    history.add(data);
  }
  EXPECT_LE(history.size(), StepHistory::kCapacity);
  FrameState f;
  ASSERT_TRUE(history.stateAt(0.0, &f));
  ASSERT_TRUE(history.stateAt(t_last_s, &f));
  EXPECT_EQ(f.z[0], 1000);
  EXPECT_FALSE(history.stateAt(1001 * 1e-6, &f));
}

}  // namespace
}  // namespace threshing_sim
