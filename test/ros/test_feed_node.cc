// rostest (feed.test, feed_record.test): the continuous feed in the node (issue 34), with a real
// master and real bags.
//  - FeedNode (feed.test: a node on config/scenes/feed.yaml in /fed, one on the default scene in
//    /plain, both in wall clock mode):
//    - feed_throughput arrives once per ~feed_interval with a consistent balance
//      (total_fed = in_drum + separated + carried over + out of bounds), consecutive intervals
//      adding up, and the drum's load;
//    - hostile feed_rate_cmd values (negative, NaN, inf, 1e12, more than the pool holds) are
//      refused, counted in /diagnostics, and the simulation runs on; rate 0 stops the feed and a
//      good rate starts it again, each applied once on feed_rate_cmd_applied;
//    - a feed_rate_cmd to a scene without a feed is refused and counted.
//  - FeedRecord (feed_record.test): record.launch records a bounded fed run while feed rate and
//    drum speed commands arrive; resimulate.launch re-applies them at their step boundaries and
//    scripts/compare_bags finds every output, feed_throughput and the applied commands included,
//    bit for bit the same.
#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <signal.h>
#include <std_msgs/Float64.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <limits>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "ros_test_util.h"
#include "threshing_sim/DrumSpeedCommand.h"
#include "threshing_sim/DrumState.h"
#include "threshing_sim/FeedRateCommand.h"
#include "threshing_sim/FeedThroughput.h"

using threshing_sim::FeedRateCommand;
using threshing_sim::FeedThroughput;
using threshing_sim::test::Launch;
using threshing_sim::test::listenUnder;
using threshing_sim::test::run;
using threshing_sim::test::waitUnder;

