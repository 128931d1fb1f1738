// rostest (launch.test): the node and the launch files as a user runs them, each started as a
// process against this test's master, one after another:
//  - bad parameters are refused with a message naming them and a non-zero exit;
//  - record.launch records a bounded run while drum speed commands arrive;
//  - replay.launch plays the bag back: the same message counts (markers: the strike frames
//    that ride in one message come out one by one), monotonic stamps;
//  - resimulate.launch re-runs the recorded commands: contact_state and impact_events are
//    bit-identical (scripts/compare_bags).
// The tests run in declaration order and share the bags.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <rosgraph_msgs/Clock.h>
#include <signal.h>
#include <std_msgs/Float64.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <tf2_msgs/TFMessage.h>
#include <topic_tools/shape_shifter.h>
#include <unistd.h>
#include <visualization_msgs/MarkerArray.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "ros_test_util.h"
#include "threshing_sim/BeamShapeArray.h"
#include "threshing_sim/ContactStateArray.h"
#include "threshing_sim/DrumSpeedCommand.h"
#include "threshing_sim/ImpactEvent.h"
#include "threshing_sim/KernelStateArray.h"

using threshing_sim::test::Launch;
using threshing_sim::test::run;

namespace {

std::string g_dir;  // scratch directory of this test run

// Issue 24: a normal end of a launch is quiet. roslaunch printed a red "REQUIRED process
// [...] has died!" at every normal end of record, replay and resimulate.
void expectQuietEnd(const std::string& what) {
  std::ifstream in(g_dir + "/roslaunch.log");
  std::stringstream text;
  text << in.rdbuf();
  EXPECT_EQ(text.str().find("has died"), std::string::npos) << what << ":\n" << text.str();
}

// A bad value: exit status 1 and a message naming the parameter. Each run has its own node
// name, so that no private parameter of a previous run is left over.
void expectRefused(const std::string& args, const std::string& named) {
  static int run_index = 0;
  const std::string name = " __name:=refused_" + std::to_string(++run_index) + " ";
  std::string out;
  EXPECT_EQ(run(std::string(THRESHING_SIM_NODE) + name + args, &out), 1) << out;
  EXPECT_NE(out.find(named), std::string::npos) << "message does not name " << named << ":\n"
                                                << out;
}

TEST(Launch, RefusesBadParameters) {
  const std::string scene = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/default_scene.yaml";
  const std::string ok = " _clock_mode:=sim _scene:=";
  expectRefused("_clock_mode:=simulated", "~clock_mode");
  expectRefused(ok + scene + " _real_time_factor:=-1", "~real_time_factor");
  expectRefused(ok + scene + " _max_drum_speed:=0", "~max_drum_speed");
  expectRefused(ok + scene + " _physics_dt:=0.1", "~physics_dt");
  expectRefused(ok + scene + " _marker_rate:=0", "~marker_rate");
  expectRefused(ok + g_dir + "/missing.yaml", "~scene");
  // A scene value: the scene loader's message names the key.
  std::ifstream in(scene);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const size_t mass = text.find("mass: 2.8e-5");
  ASSERT_NE(mass, std::string::npos);
  text.replace(mass, 12, "mass: -1.0");
  std::ofstream(g_dir + "/bad_scene.yaml") << text;
  expectRefused(ok + g_dir + "/bad_scene.yaml", "mass");
}

// Header stamps of one topic in bag order.
template <typename M>
std::vector<ros::Time> stamps(const rosbag::Bag& bag, const std::string& topic) {
  std::vector<ros::Time> out;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery(topic)))
    out.push_back(m.instantiate<M>()->header.stamp);
  return out;
}

void expectMonotonic(const std::vector<ros::Time>& t, const std::string& what) {
  for (size_t i = 1; i < t.size(); ++i)
    ASSERT_LE(t[i - 1], t[i]) << what << " stamp " << i << " goes back";
}

std::map<std::string, long> countsByTopic(const std::string& path) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  std::map<std::string, long> counts;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) ++counts[m.getTopic()];
  return counts;
}

