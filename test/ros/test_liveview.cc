// rostest (liveview.test): what a user watches and plots, driven as a user would, against one
// node running the default scene as fast as possible (factor 0, sim clock) with the demo's loop
// (kernels re-seeded once per drum revolution). The node starts paused so that this test hears
// the first strike. The tests run in declaration order.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <std_msgs/Float64.h>
#include <std_msgs/String.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <future>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "ros_test_util.h"
#include "threshing_sim/DrumState.h"
#include "threshing_sim/KernelContactForces.h"
#include "threshing_sim/KernelStateArray.h"
#include "threshing_sim/StrikeHistory.h"

namespace {

struct Observed {
  std::mutex mutex;
  std::vector<threshing_sim::StrikeHistory> strikes;
  std::vector<threshing_sim::DrumState> drum;
  threshing_sim::KernelContactForces last_forces;
  threshing_sim::KernelStateArray last_kernels;
  std::string scene;
};

Observed g_seen;
ros::NodeHandle* g_nh = nullptr;

template <typename M>
ros::Subscriber listen(const std::string& topic, const std::function<void(const M&)>& f) {
  return threshing_sim::test::listenUnder<M>(g_nh, g_seen.mutex, topic, 10000, f);
}

bool waitFor(const std::function<bool()>& pred, double timeout_s) {
  return threshing_sim::test::waitUnder(g_seen.mutex, pred, timeout_s, 0.01);
}

// The peak normal force `simulate` reports for the default scene (its --summary JSON) [N].
double simulatePeak() {
  const std::string json = std::string(TEST_TMP_DIR) + "/liveview_default_summary.json";
  const std::string cmd = std::string(THRESHING_SIM_SIMULATE) + " " + THRESHING_SIM_SOURCE_DIR +
                          "/config/default_scene.yaml --quiet --summary " + json;
  if (std::system(cmd.c_str()) != 0) return -1;
  std::ifstream in(json);
  std::stringstream text;
  text << in.rdbuf();
  std::smatch m;
  const std::string s = text.str();
  if (!std::regex_search(s, m, std::regex("\"peak_normal_force_N\"\\s*:\\s*([0-9.eE+-]+)")))
    return -1;
  return std::stod(m[1]);
}

// The first strike: one message holding the whole contact, finely sampled; its peak is the one
// `simulate` reports (within 1 %). The per-kernel forces carry its impulse under kernel 0, and a
// kernel without a pedicel is not reported as attached.
TEST(LiveView, FirstStrikeHistoryMatchesSimulate) {
  std_srvs::SetBool run;
  run.request.data = false;
  ASSERT_TRUE(ros::service::waitForService("/threshing_sim_node/pause", ros::Duration(10)));
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", run));
  ASSERT_TRUE(waitFor([] { return !g_seen.strikes.empty(); }, 30)) << "no strike_history";
  // The latched scene may reach this subscriber after the strike on a loaded machine.
  ASSERT_TRUE(waitFor([] { return !g_seen.scene.empty(); }, 30)) << "no scene_yaml";
  const double peak_sim_N = simulatePeak();
  ASSERT_GT(peak_sim_N, 0) << "simulate --summary failed";
  std::lock_guard<std::mutex> lock(g_seen.mutex);
  const threshing_sim::StrikeHistory& s = g_seen.strikes.front();
  const double duration_s = s.end_time - s.start_time;
  std::printf("first strike: %zu samples over %.1f us, peak %.4f N (simulate: %.4f N)\n",
              s.time.size(), duration_s * 1e6, s.peak_normal_force, peak_sim_N);
  EXPECT_EQ(s.tooth, 0);
  EXPECT_EQ(s.kernel, 0);
  EXPECT_GT(s.time.size(), 15u);  // a 33 us contact: the integrator accepted 20 steps
  EXPECT_GT(duration_s, 20e-6);
  EXPECT_LT(duration_s, 60e-6);
  EXPECT_EQ(s.time.size(), s.normal_force.size());
  EXPECT_NEAR(s.peak_normal_force, peak_sim_N, 0.01 * peak_sim_N);
  EXPECT_GT(s.normal_impulse, 0);
  EXPECT_NE(g_seen.scene.find("Default scene"), std::string::npos) << g_seen.scene;
  ASSERT_EQ(g_seen.last_kernels.kernels.size(), 1u);
  EXPECT_FALSE(g_seen.last_kernels.kernels[0].attached) << "the kernel has no pedicel";
  ASSERT_EQ(g_seen.last_forces.kernels.size(), 1u);
  EXPECT_EQ(g_seen.last_forces.kernels[0].index, 0);
}

// Looping for 10 s of simulated time (133 loops at 800 rpm): every loop's strike has the first
// loop's peak (within 1 %); the kernels come back at the same drum phase, never into the tooth.
TEST(LiveView, TenSecondsOfLoopsNeverDrift) {
  ASSERT_TRUE(waitFor(
      [] { return !g_seen.drum.empty() && g_seen.drum.back().header.stamp.toSec() >= 10.0; }, 90))
      << "the node did not reach t = 10 s";
  std::lock_guard<std::mutex> lock(g_seen.mutex);
  const double first_N = g_seen.strikes.front().peak_normal_force;
  double max_N = 0, min_N = 1e300;
  int n = 0;
  for (const auto& s : g_seen.strikes) {
    if (s.start_time >= 10.0) break;
    max_N = std::max(max_N, s.peak_normal_force);
    min_N = std::min(min_N, s.peak_normal_force);
    ++n;
  }
  std::printf("10 s of loops: %d strikes, peaks %.4f .. %.4f N (first %.4f N), %ld loops\n", n,
              min_N, max_N, first_N, static_cast<long>(g_seen.drum.back().loops));
  EXPECT_GE(n, 130);
  EXPECT_GE(g_seen.drum.back().loops, 130);
  EXPECT_LE(max_N, 1.01 * first_N);
  EXPECT_GE(min_N, 0.99 * first_N);
}

// A drum speed command survives the loop: drum_state shows the commanded target and speed
// after several re-seeds, and the strikes go on at the new speed.
TEST(LiveView, SpeedCommandSurvivesTheLoop) {
  long loops_before = 0;
  {
    std::lock_guard<std::mutex> lock(g_seen.mutex);
    loops_before = g_seen.drum.back().loops;
  }
  ros::Publisher pub = g_nh->advertise<std_msgs::Float64>("/drum_speed_cmd", 1, true);
  std_msgs::Float64 cmd;
  cmd.data = 60.0;
  pub.publish(cmd);
  ASSERT_TRUE(waitFor(
      [&] {
        const auto& d = g_seen.drum.back();
        return d.loops >= loops_before + 3 && d.target_speed == 60.0 &&
               std::abs(d.speed - 60.0) < 1e-9;
      },
      60))
      << "drum_state: target " << g_seen.drum.back().target_speed << ", speed "
      << g_seen.drum.back().speed << ", loops " << g_seen.drum.back().loops;
  // The strikes after the ramp (t_s past the command + 0.12 s) happen at 60 rad/s.
  const double t_now = g_seen.drum.back().header.stamp.toSec();
  ASSERT_TRUE(waitFor([&] { return g_seen.strikes.back().start_time > t_now; }, 30));
  std::lock_guard<std::mutex> lock(g_seen.mutex);
  std::printf("after the command: %ld loops, last strike peak %.2f N at 60 rad/s\n",
              static_cast<long>(g_seen.drum.back().loops), g_seen.strikes.back().peak_normal_force);
  EXPECT_GT(g_seen.strikes.back().peak_normal_force, 10.0);
  EXPECT_LT(g_seen.strikes.back().peak_normal_force, g_seen.strikes.front().peak_normal_force);
}

// The slow-motion factor changes while running (dynamic_reconfigure), and ~skip_to_contact
// runs through the free flight to the next strike at once.
TEST(LiveView, FactorReconfiguredAndSkipToContact) {
  dynamic_reconfigure::Reconfigure srv;
  dynamic_reconfigure::DoubleParameter p;
  p.name = "real_time_factor";
  p.value = 0.01;
  srv.request.config.doubles.push_back(p);
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/set_parameters", srv));
  ros::WallDuration(0.5).sleep();
  double t0 = 0;
  size_t strikes0 = 0;
  {
    std::lock_guard<std::mutex> lock(g_seen.mutex);
    t0 = g_seen.drum.back().header.stamp.toSec();
    strikes0 = g_seen.strikes.size();
  }
  ros::WallDuration(2.0).sleep();
  double t1 = 0;
  {
    std::lock_guard<std::mutex> lock(g_seen.mutex);
    t1 = g_seen.drum.back().header.stamp.toSec();
  }
  std::printf("at factor 0.01: %.4f s of simulated time in 2 s of wall time\n", t1 - t0);
  EXPECT_GT(t1 - t0, 0.01);
  EXPECT_LT(t1 - t0, 0.03);
  // One revolution at 60 rad/s is 0.105 s: 10 s of wall time at 0.01 without the skip.
  std_srvs::Trigger skip;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/skip_to_contact", skip));
  EXPECT_TRUE(skip.response.success);
  const ros::WallTime start = ros::WallTime::now();
  ASSERT_TRUE(waitFor([&] { return g_seen.strikes.size() > strikes0; }, 6))
      << "no strike within 6 s of wall time after ~skip_to_contact";
  std::printf("skip_to_contact: next strike after %.2f s of wall time\n",
              (ros::WallTime::now() - start).toSec());
}

// A reset that would put a body into another is refused: right after a strike (at factor 0.01)
// the tooth still sits on the kernel's initial place, and ~reset says so instead of placing the
// kernel inside the tooth.
TEST(LiveView, ResetIntoTheToothIsRefused) {
  size_t strikes0 = 0;
  {
    std::lock_guard<std::mutex> lock(g_seen.mutex);
    strikes0 = g_seen.strikes.size();
  }
  std_srvs::Trigger skip;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/skip_to_contact", skip));
  ASSERT_TRUE(waitFor([&] { return g_seen.strikes.size() > strikes0; }, 10)) << "no strike";
  std_srvs::SetBool pause;
  pause.request.data = true;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", pause));
  std_srvs::Trigger reset;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/reset", reset));
  std::printf("~reset right after a strike: success %d, \"%s\"\n", reset.response.success,
              reset.response.message.c_str());
  EXPECT_FALSE(reset.response.success);
  EXPECT_NE(reset.response.message.find("overlap"), std::string::npos);
  pause.request.data = false;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/pause", pause));
}

// The live plotter (scripts/live_plot, Debian's matplotlib, headless with --save) plots a field
// of drum_state, a per-kernel force and the strike histories while the node runs; a skip to the
// next contact during the plot brings a strike into it.
TEST(LiveView, LivePlotPlotsFieldsAndStrikes) {
  const std::string png = std::string(TEST_TMP_DIR) + "/live_plot.png";
  std::remove(png.c_str());
  const std::string cmd = std::string(THRESHING_SIM_SOURCE_DIR) +
                          "/scripts/live_plot /drum_state/speed "
                          "'/kernel_contact_forces/kernels[0]/tooth_normal_impulse' --strikes "
                          "--duration 5 --save " +
                          png + " 2>&1";
  auto plot = std::async(std::launch::async, [&] {
    std::string out;
    FILE* p = popen(cmd.c_str(), "r");
    char buf[1024];
    while (p && fgets(buf, sizeof(buf), p)) out += buf;
    const int status = p ? pclose(p) : -1;
    return std::make_pair(status, out);
  });
  ros::WallDuration(2.0).sleep();  // subscribed
  std_srvs::Trigger skip;
  ASSERT_TRUE(ros::service::call("/threshing_sim_node/skip_to_contact", skip));
  const auto [status, out] = plot.get();
  std::printf("%s", out.c_str());
  EXPECT_EQ(status, 0);
  std::smatch m;
  ASSERT_TRUE(std::regex_search(out, m,
                                std::regex("/drum_state/speed': (\\d+).*tooth_normal_impulse': "
                                           "(\\d+)\\}, (\\d+) strike histories")))
      << out;
  EXPECT_GT(std::stoi(m[1]), 10);
  EXPECT_GT(std::stoi(m[2]), 10);
  EXPECT_GE(std::stoi(m[3]), 1);
  EXPECT_TRUE(std::ifstream(png).good()) << png;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_liveview");
  ros::NodeHandle nh;
  g_nh = &nh;
  std::vector<ros::Subscriber> subs;
  subs.push_back(listen<threshing_sim::StrikeHistory>(
      "/strike_history",
      [](const threshing_sim::StrikeHistory& m) { g_seen.strikes.push_back(m); }));
  subs.push_back(listen<threshing_sim::DrumState>(
      "/drum_state", [](const threshing_sim::DrumState& m) { g_seen.drum.push_back(m); }));
  subs.push_back(listen<threshing_sim::KernelContactForces>(
      "/kernel_contact_forces",
      [](const threshing_sim::KernelContactForces& m) { g_seen.last_forces = m; }));
  subs.push_back(listen<threshing_sim::KernelStateArray>(
      "/kernel_states", [](const threshing_sim::KernelStateArray& m) { g_seen.last_kernels = m; }));
  subs.push_back(listen<std_msgs::String>(
      "/scene_yaml", [](const std_msgs::String& m) { g_seen.scene = m.data; }));
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::WallDuration(1.0).sleep();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
