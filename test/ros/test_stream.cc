// rostest (stream.test), issue 24 item 1: the stream scene runs in the node as in `simulate`.
//  - stream_short (3 ms): ends by itself with `simulate`'s impact count and peak normal force;
//    its strike histories are the integrator's accepted steps (several samples per strike);
//  - stream_long (the scene's 8 ms): runs past t = 7.558 ms, where the forced strike sub-steps
//    made the integrator fail on main, to its end time, ends by itself, and has `simulate`'s
//    impacts and peak force over the whole duration (equal: both take the same steps);
//    (both under the default, island scheme);
//  - the global scheme (the reference) over the whole 8 ms (a child node): `simulate`'s impacts
//    and peak force;
//  - a bounded run whose integrator fails ends by itself with exit status 1 (on main it waited
//    paused for ever: killed after 200 s), under either scheme (under islands it once ran for
//    minutes: the lone kernels' clocks were outside the work budget).
// Both nodes start paused, so that this test hears their whole runs.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <std_srvs/SetBool.h>
#include <sys/wait.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ros_test_util.h"
#include "threshing_sim/StrikeHistory.h"

using threshing_sim::test::pidOf;
using threshing_sim::test::processEnded;
using threshing_sim::test::run;

namespace {

std::mutex g_mutex;
std::map<std::string, std::map<std::string, std::string>> g_diag;  // status name -> key -> value
std::map<std::string, std::string> g_summary;                      // status name -> message
std::map<std::string, std::vector<threshing_sim::StrikeHistory>> g_strikes;  // by node

bool waitFor(const std::function<bool()>& pred, double timeout_s) {
  return threshing_sim::test::waitUnder(g_mutex, pred, timeout_s, 0.02);
}

// The diagnostic status of a node ("<node>: simulation", its name with or without namespace).
std::string statusOf(const std::string& node) {
  for (const auto& status : g_summary)
    if (status.first.find(node + ":") != std::string::npos) return status.first;
  return node + ": simulation";
}

std::string diag(const std::string& node, const std::string& key) {
  const auto it = g_diag.find(statusOf(node));
  if (it == g_diag.end() || !it->second.count(key)) return "";
  return it->second.at(key);
}

bool endsWithin(int pid, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (!processEnded(pid) && ros::WallTime::now() < end) ros::WallDuration(0.05).sleep();
  return processEnded(pid);
}

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

double jsonNumber(const std::string& json, const std::string& key) {
  std::smatch m;
  if (!std::regex_search(json, m, std::regex("\"" + key + "\"\\s*:\\s*([0-9.eE+-]+)"))) return -1;
  return std::stod(m[1]);
}

// `simulate` over the stream scene's first duration_s: its impacts and peak normal force.
void simulateStream(const std::string& duration_s, double* impacts, double* peak_N,
                    std::string* summary) {
  const std::string json = std::string(TEST_TMP_DIR) + "/stream_" +
                           std::to_string(std::hash<std::string>()(duration_s)) + "_summary.json";
  std::string out;
  ASSERT_EQ(run(std::string(THRESHING_SIM_SIMULATE) + " " + THRESHING_SIM_SOURCE_DIR +
                    "/config/scenes/stream.yaml --set duration=" + duration_s +
                    " --quiet --summary " + json,
                &out),
            0)
      << out;
  *summary = slurp(json);
  *impacts = jsonNumber(*summary, "impacts");
  *peak_N = jsonNumber(*summary, "peak_normal_force_N");
}

// Whether a node's run has ended: its summary says finished, or a failure, or it reached t_end_s
// with a warning as its summary (e.g. the chaotic stream's tooth deflection beyond the beam
// model's small-deflection range, which `simulate` warns of too). Called under g_mutex.
bool runEnded(const std::string& node, double t_end_s) {
  const std::string failure = diag(node, "failure");
  if (g_summary[statusOf(node)] == "finished" || (!failure.empty() && failure != "none"))
    return true;
  const std::string t_s = diag(node, "simulation time [s]");
  return !t_s.empty() && std::stod(t_s) >= t_end_s - 1e-9;
}

void start(const std::string& node) {
  std_srvs::SetBool run_srv;
  run_srv.request.data = false;
  ASSERT_TRUE(ros::service::waitForService(node + "/pause", 30.0));
  ASSERT_TRUE(ros::service::call(node + "/pause", run_srv));
}

TEST(Stream, ShortRunEndsWithSimulatesImpactsAndPeak) {
  const int pid = pidOf("/stream_short");
  ASSERT_GT(pid, 0);
  start("/stream_short");
  ASSERT_TRUE(waitFor([] { return runEnded("stream_short", 0.003); }, 120.0))
      << "stream_short: " << g_summary[statusOf("stream_short")];
  ros::WallDuration(0.3).sleep();  // the node's last /diagnostics
  // `simulate` over the same 3 ms.
  double impacts_sim = 0, peak_sim_N = 0;
  std::string summary;
  simulateStream("0.003", &impacts_sim, &peak_sim_N, &summary);
  ASSERT_GT(impacts_sim, 0) << summary;
  std::lock_guard<std::mutex> lock(g_mutex);
  const double peak_N = std::stod(diag("stream_short", "peak normal force [N]"));
  const long impacts = std::stol(diag("stream_short", "impacts"));
  std::printf("stream 3 ms: node %ld impacts, peak %.6f N; simulate %.0f impacts, peak %.6f N\n",
              impacts, peak_N, impacts_sim, peak_sim_N);
  EXPECT_EQ(diag("stream_short", "failure"), "none");
  EXPECT_EQ(impacts, static_cast<long>(impacts_sim));
  EXPECT_DOUBLE_EQ(peak_N, peak_sim_N);
  // Strike histories: the integrator's accepted steps, several per strike, and the largest
  // strike peak is the run's peak (the core's episode peak, not only the sampled one).
  const auto& strikes = g_strikes["stream_short"];
  ASSERT_FALSE(strikes.empty());
  double strike_peak_N = 0;
  size_t samples = 0;
  for (const auto& s : strikes) {
    strike_peak_N = std::max(strike_peak_N, s.peak_normal_force);
    samples += s.time.size();
  }
  std::printf("stream 3 ms: %zu strike histories, %zu samples, largest peak %.6f N\n",
              strikes.size(), samples, strike_peak_N);
  EXPECT_GT(samples, 5 * strikes.size());
  EXPECT_NEAR(strike_peak_N, peak_sim_N, 1e-4 * peak_sim_N);
  EXPECT_TRUE(endsWithin(pid, 20.0)) << "stream_short did not end by itself";
}

TEST(Stream, WholeRunEndsWithSimulatesImpactsAndPeak) {
  const int pid = pidOf("/long/stream_long");
  ASSERT_GT(pid, 0);
  start("/long/stream_long");
  // `simulate` over the scene's whole duration, while the node runs.
  double impacts_sim = 0, peak_sim_N = 0;
  std::string summary;
  simulateStream("0.008", &impacts_sim, &peak_sim_N, &summary);
  ASSERT_GT(impacts_sim, 0) << summary;
  ASSERT_TRUE(waitFor([] { return runEnded("stream_long", 0.008); }, 400.0))
      << "stream_long: " << g_summary[statusOf("stream_long")];
  ros::WallDuration(0.3).sleep();  // the node's last /diagnostics
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    EXPECT_EQ(diag("stream_long", "failure"), "none");
    EXPECT_NEAR(std::stod(diag("stream_long", "simulation time [s]")), 0.008, 1e-9);
    const double peak_N = std::stod(diag("stream_long", "peak normal force [N]"));
    const long impacts = std::stol(diag("stream_long", "impacts"));
    std::printf("stream 8 ms: node %ld impacts, peak %.6f N; simulate %.0f impacts, peak %.6f N\n",
                impacts, peak_N, impacts_sim, peak_sim_N);
    EXPECT_EQ(impacts, static_cast<long>(impacts_sim));
    EXPECT_DOUBLE_EQ(peak_N, peak_sim_N);
  }
  EXPECT_TRUE(endsWithin(pid, 20.0)) << "stream_long did not end by itself";
}