// The markers messages a replay sends for a bag: play_bag splits a message whose markers carry
// several stamps (a strike's frames ride with the next boundary's markers) into one per run of
// equal stamps.
long replayedMarkerMessages(const std::string& path) {
  rosbag::Bag bag(path, rosbag::bagmode::Read);
  long n = 0;
  for (const rosbag::MessageInstance& m :
       rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{"/markers"}))) {
    const auto msg = m.instantiate<visualization_msgs::MarkerArray>();
    if (!msg) continue;
    for (size_t i = 0; i < msg->markers.size(); ++i)
      n += i == 0 || msg->markers[i].header.stamp != msg->markers[i - 1].header.stamp;
    n += msg->markers.empty();
  }
  return n;
}

// A bounded run at real_time_factor 0 in sim clock mode, with speed commands sent while it
// runs; everything lands in run.bag. Each command goes out once the one before it has been
// applied, so the run must outlast two round trips through the test's own thread: at 2 s of
// simulated time it lasted about 0.12 s of wall time under the island scheme (the default scene
// at factor 0 simulates 1 s in 0.06 s, scripts/measure_node_rtf.sh), and under a heavy load the
// second command could land after the end. 8 s (about 0.5 s of wall time) gives them four
// times as long.
constexpr int kRecordedRun_s = 8;  // simulated time of the recorded run [s]

TEST(Launch, RecordsABoundedRun) {
  ros::NodeHandle nh;
  std::mutex mutex;
  long applied = 0;
  ros::Subscriber sub = nh.subscribe<threshing_sim::DrumSpeedCommand>(
      "/drum_speed_cmd_applied", 10,
      boost::function<void(const threshing_sim::DrumSpeedCommand::ConstPtr&)>(
          [&](const threshing_sim::DrumSpeedCommand::ConstPtr&) {
            std::lock_guard<std::mutex> lock(mutex);
            ++applied;
          }));
  ros::Publisher pub = nh.advertise<std_msgs::Float64>("/drum_speed_cmd", 1, true);
  std_msgs::Float64 cmd;
  cmd.data = 60.0;
  pub.publish(cmd);

  Launch launch(g_dir + "/roslaunch.log",
                "threshing_sim record.launch bag:=" + g_dir +
                    "/run.bag duration:=" + std::to_string(kRecordedRun_s));
  // Each time a command has been applied, the next one, while the run goes on.
  long sent = 1;
  for (double speed : {100.0, 70.0}) {
    auto appliedSoFar = [&] {
      std::lock_guard<std::mutex> lock(mutex);
      return applied;
    };
    while (launch.running() && appliedSoFar() < sent) ros::WallDuration(1e-3).sleep();
    cmd.data = speed;
    pub.publish(cmd);
    ++sent;
  }
  ASSERT_EQ(launch.wait(60), 0) << "record.launch did not end by itself";
  expectQuietEnd("record.launch");

  rosbag::Bag bag(g_dir + "/run.bag", rosbag::bagmode::Read);
  const auto contact = stamps<threshing_sim::ContactStateArray>(bag, "/contact_state");
  const auto impacts = stamps<threshing_sim::ImpactEvent>(bag, "/impact_events");
  const auto commands = stamps<threshing_sim::DrumSpeedCommand>(bag, "/drum_speed_cmd_applied");
  ASSERT_FALSE(contact.empty());
  EXPECT_EQ(contact.back(), ros::Time(kRecordedRun_s)) << "the run ends at ~end_time";
  EXPECT_GE(impacts.size(), 1u);
  // The first command is applied at t = 0, the next ones while the run goes on.
  ASSERT_GE(commands.size(), 2u);
  EXPECT_GT(commands.back(), ros::Time(0));
  expectMonotonic(contact, "contact_state");
  expectMonotonic(impacts, "impact_events");
  expectMonotonic(commands, "drum_speed_cmd_applied");
  expectMonotonic(stamps<threshing_sim::KernelStateArray>(bag, "/kernel_states"), "kernel_states");
  expectMonotonic(stamps<threshing_sim::BeamShapeArray>(bag, "/beam_shape"), "beam_shape");
  std::vector<ros::Time> clock, drum_tf;
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/clock")))
    clock.push_back(m.instantiate<rosgraph_msgs::Clock>()->clock);
  for (const rosbag::MessageInstance& m : rosbag::View(bag, rosbag::TopicQuery("/tf")))
    for (const auto& t : m.instantiate<tf2_msgs::TFMessage>()->transforms)
      if (t.child_frame_id == "drum") drum_tf.push_back(t.header.stamp);
  EXPECT_FALSE(clock.empty());
  expectMonotonic(clock, "/clock");
  expectMonotonic(drum_tf, "world->drum");
  const auto counts = countsByTopic(g_dir + "/run.bag");
  for (const char* topic : {"/beam_shape", "/kernel_states", "/markers", "/tf", "/tf_static",
                            "/diagnostics", "/drum_speed_cmd"})
    EXPECT_GT(counts.count(topic) ? counts.at(topic) : 0, 0) << topic;
}

