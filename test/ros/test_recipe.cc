// rostest (recipe.test): the record / replay / re-simulate recipe of docs/ros_interface.md (the
// block between its record-recipe markers), run verbatim as a bash script from the source
// directory, with rviz on an Xvfb display, against this test's master. It must exit 0
// (compare_bags: the re-simulation is bit-identical), the recorded bag must hold the strike
// history and the impact, and the replay must show the strike: rviz is sent the strike chart by
// rosbag play, and a screenshot then shows the chart's force curve.
//
// Replays that move (issue 24): during every recorded tooth-kernel contact (from the first to the
// last sample of its strike history in the bag) the replay must
// send rviz at least 20 marker frames that differ in the tooth's or the kernel's pose, each on
// screen at least one rviz frame (1/30 s of wall time) before the next; five screenshots taken
// through the second strike (replay_strike_<i>.png, in the test results) must each show the
// tooth and another frame, and differ from the one before.
#include <gtest/gtest.h>
#include <ros/ros.h>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <threshing_sim/StrikeHistory.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <future>
#include <iomanip>
#include <mutex>
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

// The RGB pixels of a PNG (empty if it cannot be read).
std::vector<unsigned char> readRgb(const std::string& png) {
  const std::string ppm = png + ".ppm";
  if (std::system(("convert " + png + " " + ppm).c_str()) != 0) return {};
  std::ifstream in(ppm, std::ios::binary);
  std::string magic;
  int w = 0, h = 0, maxval = 0;
  in >> magic >> w >> h >> maxval;
  in.get();
  std::vector<unsigned char> rgb(3 * w * h);
  in.read(reinterpret_cast<char*>(rgb.data()), rgb.size());
  std::remove(ppm.c_str());
  return rgb;
}

// Pixels that differ between two screenshots of one size (-1: sizes differ or unreadable).
long differingPixels(const std::vector<unsigned char>& a, const std::vector<unsigned char>& b) {
  if (a.empty() || a.size() != b.size()) return -1;
  long n = 0;
  for (size_t i = 0; i + 2 < a.size(); i += 3)
    n += a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2];
  return n;
}

// A replayed marker message that draws the moving bodies: its stamp, when it arrived, and the
// tooth's centreline and the kernels' poses as text.
struct Frame {
  double stamp_s = 0;
  double wall_s = 0;
  std::string bodies;
};

// The moving bodies of a marker message ("" when it draws none).
std::string bodiesOf(const visualization_msgs::MarkerArray& msg) {
  std::ostringstream out;
  out << std::setprecision(9);
  for (const auto& m : msg.markers) {
    if (m.ns == "teeth")
      for (const auto& p : m.points) out << p.x << ',' << p.y << ' ';
    if (m.ns == "kernels")
      out << m.pose.position.x << ',' << m.pose.position.y << ',' << m.pose.orientation.z << ' ';
  }
  return out.str();
}

