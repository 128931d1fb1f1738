// Unit tests of the run's status (no ROS master; issue 24 item 4): runStatus, which
// /diagnostics and the overlay share, and what the markers make of it - the overlay's status
// line and colour, the status word, the whole cause, and the alarm frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/ros/live_view.h"
#include "threshing_sim/ros/messages.h"
#include "threshing_sim/ros/node_shared.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

constexpr double kWatchdog_s = 5.0;

struct FakeRun {
  RunFlags flags;
  RunCounters counters;
  FakeRun() {
    counters.target_rtf = 1;
    counters.requested_rtf = 1;
    counters.measured_rtf = 1;
  }
  RunStatus status(double busy_s = 0, const std::string& failure = "") const {
    return runStatus(flags, counters, failure, busy_s, kWatchdog_s);
  }
};

TEST(Status, RunningHoldingThePaceIsOk) {
  const RunStatus s = FakeRun().status();
  EXPECT_EQ(s.level, RunStatus::kOk);
  EXPECT_EQ(s.state, "RUNNING");
  EXPECT_EQ(s.message, "running");
}

TEST(Status, PausedNamesTheServiceThatRunsItOn) {
  FakeRun run;
  run.flags.paused = true;
  run.counters.measured_rtf = 0;  // a paused run measures 0: not slow
  const RunStatus s = run.status();
  EXPECT_EQ(s.level, RunStatus::kOk);
  EXPECT_EQ(s.state, "PAUSED");
  EXPECT_NE(s.message.find("call ~pause false to run"), std::string::npos) << s.message;
}

TEST(Status, APaceNotHeldIsSlow) {
  FakeRun run;
  run.counters.measured_rtf = 0.5;
  RunStatus s = run.status();
  EXPECT_EQ(s.level, RunStatus::kWarn);
  EXPECT_EQ(s.state, "SLOW");
  EXPECT_EQ(s.message.rfind("slower than the target real time: real-time factor 0.5, pace 1", 0),
            0u)
      << s.message;
  run.counters.measured_rtf = 0.91;  // within 90 % of the pace: held
  EXPECT_EQ(run.status().state, "RUNNING");
  run.counters.target_rtf = 0;  // as fast as possible: no pace to miss
  run.counters.measured_rtf = 0.01;
  EXPECT_EQ(run.status().level, RunStatus::kOk);
}

TEST(Status, AFailureIsAnErrorWithItsCause) {
  FakeRun run;
  run.flags.failed = true;
  run.flags.paused = true;
  const RunStatus s = run.status(0, "work budget exceeded [work_budget]");
  EXPECT_EQ(s.level, RunStatus::kError);
  EXPECT_EQ(s.state, "FAILED");
  EXPECT_EQ(s.message, "integrator failed (work budget exceeded [work_budget]): call ~reset");
}

TEST(Status, TheWatchdogComesFirst) {
  FakeRun run;
  run.flags.failed = true;
  const RunStatus s = run.status(7.25, "x");
  EXPECT_EQ(s.level, RunStatus::kError);
  EXPECT_EQ(s.state, "STALLED");
  EXPECT_EQ(s.message, "watchdog: physics step running for 7.2 s");
  EXPECT_EQ(run.status(kWatchdog_s, "x").state, "FAILED");  // not beyond the timeout yet
}

TEST(Status, OtherWarningsKeepTheState) {
  FakeRun run;
  run.flags.finished = true;
  EXPECT_EQ(run.status().message, "finished");
  run.counters.recoveries = 2;
  const RunStatus s = run.status();
  EXPECT_EQ(s.level, RunStatus::kWarn);
  EXPECT_EQ(s.state, "FINISHED");
  EXPECT_EQ(s.message, "numerical recoveries");
}

// The markers of the default scene's initial state under a given status.
struct Drawn {
  const visualization_msgs::Marker* overlay = nullptr;
  const visualization_msgs::Marker* word = nullptr;
  const visualization_msgs::Marker* cause = nullptr;
  const visualization_msgs::Marker* frame = nullptr;
};