namespace {

std::string g_dir;  // scratch directory of this test run
std::mutex g_mutex;

// What the FeedNode tests see of the two nodes, under g_mutex.
struct Seen {
  std::vector<FeedThroughput> throughput;      // /fed/feed_throughput
  std::vector<FeedRateCommand> applied;        // /fed/feed_rate_cmd_applied
  std::vector<threshing_sim::DrumState> drum;  // /fed/drum_state
  std::map<std::string, std::map<std::string, std::string>> diagnostics;  // node -> key -> value
} g_seen;

double diag(const std::string& node, const std::string& key) {
  const auto n = g_seen.diagnostics.find(node);
  if (n == g_seen.diagnostics.end()) return -1;
  const auto v = n->second.find(key);
  return v == n->second.end() ? -1 : std::stod(v->second);
}

bool balanced(const FeedThroughput& m) {
  return m.total_fed == m.in_drum + m.total_separated + m.total_carried_over_detached +
                            m.total_carried_over_unthreshed + m.total_out_of_bounds;
}

// feed_throughput once per interval, balanced, consecutive intervals adding up, with kernels
// retired and the drum's load in them.
TEST(FeedNode, ThroughputArrivesWithABalance) {
  ASSERT_TRUE(waitUnder(
      g_mutex,
      [] {
        return !g_seen.throughput.empty() &&
               g_seen.throughput.back().total_fed > g_seen.throughput.back().in_drum + 3;
      },
      150.0, 0.1))
      << "no feed_throughput with retired kernels (" << g_seen.throughput.size() << " messages)";
  std::lock_guard<std::mutex> lock(g_mutex);
  const std::vector<FeedThroughput>& t = g_seen.throughput;
  ASSERT_GE(t.size(), 3u);
  bool some_power = false;
  for (size_t i = 0; i < t.size(); ++i) {
    const FeedThroughput& m = t[i];
    EXPECT_TRUE(balanced(m)) << "message " << i << ": fed " << m.total_fed;
    // 0.01 s on the step grid (its end the step end at or past the boundary).
    EXPECT_NEAR(m.end_time - m.start_time, 0.01, 2e-4) << i;
    EXPECT_EQ(m.feed_rate_per_s, 200.0);
    EXPECT_NEAR(m.feed_rate_kgps, 200.0 * 0.5 * (2.4e-5 + 3.1e-5), 1e-12);
    EXPECT_GE(m.threshed, 0);
    EXPECT_LE(m.total_threshed, m.total_fed - m.in_drum);
    EXPECT_LE(m.peak_force_p50, m.peak_force_p90);
    EXPECT_LE(m.peak_force_p90, m.peak_force_max);
    EXPECT_TRUE(std::isfinite(m.power) && std::isfinite(m.torque));
    some_power |= m.power > 0;
    if (i == 0) continue;
    const FeedThroughput& p = t[i - 1];
    EXPECT_EQ(m.start_time, p.end_time) << i;
    EXPECT_EQ(m.total_fed - p.total_fed, m.fed) << i;
    EXPECT_EQ(m.total_separated - p.total_separated, m.separated) << i;
    EXPECT_EQ(m.total_out_of_bounds - p.total_out_of_bounds, m.out_of_bounds) << i;
    EXPECT_EQ(m.total_threshed - p.total_threshed, m.threshed) << i;
    EXPECT_EQ(m.header.stamp > p.header.stamp, true) << i;
  }
  EXPECT_TRUE(some_power) << "the drive did no work on the kernels";
  // drum_state: load power = load torque x speed, every field finite.
  ASSERT_FALSE(g_seen.drum.empty());
  for (const threshing_sim::DrumState& d : g_seen.drum) {
    ASSERT_TRUE(std::isfinite(d.load_torque));
    EXPECT_EQ(d.load_power, d.load_torque * d.speed);
  }
}

// Hostile values on feed_rate_cmd: refused, counted, and the run goes on; 0 stops the feed, a
// good rate starts it again.
TEST(FeedNode, HostileFeedRatesAreRefusedAndCounted) {
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<std_msgs::Float64>("/fed/feed_rate_cmd", 10);
  const std::string node = "fed/threshing_sim_node";
  ASSERT_TRUE(waitUnder(
      g_mutex,
      [&] { return pub.getNumSubscribers() > 0 && diag(node, "rejected feed rate commands") >= 0; },
      30.0, 0.05));
  double rejected = 0, t_before = 0;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    rejected = diag(node, "rejected feed rate commands");
    t_before = diag(node, "simulation time [s]");
  }
  // The pool (96 slots) holds 363 kernels/s on the 0.264 m of the mat at 1 m/s: 1e6 is refused.
  const double inf = std::numeric_limits<double>::infinity();
  for (double bad : {-1.0, std::numeric_limits<double>::quiet_NaN(), inf, -inf, 1e12, 1e6}) {
    std_msgs::Float64 m;
    m.data = bad;
    pub.publish(m);
    ros::WallDuration(0.02).sleep();
  }
  EXPECT_TRUE(waitUnder(
      g_mutex, [&] { return diag(node, "rejected feed rate commands") == rejected + 6; }, 20.0,
      0.05))
      << "rejected feed rate commands: " << diag(node, "rejected feed rate commands");
  // The simulation runs on, and applied none of them.
  EXPECT_TRUE(waitUnder(
      g_mutex, [&] { return diag(node, "simulation time [s]") > t_before + 0.005; }, 60.0, 0.1));
  size_t applied_before = 0;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    EXPECT_TRUE(g_seen.applied.empty());
    for (const FeedThroughput& m : g_seen.throughput) EXPECT_EQ(m.feed_rate_per_s, 200.0);
    applied_before = g_seen.applied.size();
  }
  // 0 stops the feed: later intervals feed nothing.
  std_msgs::Float64 stop;
  stop.data = 0.0;
  pub.publish(stop);
  ASSERT_TRUE(waitUnder(
      g_mutex, [&] { return g_seen.applied.size() == applied_before + 1; }, 20.0, 0.05));
  size_t stopped_at = 0;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    EXPECT_EQ(g_seen.applied.back().rate_per_s, 0.0);
    stopped_at = g_seen.throughput.size();
  }
  ASSERT_TRUE(waitUnder(
      g_mutex, [&] { return g_seen.throughput.size() >= stopped_at + 3; }, 90.0, 0.1));
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    const std::vector<FeedThroughput>& t = g_seen.throughput;
    // The interval the command fell in may have fed before it; every later one feeds none.
    for (size_t i = stopped_at + 1; i < t.size(); ++i) {
      EXPECT_EQ(t[i].fed, 0) << i;
      EXPECT_EQ(t[i].feed_rate_per_s, 0.0) << i;
      EXPECT_TRUE(balanced(t[i])) << i;
    }
  }
  // A good rate again.
  std_msgs::Float64 go;
  go.data = 300.0;
  pub.publish(go);
  ASSERT_TRUE(waitUnder(
      g_mutex, [&] { return g_seen.applied.size() == applied_before + 2; }, 20.0, 0.05));
  std::lock_guard<std::mutex> lock(g_mutex);
  EXPECT_EQ(g_seen.applied.back().rate_per_s, 300.0);
  EXPECT_EQ(diag(node, "rejected feed rate commands"), rejected + 6);
}