long orangePixels(const std::string& png) {
  const std::vector<unsigned char> rgb = readRgb(png);
  if (rgb.empty()) return -1;
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

  std::mutex mutex;
  // Every replayed marker message that draws the moving bodies.
  std::vector<Frame> frames;
  ros::Subscriber frame_sub = nh.subscribe<visualization_msgs::MarkerArray>(
      "/markers", 1000,
      boost::function<void(const ros::MessageEvent<visualization_msgs::MarkerArray const>&)>(
          [&](const ros::MessageEvent<visualization_msgs::MarkerArray const>& e) {
            if (e.getPublisherName() != "/play" || e.getMessage()->markers.empty()) return;
            Frame f{e.getMessage()->markers.front().header.stamp.toSec(),
                    ros::WallTime::now().toSec(), bodiesOf(*e.getMessage())};
            if (f.bodies.empty()) return;
            std::lock_guard<std::mutex> lock(mutex);
            frames.push_back(std::move(f));
          }));
  // Whether the replay is inside the second strike (t = 76 ms; the first comes 0.3 ms into
  // the recording, while rviz may still be starting on a loaded machine): the two newest
  // frames are less than a physics step (10 us) apart, which only the frames of a strike are
  // (the marker schedule is 33 ms).
  auto inStrike = [&] {
    std::lock_guard<std::mutex> lock(mutex);
    const size_t n = frames.size();
    return n >= 2 && frames[n - 1].stamp_s > 0.05 &&
           frames[n - 1].stamp_s - frames[n - 2].stamp_s < 1e-5;
  };

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
  // Five screenshots through the second strike, each of another frame, about 0.3 s apart (the
  // strike plays for about 2 s at replay.launch's strike_rate).
  const int kStrikeShots = 5;
  std::vector<std::string> strike_pngs;
  std::vector<std::string> strike_bodies;  // the newest replayed frame at each screenshot
  while (ros::WallTime::now() < end &&
         done.wait_for(std::chrono::milliseconds(20)) != std::future_status::ready) {
    if (strike_pngs.empty() && inStrike()) {
      // Each screenshot waits (at most 1 s) for a frame it has not shown yet, and for rviz to
      // draw it (two of its frames at 30 fps).
      std::string shown;
      for (int i = 0; i < kStrikeShots; ++i) {
        const ros::WallTime give_up = ros::WallTime::now() + ros::WallDuration(1.0);
        std::string newest;
        while (ros::WallTime::now() < give_up) {
          {
            std::lock_guard<std::mutex> lock(mutex);
            newest = frames.back().bodies;
          }
          if (newest != shown) break;
          ros::WallDuration(0.005).sleep();
        }
        ros::WallDuration(0.07).sleep();
        const std::string shot =
            std::string(SCREENSHOT_DIR) + "/replay_strike_" + std::to_string(i) + ".png";
        strike_bodies.push_back(newest);
        shown = newest;
        if (std::system(
                ("import -display " + std::string(kDisplay) + " -window root " + shot).c_str()) ==
            0)
          strike_pngs.push_back(shot);
        ros::WallDuration(0.15).sleep();
      }
    }
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

  // Frames per strike: replayed marker messages stamped within the contact (the first to the
  // last sample of its recorded strike history) whose bodies differ from the frame before, and
  // of those the ones rviz had at least 1/30 s of wall time to draw before the next.
  std::vector<std::pair<double, double>> strikes;
  {
    rosbag::Bag bag("/tmp/run.bag", rosbag::bagmode::Read);
    for (const rosbag::MessageInstance& m :
         rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{"/strike_history"}))) {
      const auto h = m.instantiate<threshing_sim::StrikeHistory>();
      if (h && !h->time.empty()) strikes.emplace_back(h->time.front(), h->time.back());
    }
  }
  {
    std::lock_guard<std::mutex> lock(mutex);
    ASSERT_EQ(strikes.size(), 3u) << "the recording holds " << strikes.size() << " strikes";
    for (const auto& [first_s, last_s] : strikes) {
      std::vector<const Frame*> in_strike;
      for (size_t i = 0; i < frames.size(); ++i)
        if (frames[i].stamp_s >= first_s && frames[i].stamp_s <= last_s &&
            (i == 0 || frames[i].bodies != frames[i - 1].bodies))
          in_strike.push_back(&frames[i]);
      long shown = 0;
      for (size_t i = 0; i < in_strike.size(); ++i) {
        const auto next = std::find_if(frames.begin(), frames.end(), [&](const Frame& f) {
          return f.wall_s > in_strike[i]->wall_s;
        });
        shown += next == frames.end() || next->wall_s - in_strike[i]->wall_s >= 1.0 / 30;
      }
      const double wall_s =
          in_strike.empty() ? 0 : in_strike.back()->wall_s - in_strike.front()->wall_s;
      std::printf(
          "strike %.6f..%.6f s: %zu frames with the bodies moved, %ld on screen >= 1/30 s, "
          "over %.2f s of wall time\n",
          first_s, last_s, in_strike.size(), shown, wall_s);
      EXPECT_GE(shown, 20) << "the strike at " << first_s << " s shows " << shown << " frames";
    }
  }
  // The screenshots through the strike: each shows the tooth (blue) and another frame and
  // another picture than the one before.
  ASSERT_EQ(strike_pngs.size(), static_cast<size_t>(kStrikeShots))
      << "no screenshots in the strike";
  std::vector<std::vector<unsigned char>> shots;
  for (const std::string& png : strike_pngs) shots.push_back(readRgb(png));
  for (int i = 0; i < kStrikeShots; ++i) {
    long blue = 0;  // the tooth's colour, rgba(0.3, 0.6, 1)
    for (size_t j = 0; j + 2 < shots[i].size(); j += 3)
      blue += std::abs(shots[i][j] - 77) < 20 && std::abs(shots[i][j + 1] - 153) < 20 &&
              shots[i][j + 2] > 230;
    std::printf("replay_strike_%d.png: tooth %ld px\n", i, blue);
    EXPECT_GT(blue, 200) << "replay_strike_" << i << ".png shows no tooth";
  }
  for (int i = 1; i < kStrikeShots; ++i) {
    const long diff = differingPixels(shots[i - 1], shots[i]);
    std::printf("replay_strike_%d.png vs replay_strike_%d.png: %ld pixels differ\n", i - 1, i,
                diff);
    EXPECT_GT(diff, 0) << "screenshots " << i - 1 << " and " << i << " of the strike are equal";
    EXPECT_NE(strike_bodies[i - 1], strike_bodies[i]) << "no new frame between screenshots";
  }

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
