// Issue 14 against live nodes (test/ros/hostile.test):
//  - reset_node: its periodic reset at t = 0.0375 s would put the kernel inside the tooth (the
//    node hung there for good before); the reset now waits for the tooth to pass, the run
//    reaches its end time 0.1 s, /diagnostics counts the deferred reset and no failure;
//  - nan/threshing_sim_node: NaN rates and a NaN contact value through dynamic_reconfigure are
//    refused, the server keeps the last good values (so a later good request succeeds), and
//    contact_state keeps its rate (it was published on every physics step);
//  - failing_node: a scene beyond the work budget; the watchdog flags the busy physics step,
//    /diagnostics reports ERROR with the typed cause, and the node answers ~reset and SIGINT.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <signal.h>
#include <std_srvs/SetBool.h>
#include <std_srvs/Trigger.h>
#include <sys/types.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <atomic>
#include <cmath>
#include <fstream>
#include <map>
#include <mutex>
#include <set>
#include <string>

#include "ros_test_util.h"
#include "threshing_sim/ContactStateArray.h"

using threshing_sim::test::pidOf;
using threshing_sim::test::processEnded;

namespace {

std::mutex g_mutex;
std::map<std::string, std::map<std::string, std::string>> g_diag;  // status name -> key -> value
std::map<std::string, int> g_level;                                // status name -> level
std::map<std::string, std::set<std::string>> g_messages;           // status name -> messages heard
double g_clock_s = 0;
std::atomic<long> g_contact_messages{0};

bool waitFor(const std::function<bool()>& pred, double timeout_s) {
  return threshing_sim::test::waitUnder(g_mutex, pred, timeout_s, 0.02);
}

std::string diag(const std::string& node, const std::string& key) {
  for (const auto& status : g_diag)
    if (status.first.find(node) != std::string::npos && status.second.count(key))
      return status.second.at(key);
  return "";
}

TEST(HostileNode, ResetIntoToothIsDeferredAndTheRunEnds) {
  // The node starts paused, so that this test hears its whole run.
  std_srvs::SetBool run;
  run.request.data = false;
  ASSERT_TRUE(ros::service::waitForService("/reset_node/pause", 10.0));
  ASSERT_TRUE(ros::service::call("/reset_node/pause", run));
  // The run reaches 0.1 s (about a second of wall time at factor 0 when nothing hangs).
  ASSERT_TRUE(waitFor([] { return g_clock_s >= 0.1 - 1e-9; }, 60.0))
      << "simulated time stuck at " << g_clock_s << " s";
  ASSERT_TRUE(waitFor(
      [] {
        return diag("reset_node", "resets deferred (overlap)") != "" &&
               std::stol(diag("reset_node", "resets deferred (overlap)")) >= 1;
      },
      10.0));
  std::lock_guard<std::mutex> lock(g_mutex);
  EXPECT_EQ(diag("reset_node", "failure"), "none");
  // The strike after the deferred reset is an ordinary one: no 30 kN forces.
  EXPECT_LT(std::stod(diag("reset_node", "peak normal force [N]")), 200.0);
}

dynamic_reconfigure::Reconfigure::Response reconfigure(const std::string& name, double value) {
  dynamic_reconfigure::Reconfigure srv;
  dynamic_reconfigure::DoubleParameter p;
  p.name = name;
  p.value = value;
  srv.request.config.doubles.push_back(p);
  EXPECT_TRUE(ros::service::waitForService("/nan/threshing_sim_node/set_parameters", 10.0));
  EXPECT_TRUE(ros::service::call("/nan/threshing_sim_node/set_parameters", srv));
  return srv.response;
}

double valueOf(const dynamic_reconfigure::Reconfigure::Response& r, const std::string& name) {
  for (const auto& d : r.config.doubles)
    if (d.name == name) return d.value;
  return -1;
}

TEST(HostileNode, NanReconfigureIsRefusedAndTheServerKeepsTheLastGoodValues) {
  auto r = reconfigure("contact_state_rate", std::nan(""));
  EXPECT_EQ(valueOf(r, "contact_state_rate"), 100.0);
  r = reconfigure("state_rate", std::nan(""));
  EXPECT_EQ(valueOf(r, "state_rate"), 50.0);
  r = reconfigure("tooth_kernel_restitution", std::nan(""));
  EXPECT_EQ(valueOf(r, "tooth_kernel_restitution"), 0.48);
  // A good request afterwards is applied (it was rejected while the NaN stayed in the server).
  r = reconfigure("tooth_kernel_friction", 0.4);
  EXPECT_EQ(valueOf(r, "tooth_kernel_friction"), 0.4);
  EXPECT_EQ(valueOf(r, "tooth_kernel_restitution"), 0.48);
  // contact_state at ~100 Hz, not on every physics step (1e5 per second).
  const long before = g_contact_messages;
  ros::WallDuration(1.0).sleep();
  const long per_second = g_contact_messages - before;
  EXPECT_GT(per_second, 20);
  EXPECT_LT(per_second, 300);
  EXPECT_TRUE(waitFor(
      [] { return diag("nan/threshing_sim_node", "refused reconfigure requests") == "3"; }, 5.0))
      << diag("nan/threshing_sim_node", "refused reconfigure requests");
}

// ERROR summaries heard from a node, cut before their first ':' or '(' ("watchdog",
// "integrator failed ").
std::set<std::string> errorsOf(const std::string& node) {
  std::set<std::string> out;
  for (const auto& status : g_messages)
    if (status.first.find(node) != std::string::npos)
      out.insert(status.second.begin(), status.second.end());
  return out;
}

TEST(HostileNode, NumericalFailureIsAnErrorWithItsCauseAndTheNodeStillAnswers) {
  // The watchdog flags the physics step while it runs, then the typed cause is reported.
  ASSERT_TRUE(waitFor([] { return errorsOf("failing_node").count("watchdog") > 0; }, 30.0));
  ASSERT_TRUE(waitFor(
      [] { return diag("failing_node", "failure").find("[work_budget]") != std::string::npos; },
      30.0))
      << diag("failing_node", "failure");
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    EXPECT_EQ(errorsOf("failing_node").count("integrator failed "), 1u);
    EXPECT_EQ(diag("failing_node", "paused"), "True");
    // The time of the state kept (inside the failed step), not the end of the failed step.
    EXPECT_LT(std::stod(diag("failing_node", "simulation time [s]")), 1e-4);
  }
  // ~reset is answered and runs the node again (issue 24: it answered "bodies reset" and
  // stayed paused): /diagnostics shows it running, and its simulation time passes the
  // failure's until the next physics step fails as well.
  double failed_at_s = 0;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    failed_at_s = std::stod(diag("failing_node", "simulation time [s]"));
  }
  std_srvs::Trigger reset;
  ASSERT_TRUE(ros::service::waitForService("/failing_node/reset", 10.0));
  const ros::WallTime asked = ros::WallTime::now();
  ASSERT_TRUE(ros::service::call("/failing_node/reset", reset));
  EXPECT_LT((ros::WallTime::now() - asked).toSec(), 10.0);
  EXPECT_TRUE(reset.response.success) << reset.response.message;
  EXPECT_NE(reset.response.message.find("running again"), std::string::npos)
      << reset.response.message;
  EXPECT_TRUE(waitFor([] { return diag("failing_node", "paused") == "False"; }, 10.0))
      << "still paused after ~reset";
  EXPECT_TRUE(waitFor(
      [&] {
        return diag("failing_node", "paused") == "True" &&
               std::stod(diag("failing_node", "simulation time [s]")) > failed_at_s;
      },
      90.0))
      << "simulation time " << diag("failing_node", "simulation time [s]") << " s, failed at "
      << failed_at_s << " s";
  // Paused by the user, a reset after a failure stays paused.
  std_srvs::SetBool pause;
  pause.request.data = true;
  ASSERT_TRUE(ros::service::call("/failing_node/pause", pause));
  ASSERT_TRUE(ros::service::call("/failing_node/reset", reset));
  EXPECT_EQ(reset.response.message.find("running again"), std::string::npos)
      << reset.response.message;
  ros::WallDuration(0.5).sleep();
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    EXPECT_EQ(diag("failing_node", "paused"), "True");
  }
  // SIGINT ends it within seconds (before the work budget, it could only be killed).
  const int pid = pidOf("/failing_node");
  ASSERT_GT(pid, 0);
  ASSERT_EQ(kill(pid, SIGINT), 0);
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(10.0);
  while (!processEnded(pid) && ros::WallTime::now() < end) ros::WallDuration(0.05).sleep();
  EXPECT_TRUE(processEnded(pid)) << "failing_node (pid " << pid << ") ignored SIGINT for 10 s";
}

void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (const auto& s : m->status) {
    g_level[s.name] = s.level;
    if (s.level == diagnostic_msgs::DiagnosticStatus::ERROR)
      g_messages[s.name].insert(s.message.substr(0, s.message.find_first_of(":(")));
    for (const auto& kv : s.values) g_diag[s.name][kv.key] = kv.value;
  }
}

void onClock(const rosgraph_msgs::Clock::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(g_mutex);
  g_clock_s = std::max(g_clock_s, m->clock.toSec());
}

void onContactState(const threshing_sim::ContactStateArray::ConstPtr&) { ++g_contact_messages; }

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_hostile_node");
  ros::NodeHandle nh;
  auto diag_sub = nh.subscribe("/diagnostics", 100, onDiagnostics);
  auto clock_sub = nh.subscribe("/clock", 100, onClock);
  auto contact_sub = nh.subscribe("/nan/contact_state", 10000, onContactState);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  ros::WallDuration(1.0).sleep();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