// The global scheme (the reference; islands are the default) over the whole 8 ms: the node as a
// child process on the scene with islands: false, `simulate` with --set integrator.islands=false
// at the same time.
TEST(Stream, WholeRunUnderTheGlobalSchemeEndsWithSimulatesImpactsAndPeak) {
  std::string scene = slurp(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/stream.yaml");
  const std::regex integrator("\nintegrator: \\{");
  ASSERT_TRUE(std::regex_search(scene, integrator));
  scene = std::regex_replace(scene, integrator, "\nintegrator: {islands: false, ");
  const std::string path = std::string(TEST_TMP_DIR) + "/stream_global.yaml";
  std::ofstream(path) << scene;
  double impacts_sim = 0, peak_sim_N = 0;
  std::string summary;
  std::thread simulate([&] {
    simulateStream("0.008 --set integrator.islands=false", &impacts_sim, &peak_sim_N, &summary);
  });
  std::string out;
  const int status = run("timeout -s INT 400 " + std::string(THRESHING_SIM_NODE) +
                             " __name:=stream_global _scene:=" + path +
                             " _clock_mode:=wall _real_time_factor:=0 _end_time:=0.008"
                             " _status_period:=0 _diagnostic_period:=1",
                         &out);
  simulate.join();
  ros::WallDuration(0.3).sleep();  // the node's last /diagnostics
  EXPECT_EQ(status, 0) << out;
  ASSERT_GT(impacts_sim, 0) << summary;
  std::lock_guard<std::mutex> lock(g_mutex);
  EXPECT_EQ(diag("stream_global", "failure"), "none");
  const double peak_N = std::stod(diag("stream_global", "peak normal force [N]"));
  const long impacts = std::stol(diag("stream_global", "impacts"));
  std::printf(
      "stream 8 ms, global scheme: node %ld impacts, peak %.6f N; simulate %.0f impacts, peak "
      "%.6f N\n",
      impacts, peak_N, impacts_sim, peak_sim_N);
  EXPECT_EQ(impacts, static_cast<long>(impacts_sim));
  EXPECT_DOUBLE_EQ(peak_N, peak_sim_N);
}

TEST(Stream, FailedBoundedRunEndsWithExitStatusOne) {
  // The stream with max_step 1e-9 s: 1e6 steps per physics step of 1 ms, beyond the core's work
  // budget; the first step fails. Under the island scheme (the default) and the global one.
  for (const std::string islands : {"true", "false"}) {
    std::string scene = slurp(std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/stream.yaml");
    const std::regex integrator("integrator: \\{[^}]*\\}");
    ASSERT_TRUE(std::regex_search(scene, integrator));
    scene =
        std::regex_replace(scene, integrator,
                           "integrator: {type: event_driven, tolerance: 1.0e-6, max_step: 1e-9, "
                           "islands: " +
                               islands + "}");
    const std::string path = std::string(TEST_TMP_DIR) + "/stream_failing_" + islands + ".yaml";
    std::ofstream(path) << scene;
    std::string out;
    const ros::WallTime started = ros::WallTime::now();
    const int status = run("timeout -s INT 60 " + std::string(THRESHING_SIM_NODE) +
                               " __name:=failing_bounded _scene:=" + path +
                               " _clock_mode:=wall _real_time_factor:=0 _physics_dt:=1e-3"
                               " _end_time:=0.01 _status_period:=0",
                           &out);
    const double wall_s = (ros::WallTime::now() - started).toSec();
    std::printf("failing bounded run, islands %s: exit status %d after %.1f s\n", islands.c_str(),
                status, wall_s);
    EXPECT_EQ(status, 1) << out;
    EXPECT_LT(wall_s, 30.0);
    EXPECT_NE(out.find("the run ends"), std::string::npos) << out;
    EXPECT_NE(out.find("work_budget"), std::string::npos) << out;
  }
}

void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (const auto& s : m->status) {
    g_summary[s.name] = s.message;
    for (const auto& kv : s.values) g_diag[s.name][kv.key] = kv.value;
  }
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_stream");
  ros::NodeHandle nh;
  auto diag_sub = nh.subscribe("/diagnostics", 1000, onDiagnostics);
  auto strike_sub = nh.subscribe<threshing_sim::StrikeHistory>(
      "/strike_history", 10000,
      boost::function<void(const threshing_sim::StrikeHistory::ConstPtr&)>(
          [](const threshing_sim::StrikeHistory::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(g_mutex);
            g_strikes["stream_short"].push_back(*m);
          }));
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::WallDuration(1.0).sleep();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
