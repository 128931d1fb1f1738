// rostest (recipe.test): the record / replay / re-simulate recipe of docs/ros_interface.md (the
// block between its record-recipe markers), run verbatim as a bash script from the source
// directory, with rviz on an Xvfb display, against this test's master. It must exit 0
// (compare_bags: the re-simulation is bit-identical), the recorded bag must hold the strike
// history and the impact, and the replay must show the strike: rviz is sent the strike chart by
// rosbag play, and a screenshot then shows the chart's force curve.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <visualization_msgs/MarkerArray.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <future>
#include <sstream>
#include <string>
#include <vector>

namespace {

const char* const kDisplay = ":64";

// The recipe block of docs/ros_interface.md, without its ``` fence lines.
std::string recipe() {
  std::ifstream in(std::string(THRESHING_SIM_SOURCE_DIR) + "/docs/ros_interface.md");
  std::stringstream text;
  text << in.rdbuf();
  const std::string s = text.str();
  const std::string begin = "<!-- record-recipe -->", end = "<!-- record-recipe-end -->";
  const size_t a = s.find(begin), b = s.find(end);
  if (a == std::string::npos || b == std::string::npos) return "";
  std::stringstream block(s.substr(a + begin.size(), b - a - begin.size()));
  std::string line, out;
  while (std::getline(block, line))
    if (line.rfind("```", 0) != 0) out += line + "\n";
  return out;
}

int run(const std::string& cmd, std::string* output) {
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (!p) return -1;
  char buf[4096];
  while (fgets(buf, sizeof(buf), p)) *output += buf;
  const int status = pclose(p);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

long orangePixels(const std::string& png) {
  const std::string ppm = png + ".ppm";
  if (std::system(("convert " + png + " " + ppm).c_str()) != 0) return -1;
  std::ifstream in(ppm, std::ios::binary);
  std::string magic;
  int w = 0, h = 0, maxval = 0;
  in >> magic >> w >> h >> maxval;
  in.get();
  std::vector<unsigned char> rgb(3 * w * h);
  in.read(reinterpret_cast<char*>(rgb.data()), rgb.size());
  std::remove(ppm.c_str());
  long n = 0;
  for (size_t i = 0; i + 2 < rgb.size(); i += 3)
    n += rgb[i] > 230 && std::abs(rgb[i + 1] - 115) < 25 && rgb[i + 2] < 30;
  return n;
}

TEST(Recipe, RecordReplayResimulateVerbatim) {
  const std::string script = recipe();
  ASSERT_FALSE(script.empty()) << "docs/ros_interface.md has no record-recipe block";
  const std::string path = std::string(TEST_TMP_DIR) + "/readme_recipe.sh";
  std::ofstream(path) << "set -euo pipefail\n" << script;
  std::remove("/tmp/run.bag");
  std::remove("/tmp/resim.bag");

  // The strike chart, as rosbag play (node /play) sends it to rviz during the replay.
  ros::NodeHandle nh;
  std::atomic<bool> chart_replayed{false};
  ros::Subscriber sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/markers", 100,
      boost::function<void(const ros::MessageEvent<visualization_msgs::MarkerArray const>&)>(
          [&](const ros::MessageEvent<visualization_msgs::MarkerArray const>& e) {
            if (e.getPublisherName() != "/play") return;
            for (const auto& m : e.getMessage()->markers)
              if (m.ns == "strike_chart" && m.points.size() > 10) chart_replayed = true;
          }));

  std::string output;
  auto done = std::async(std::launch::async, [&] {
    return run(std::string("cd ") + THRESHING_SIM_SOURCE_DIR + " && xvfb-run -n " +
                   std::string(kDisplay + 1) + " -s '-screen 0 1400x900x24 -ac' bash " + path,
               &output);
  });
  // Screenshot of the replay once rviz has been sent the strike chart, again every 1.5 s while
  // the replay runs until the chart shows (rviz may still be drawing its first frames when the
  // first chart arrives).
  const std::string png = std::string(SCREENSHOT_DIR) + "/replay_screenshot.png";
  long orange = -1;
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(150);
  while (ros::WallTime::now() < end &&
         done.wait_for(std::chrono::milliseconds(50)) != std::future_status::ready) {
    if (chart_replayed && orange <= 100) {
      ros::WallDuration(1.5).sleep();
      if (std::system(
              ("import -display " + std::string(kDisplay) + " -window root " + png).c_str()) == 0)
        orange = orangePixels(png);
    }
  }
  ASSERT_EQ(done.wait_for(std::chrono::seconds(60)), std::future_status::ready) << "recipe hangs";
  const int status = done.get();
  std::printf("%s\n", output.substr(output.size() > 3000 ? output.size() - 3000 : 0).c_str());
  EXPECT_EQ(status, 0) << "the recipe failed";
  EXPECT_NE(output.find("/strike_history: 3 messages, bit-identical"), std::string::npos);
  EXPECT_NE(output.find("/drum_speed_cmd_applied: 1 messages, bit-identical"), std::string::npos);
  EXPECT_TRUE(chart_replayed) << "the replay sent no strike chart";
  std::printf("replay screenshot %s: strike chart curve %ld px\n", png.c_str(), orange);
  EXPECT_GT(orange, 100) << "the replay's screenshot shows no strike chart";

  // The recording: strike histories, impacts, the scene and the applied command.
  rosbag::Bag bag("/tmp/run.bag", rosbag::bagmode::Read);
  std::map<std::string, long> counts;
  for (const rosbag::MessageInstance& m : rosbag::View(bag)) ++counts[m.getTopic()];
  EXPECT_EQ(counts["/strike_history"], 3);
  EXPECT_EQ(counts["/impact_events"], 3);
  EXPECT_EQ(counts["/scene_yaml"], 1);
  EXPECT_EQ(counts["/static_markers"], 1);
  EXPECT_EQ(counts["/drum_speed_cmd_applied"], 1);
}

// compare_bags passes when both bags lack a topic, and fails when the runs differ in their scene
// record: a re-simulation of the recipe's bag without its loop (loop_revolutions 0).
TEST(Recipe, CompareBagsChecksTheSceneRecord) {
  const std::string compare = std::string(THRESHING_SIM_SOURCE_DIR) + "/scripts/compare_bags";
  std::string out;
  EXPECT_EQ(
      run(compare + " /tmp/run.bag /tmp/resim.bag --topics /no_such_topic /strike_history", &out),
      0)
      << out;
  EXPECT_NE(out.find("/no_such_topic: in neither bag"), std::string::npos) << out;
  out.clear();
  ASSERT_EQ(run("roslaunch threshing_sim resimulate.launch bag:=/tmp/run.bag "
                "out:=/tmp/resim_noloop.bag",
                &out),
            0)
      << out;
  out.clear();
  EXPECT_EQ(run(compare + " /tmp/run.bag /tmp/resim_noloop.bag", &out), 1) << out;
  EXPECT_NE(out.find("/scene_yaml: the bags hold different scenes or node settings"),
            std::string::npos)
      << out;
}

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_recipe");
  ros::AsyncSpinner spinner(1);
  spinner.start();
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
