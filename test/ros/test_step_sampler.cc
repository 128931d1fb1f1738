// Unit tests of StepSampler (no ROS master): strike samples are the integrator's accepted
// steps, and sampling leaves the run as `simulate` has it (issue 24 item 1). And the strike's
// frames drawn from them (StrikeFrames, issue 24 "replays that move").
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/physics_loop.h"
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
};

// The node's stepping: boundary by boundary, sampling strikes (or not).
NodeRun runNode(const Model& model, double end_s, bool sampling) {
  NodeRun run;
  resetData(model, &run.data);
  StepSampler sampler(model, sampling, 3 * kPhysicsStep_s);
  StrikeRecorder strikes(kPhysicsStep_s);
  for (long k = 1; k * kPhysicsStep_s < end_s + 1e-12; ++k) {
    const StepStatus s = sampler.advance(model, &run.data, k * kPhysicsStep_s,
                                         [&](const Data& d) { strikes.sample(d); });
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

// `simulate`'s stepping without --forces: advanceTo in chunks of 1e-4 s.
Data runSimulate(const Model& model, double end_s) {
  Data data;
  resetData(model, &data);
  for (long k = 1; k * 1e-4 < end_s + 1e-12; ++k) advanceTo(model, &data, k * 1e-4);
  return data;
}

std::string scene(const char* name) { return std::string(THRESHING_SIM_SOURCE_DIR) + "/" + name; }

TEST(StepSampler, DefaultStrikeIsSampledAtAcceptedStepsWithTheCorePeak) {
  const Model model = loadScene(scene("config/default_scene.yaml"));
  const NodeRun run = runNode(model, 0.01, true);
  ASSERT_FALSE(run.failed);
  ASSERT_EQ(run.strikes.size(), 1u);
  const StrikeRecord& r = run.strikes.front();
  // 33 us of contact: the integrator accepts about 20 steps (not 3 physics steps).
  EXPECT_GT(r.t_s.size(), 15u);
  for (size_t i = 1; i < r.t_s.size(); ++i) EXPECT_GT(r.t_s[i], r.t_s[i - 1]);
  EXPECT_NEAR(r.sample_interval_s, (r.t_s.back() - r.t_s.front()) / (r.t_s.size() - 1), 1e-15);
  // The message's peak is the core's located peak, also `simulate`'s.
  const Data reference = runSimulate(model, 0.01);
  EXPECT_NEAR(r.peakNormalForce(), reference.stats.peak_normal_force_N,
              1e-5 * reference.stats.peak_normal_force_N);
  EXPECT_EQ(run.data.stats.impacts, reference.stats.impacts);
  // Without sampling, one sample per physics step.
  const NodeRun coarse = runNode(model, 0.01, false);
  ASSERT_EQ(coarse.strikes.size(), 1u);
  EXPECT_LT(coarse.strikes.front().t_s.size(), 6u);
  EXPECT_EQ(coarse.sampled_steps, 0);
}

TEST(StepSampler, StreamRunsAsInSimulate) {
  const Model model = loadScene(scene("config/scenes/stream.yaml"));
  const NodeRun run = runNode(model, 0.003, true);
  ASSERT_FALSE(run.failed);
  EXPECT_GT(run.sampled_steps, 1000);
  const Data reference = runSimulate(model, 0.003);
  EXPECT_EQ(run.data.stats.impacts, reference.stats.impacts);
  EXPECT_NEAR(run.data.stats.peak_normal_force_N, reference.stats.peak_normal_force_N,
              1e-4 * reference.stats.peak_normal_force_N);
}

TEST(StepSampler, TimeSteppingAndIslandsAreNotSampledStepByStep) {
  Model model = loadScene(scene("config/default_scene.yaml"));
  EXPECT_TRUE(StepSampler::samplesSteps(model));
  model.integrator.islands = true;
  EXPECT_FALSE(StepSampler::samplesSteps(model));
  model.integrator.islands = false;
  model.integrator.type = IntegratorType::kTimeStepping;
  EXPECT_FALSE(StepSampler::samplesSteps(model));
  EXPECT_FALSE(StepSampler(model, true, 3e-5).enabled());
}

// The default strike's frames, as the node takes them at factor 0: at least 20 inside the
// contact (one per us of its 33 us), on the 1 us grid, strictly between the physics boundaries
// (whose own snapshots draw the state there) and increasing; the kernel, pushed up by the
// tooth, never moves back between frames (the interpolant stays between the accepted steps);
// and the run is bit for bit the run without frames.
TEST(StrikeFrames, DefaultStrikeHasAFrameEveryMicrosecond) {
  const Model model = loadScene(scene("config/default_scene.yaml"));
  constexpr double kEnd_s = 1e-3;
  constexpr std::int64_t kStep_ns = 10000;
  Data data;
  resetData(model, &data);
  StepSampler sampler(model, true, 3 * kPhysicsStep_s);
  StrikeRecorder strikes(kPhysicsStep_s);
  StrikeFrames frames;
  std::vector<FrameState> got;
  std::vector<long> boundary_of;
  for (long k = 1; k * kPhysicsStep_s < kEnd_s + 1e-12; ++k) {
    frames.start(data);
    const StepStatus s = sampler.advance(model, &data, k * kPhysicsStep_s, [&](const Data& d) {
      strikes.sample(d);
      frames.sample(d, k * kStep_ns, [&](const FrameState& f) {
        got.push_back(f);
        boundary_of.push_back(k);
      });
    });
    ASSERT_NE(s, StepStatus::kFailed);
    data.events.clear();
  }
  ASSERT_EQ(strikes.finished().size(), 1u);
  const StrikeRecord& r = strikes.finished().front();
  const int o = model.kernels[0].dof_offset;
  long in_contact = 0;
  double last_y_m = -1e9;
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].t_ns % StrikeFrames::kFrame_ns, 0);
    EXPECT_LT(got[i].t_ns, boundary_of[i] * kStep_ns);
    EXPECT_GT(got[i].t_ns, (boundary_of[i] - 1) * kStep_ns);
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

}  // namespace
}  // namespace threshing_sim