// A feed rate command to a scene without a feed: refused and counted, the run goes on.
TEST(FeedNode, FeedCommandWithoutAFeedIsRefused) {
  ros::NodeHandle nh;
  ros::Publisher pub = nh.advertise<std_msgs::Float64>("/plain/feed_rate_cmd", 10);
  const std::string node = "plain/threshing_sim_node";
  ASSERT_TRUE(waitUnder(
      g_mutex,
      [&] { return pub.getNumSubscribers() > 0 && diag(node, "rejected feed rate commands") >= 0; },
      30.0, 0.05));
  double rejected = 0, all = 0, t_before = 0;
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    rejected = diag(node, "rejected feed rate commands");
    all = diag(node, "rejected commands");
    t_before = diag(node, "simulation time [s]");
  }
  std_msgs::Float64 m;
  m.data = 100.0;
  pub.publish(m);
  EXPECT_TRUE(waitUnder(
      g_mutex,
      [&] {
        return diag(node, "rejected feed rate commands") == rejected + 1 &&
               diag(node, "rejected commands") == all + 1;
      },
      20.0, 0.05));
  EXPECT_TRUE(waitUnder(
      g_mutex, [&] { return diag(node, "simulation time [s]") > t_before; }, 30.0, 0.1));
}

// ---------------------------------------------------------------------------------------------
// FeedRecord: feed and drum commands through a recording and its re-simulation.

template <class M>
std::vector<M> messages(const std::string& path, const std::string& topic) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::vector<M> out;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic)))
    out.push_back(*m.instantiate<M>());
  return out;
}

constexpr double kRecorded_s = 0.1;  // simulated time of the recorded run [s]

