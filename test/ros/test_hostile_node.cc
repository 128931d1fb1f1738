// Issue 14 against live nodes (test/ros/hostile.test):
//  - reset_node: its periodic reset at t = 0.0375 s would put the kernel inside the tooth (the
//    node hung there for good before); the reset now waits for the tooth to pass, the run
//    reaches its end time 0.1 s, /diagnostics counts the deferred reset and no failure;
//  - nan/threshing_sim_node: NaN rates and a NaN contact value through dynamic_reconfigure are
//    refused, the server keeps the last good values (so a later good request succeeds), and
//    contact_state keeps its rate (it was published on every physics step).
#include <diagnostic_msgs/DiagnosticArray.h>
#include <dynamic_reconfigure/Reconfigure.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosgraph_msgs/Clock.h>
#include <std_srvs/SetBool.h>

#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <string>

#include "threshing_sim/ContactStateArray.h"

namespace {

std::mutex g_mutex;
std::map<std::string, std::map<std::string, std::string>> g_diag;  // status name -> key -> value
std::map<std::string, int> g_level;                                // status name -> level
double g_clock_s = 0;
std::atomic<long> g_contact_messages{0};

bool waitFor(const std::function<bool()>& pred, double timeout_s) {
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (ros::WallTime::now() < end) {
    {
      std::lock_guard<std::mutex> lock(g_mutex);
      if (pred()) return true;
    }
    ros::WallDuration(0.02).sleep();
  }
  return false;
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

void onDiagnostics(const diagnostic_msgs::DiagnosticArray::ConstPtr& m) {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (const auto& s : m->status) {
    g_level[s.name] = s.level;
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