class StatusMarkers : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = std::make_shared<const Model>(
        loadScene(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/default_scene.yaml"));
    Data data;
    resetData(*model_, &data);
    s_.model = model_;
    s_.theta_rad = data.theta_rad;
    s_.z = data.z;
    s_.u = data.u;
    s_.kernel_attached = data.kernel_attached;
    s_.kernel_peak_force_N.assign(model_->kernels.size(), 0.0);
    s_.streams = kAllStreams;
    loadPose(s_, &scratch_);
    builder_.setView(sceneExtent(*model_), DamageThresholds());
  }
  Drawn draw(const RunStatus& status) {
    builder_.setStatus(status);
    markers_ = builder_.build(s_, scratch_, false);
    Drawn d;
    for (const auto& m : markers_.markers) {
      if (m.ns == "overlay") d.overlay = &m;
      if (m.ns == "status" && m.id == 0) d.word = &m;
      if (m.ns == "status" && m.id == 1) d.cause = &m;
      if (m.ns == "status_frame") d.frame = &m;
    }
    return d;
  }
  static bool colour(const visualization_msgs::Marker& m, float r, float g, float b) {
    return std::abs(m.color.r - r) < 1e-3 && std::abs(m.color.g - g) < 1e-3 &&
           std::abs(m.color.b - b) < 1e-3;
  }
  static std::string firstLine(const std::string& text) { return text.substr(0, text.find('\n')); }

  std::shared_ptr<const Model> model_;
  Snapshot s_;
  Data scratch_;
  MarkerBuilder builder_{5e-4, 20};
  visualization_msgs::MarkerArray markers_;
};

TEST_F(StatusMarkers, RunningShowsTheOverlayAsBefore) {
  const Drawn d = draw(FakeRun().status());
  ASSERT_TRUE(d.overlay && d.word && d.cause && d.frame);
  EXPECT_EQ(d.overlay->text.rfind("t = ", 0), 0u) << d.overlay->text;
  EXPECT_TRUE(colour(*d.overlay, 0.95f, 0.95f, 0.95f));
  for (const auto* m : {d.word, d.cause, d.frame})
    EXPECT_EQ(m->action, visualization_msgs::Marker::DELETE) << m->ns << " " << m->id;
}

TEST_F(StatusMarkers, FailedShowsTheWholeCauseInRed) {
  FakeRun run;
  run.flags.failed = true;
  const std::string failure =
      "work budget exceeded (steps, rejected steps and events) [work_budget] at t = 1.6001e-05 s "
      "(target 0.0001 s, 32002 of 32000 work units)";
  const RunStatus status = run.status(0, failure);
  const Drawn d = draw(status);
  ASSERT_TRUE(d.overlay && d.word && d.cause && d.frame);
  EXPECT_EQ(firstLine(d.overlay->text), "FAILED: integrator failed");
  EXPECT_EQ(d.word->text, "FAILED");
  // The cause is wrapped at spaces into lines of at most 48 characters, else word for word.
  std::string cause = d.cause->text;
  size_t start = 0;
  for (size_t nl = cause.find('\n'); nl != std::string::npos; nl = cause.find('\n', start)) {
    EXPECT_LE(nl - start, 48u) << cause;
    start = nl + 1;
  }
  EXPECT_GT(std::count(cause.begin(), cause.end(), '\n'), 1);
  std::replace(cause.begin(), cause.end(), '\n', ' ');
  EXPECT_EQ(cause, status.message);
  for (const auto* m : {d.overlay, d.word, d.cause, d.frame}) {
    EXPECT_TRUE(colour(*m, 1.f, 0.15f, 0.15f)) << m->ns << " " << m->id;
    EXPECT_EQ(m->action, visualization_msgs::Marker::ADD) << m->ns << " " << m->id;
  }
  EXPECT_EQ(d.frame->points.size(), 5u);
}

TEST_F(StatusMarkers, SlowIsAmberAndFramed) {
  FakeRun run;
  run.counters.measured_rtf = 0.2;
  const Drawn d = draw(run.status());
  ASSERT_TRUE(d.overlay && d.word && d.frame);
  EXPECT_EQ(firstLine(d.overlay->text), "SLOW: slower than the target real time");
  EXPECT_TRUE(colour(*d.overlay, 1.f, 0.6f, 0.f));
  EXPECT_TRUE(colour(*d.word, 1.f, 0.6f, 0.f));
  EXPECT_EQ(d.frame->action, visualization_msgs::Marker::ADD);
}

TEST_F(StatusMarkers, PausedIsSkyBlueWithoutAnAlarm) {
  FakeRun run;
  run.flags.paused = true;
  const Drawn d = draw(run.status());
  ASSERT_TRUE(d.overlay && d.word && d.cause && d.frame);
  EXPECT_EQ(firstLine(d.overlay->text), "PAUSED");
  EXPECT_EQ(d.word->text, "PAUSED");
  EXPECT_TRUE(colour(*d.word, 0.6f, 0.8f, 1.f));
  EXPECT_EQ(d.cause->action, visualization_msgs::Marker::ADD);
  EXPECT_EQ(d.frame->action, visualization_msgs::Marker::DELETE);
}

}  // namespace
}  // namespace threshing_sim