TEST(FeedRecord, FeedCommandsAreRecordedAndResimulatedBitForBit) {
  const std::string scene = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/feed.yaml";
  ros::NodeHandle nh;
  std::mutex mutex;
  std::vector<FeedRateCommand> applied;
  ros::Subscriber sub =
      listenUnder<FeedRateCommand>(&nh, mutex, "/feed_rate_cmd_applied", 10,
                                   [&](const FeedRateCommand& m) { applied.push_back(m); });
  // The first command waits latched for the node (applied at t = 0), with a drum command.
  ros::Publisher feed = nh.advertise<std_msgs::Float64>("/feed_rate_cmd", 1, true);
  ros::Publisher drum = nh.advertise<std_msgs::Float64>("/drum_speed_cmd", 1, true);
  std_msgs::Float64 cmd;
  cmd.data = 300.0;
  feed.publish(cmd);
  cmd.data = 90.0;
  drum.publish(cmd);

  Launch launch(g_dir + "/roslaunch.log", "threshing_sim record.launch scene:=" + scene +
                                              " bag:=" + g_dir +
                                              "/run.bag duration:=" + std::to_string(kRecorded_s));
  // Each time a feed command has been applied, the next one, while the run goes on: a stop, a
  // hostile value (refused, not recorded), a new rate.
  size_t sent = 1;
  for (double rate : {0.0, -5.0, 150.0}) {
    while (launch.running() && waitUnder(
                                   mutex, [&] { return applied.size() < sent; }, 1e-3, 1e-3))
      ros::WallDuration(1e-3).sleep();
    ros::WallDuration(0.3).sleep();  // some simulated time between the commands
    cmd.data = rate;
    feed.publish(cmd);
    if (rate >= 0) ++sent;
  }
  ASSERT_EQ(launch.wait(120), 0) << "record.launch did not end by itself";

  const std::string run_bag = g_dir + "/run.bag";
  const auto commands = messages<FeedRateCommand>(run_bag, "/feed_rate_cmd_applied");
  const auto throughput = messages<FeedThroughput>(run_bag, "/feed_throughput");
  ASSERT_GE(commands.size(), 2u) << "too few feed rate commands applied during the run";
  EXPECT_EQ(commands.front().header.stamp, ros::Time(0)) << "the latched command at t = 0";
  EXPECT_EQ(commands.front().rate_per_s, 300.0);
  for (const FeedRateCommand& c : commands) EXPECT_GE(c.rate_per_s, 0.0);
  EXPECT_EQ(throughput.size(), static_cast<size_t>(std::lround(kRecorded_s / 0.01)));
  for (const FeedThroughput& m : throughput) EXPECT_TRUE(balanced(m)) << m.end_time;
  ASSERT_FALSE(
      messages<threshing_sim::DrumSpeedCommand>(run_bag, "/drum_speed_cmd_applied").empty());

  Launch resim(g_dir + "/roslaunch.log", "threshing_sim resimulate.launch scene:=" + scene +
                                             " bag:=" + run_bag + " out:=" + g_dir + "/resim.bag");
  ASSERT_EQ(resim.wait(120), 0) << "resimulate.launch did not end by itself";
  const auto resim_commands =
      messages<FeedRateCommand>(g_dir + "/resim.bag", "/feed_rate_cmd_applied");
  EXPECT_EQ(resim_commands.size(), commands.size());
  std::string out;
  EXPECT_EQ(run(std::string(THRESHING_SIM_SOURCE_DIR) + "/scripts/compare_bags " + run_bag + " " +
                    g_dir + "/resim.bag",
                &out),
            0)
      << out;
  std::printf("%s", out.c_str());
  EXPECT_NE(out.find("/feed_throughput: 10 messages, bit-identical"), std::string::npos) << out;
  EXPECT_NE(out.find("/feed_rate_cmd_applied: " + std::to_string(commands.size()) +
                     " messages, bit-identical"),
            std::string::npos)
      << out;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_feed_node");
  ros::NodeHandle nh;
  char dir[] = "/tmp/threshing_sim_feed_XXXXXX";
  g_dir = mkdtemp(dir);
  std::vector<ros::Subscriber> subs;
  subs.push_back(
      listenUnder<FeedThroughput>(&nh, g_mutex, "/fed/feed_throughput", 1000,
                                  [](const FeedThroughput& m) { g_seen.throughput.push_back(m); }));
  subs.push_back(
      listenUnder<FeedRateCommand>(&nh, g_mutex, "/fed/feed_rate_cmd_applied", 100,
                                   [](const FeedRateCommand& m) { g_seen.applied.push_back(m); }));
  subs.push_back(listenUnder<threshing_sim::DrumState>(
      &nh, g_mutex, "/fed/drum_state", 1000,
      [](const threshing_sim::DrumState& m) { g_seen.drum.push_back(m); }));
  subs.push_back(listenUnder<diagnostic_msgs::DiagnosticArray>(
      &nh, g_mutex, "/diagnostics", 100, [](const diagnostic_msgs::DiagnosticArray& m) {
        for (const auto& status : m.status) {
          const std::string node = status.name.substr(0, status.name.find(':'));
          for (const auto& kv : status.values) g_seen.diagnostics[node][kv.key] = kv.value;
        }
      }));
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