// replay.launch (no simulator, no rviz) delivers every recorded message of every topic.
TEST(Launch, ReplaysWithTheSameCounts) {
  auto counts = countsByTopic(g_dir + "/run.bag");
  ASSERT_FALSE(counts.empty());
  counts.erase("/clock");  // rosbag play publishes its own /clock instead
  const long recorded_markers = counts["/markers"];
  counts["/markers"] = replayedMarkerMessages(g_dir + "/run.bag");
  std::printf("/markers: %ld messages recorded, %ld replayed (the strike's frames split)\n",
              recorded_markers, counts["/markers"]);
  EXPECT_GT(counts["/markers"], recorded_markers) << "the recording holds no strike frames";

  ros::NodeHandle nh;
  std::mutex mutex;
  std::map<std::string, long> received;
  bool clock_went_back = false;
  ros::Time last_clock;
  std::vector<ros::Subscriber> subs;
  for (const auto& [topic, n] : counts) {
    const std::string name = topic;
    subs.push_back(nh.subscribe<topic_tools::ShapeShifter>(
        name, 10000,
        boost::function<void(const topic_tools::ShapeShifter::ConstPtr&)>(
            [&, name](const topic_tools::ShapeShifter::ConstPtr&) {
              std::lock_guard<std::mutex> lock(mutex);
              ++received[name];
            })));
  }
  subs.push_back(nh.subscribe<rosgraph_msgs::Clock>(
      "/clock", 1000,
      boost::function<void(const rosgraph_msgs::Clock::ConstPtr&)>(
          [&](const rosgraph_msgs::Clock::ConstPtr& m) {
            std::lock_guard<std::mutex> lock(mutex);
            clock_went_back |= m->clock < last_clock;
            last_clock = m->clock;
          })));

  Launch launch(g_dir + "/roslaunch.log",
                "threshing_sim replay.launch rviz:=false wait_for_subscribers:=true bag:=" + g_dir +
                    "/run.bag");
  ASSERT_EQ(launch.wait(60), 0) << "replay.launch did not end by itself";
  expectQuietEnd("replay.launch");
  ros::WallDuration(1.0).sleep();  // the last messages in flight
  std::lock_guard<std::mutex> lock(mutex);
  for (const auto& [topic, n] : counts) EXPECT_EQ(received[topic], n) << topic;
  EXPECT_FALSE(clock_went_back);
}

// resimulate.launch re-applies the recorded commands at their step boundaries: contact_state
// and impact_events come out bit for bit the same.
TEST(Launch, ResimulatesBitForBit) {
  Launch launch(g_dir + "/roslaunch.log", "threshing_sim resimulate.launch bag:=" + g_dir +
                                              "/run.bag out:=" + g_dir + "/resim.bag");
  ASSERT_EQ(launch.wait(60), 0) << "resimulate.launch did not end by itself";
  expectQuietEnd("resimulate.launch");
  const auto run_counts = countsByTopic(g_dir + "/run.bag");
  const auto resim_counts = countsByTopic(g_dir + "/resim.bag");
  EXPECT_EQ(run_counts.at("/drum_speed_cmd_applied"),
            resim_counts.count("/drum_speed_cmd_applied")
                ? resim_counts.at("/drum_speed_cmd_applied")
                : 0);
  std::string out;
  EXPECT_EQ(run(std::string(THRESHING_SIM_SOURCE_DIR) + "/scripts/compare_bags " + g_dir +
                    "/run.bag " + g_dir + "/resim.bag",
                &out),
            0)
      << out;
  std::printf("%s", out.c_str());
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_launch");
  ros::NodeHandle nh;
  char dir[] = "/tmp/threshing_sim_test_XXXXXX";
  g_dir = mkdtemp(dir);
  ros::AsyncSpinner spinner(2);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
