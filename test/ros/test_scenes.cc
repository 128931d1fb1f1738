// rostest (scenes.test), issue 24 "live = headless": every scene of config/scenes/,
// config/bench/ and config/hard/ runs in the node at real-time factor 0 to its duration
// (~end_time), ends by itself with exit status 0, and has `simulate`'s impact count and peak
// normal force, equal (both programs take the same integrator steps: neither cuts a step but at
// the run's end, advancePast), under the global scheme and under the island scheme.
// SCENES_MAX_DURATION caps the runs (default 1 s: only config/hard/10_long_run.yaml is longer).
// About 2.5 min for both schemes (the stream scene's 8 ms are most of it).
#include <dirent.h>
#include <gtest/gtest.h>
#include <ros/master.h>
#include <ros/network.h>
#include <ros/ros.h>
#include <xmlrpcpp/XmlRpcClient.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ros_test_util.h"

using threshing_sim::test::run;

namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The first top-level "key: number" of a YAML or JSON text; NaN if none.
double firstNumber(const std::string& text, const std::string& pattern) {
  std::smatch m;
  if (!std::regex_search(text, m, std::regex(pattern + "\\s*:\\s*([0-9.eE+-]+)"))) return NAN;
  return std::stod(m[1]);
}

// The scenes of a folder of the source tree (its *.yaml files, sorted).
std::vector<std::string> scenesIn(const std::string& folder) {
  std::vector<std::string> out;
  const std::string dir = std::string(THRESHING_SIM_SOURCE_DIR) + "/" + folder;
  DIR* d = opendir(dir.c_str());
  if (d == nullptr) return out;
  while (const dirent* e = readdir(d)) {
    const std::string name = e->d_name;
    if (name.size() > 5 && name.compare(name.size() - 5, 5, ".yaml") == 0)
      out.push_back(dir + "/" + name);
  }
  closedir(d);
  std::sort(out.begin(), out.end());
  return out;
}

struct Result {
  int status = -1;
  double impacts = NAN;
  double peak_N = NAN;
  std::string text;  // the output, on failure
};

Result runSimulate(const std::string& scene, double duration_s, const std::string& islands,
                   const std::string& tag) {
  Result r;
  const std::string json = std::string(TEST_TMP_DIR) + "/scenes_" + tag + ".json";
  std::remove(json.c_str());
  char duration[64];
  std::snprintf(duration, sizeof(duration), "%.17g", duration_s);
  r.status = run(std::string(THRESHING_SIM_SIMULATE) + " " + scene + " --set duration=" + duration +
                     " --set integrator.islands=" + islands + " --quiet --summary " + json,
                 &r.text);
  const std::string summary = slurp(json);
  r.impacts = firstNumber(summary, "\"impacts\"");
  r.peak_N = firstNumber(summary, "\"peak_normal_force_N\"");
  return r;
}

// The node over the scene's duration at factor 0: its exit status and its summary line's values.
Result runNode(const std::string& scene, double duration_s, const std::string& islands,
               const std::string& tag) {
  Result r;
  // The scheme named in the scene's integrator map (islands: true or false), as simulate's
  // --set names it: the node has no overrides, and the default is one of the two.
  std::string text = slurp(scene);
  // A scene naming the scheme already (a feed scene: islands: false) runs as it is.
  if (text.find("islands: " + islands) == std::string::npos) {
    const std::string before = text;
    text = std::regex_replace(text, std::regex("\\nintegrator: \\{"),
                              "\nintegrator: {islands: " + islands + ", ");
    text = std::regex_replace(text, std::regex("\\nintegrator:[ \t]*\\n"),
                              "\nintegrator:\n  islands: " + islands + "\n");
    if (text == before) text += "\nintegrator: {islands: " + islands + "}\n";
  }
  const std::string path = std::string(TEST_TMP_DIR) + "/scenes_" + tag + ".yaml";
  std::ofstream(path) << text;
  char end[64];
  std::snprintf(end, sizeof(end), "%.17g", duration_s);
  const std::string name = "scenes_" + tag;
  r.status =
      run("timeout -s INT 900 " + std::string(THRESHING_SIM_NODE) + " __name:=" + name +
              " _scene:=" + path + " _clock_mode:=wall _real_time_factor:=0 _end_time:=" + end +
              " _status_period:=0 _diagnostic_period:=1 _strike_frames:=false",
          &r.text);
  // Its summary line: "..., N impacts, peak normal force F N, ..." (F with all 17 digits).
  std::smatch m;
  if (std::regex_search(r.text, m,
                        std::regex("([0-9]+) impacts, peak normal force ([0-9.eE+-]+) N"))) {
    r.impacts = std::stod(m[1]);
    r.peak_N = std::stod(m[2]);
  }
  return r;
}

// The longest run the test makes [s]: SCENES_MAX_DURATION, else 1 s (every scene runs to its
// duration but config/hard/10_long_run.yaml, 750 s, which CI runs for 1 s: 13 revolutions, its
// strikes and the kernels' flights and landings).
double maxDuration() {
  const char* env = std::getenv("SCENES_MAX_DURATION");
  return env != nullptr ? std::stod(env) : 1.0;
}

void expectEveryScene(const std::string& islands) {
  std::vector<std::string> scenes;
  for (const char* folder : {"config/scenes", "config/bench", "config/hard"})
    for (const std::string& s : scenesIn(folder)) scenes.push_back(s);
  ASSERT_GE(scenes.size(), 17u);
  int n = 0;
  for (const std::string& scene : scenes) {
    const double scene_duration_s = firstNumber(slurp(scene), "\\nduration");
    ASSERT_TRUE(scene_duration_s > 0) << scene;
    // A feed scene (a `feed` section, core/feed.h) runs the global scheme only: both programs
    // update the feed at the first step end past each kFeedUpdateStep_s (issue 34).
    if (islands == "true" && slurp(scene).find("\nfeed:") != std::string::npos) continue;
    const double duration_s = std::min(scene_duration_s, maxDuration());
    const std::string tag = "s" + std::to_string(n++) + (islands == "true" ? "i" : "g");
    Result sim;
    std::thread simulate([&] { sim = runSimulate(scene, duration_s, islands, tag); });
    const ros::WallTime started = ros::WallTime::now();
    const Result node = runNode(scene, duration_s, islands, tag);
    simulate.join();
    std::printf(
        "%-40s islands %-5s %8.4g s: node %4.0f impacts, peak %.17g N; simulate %4.0f, "
        "%.17g N (%.1f s wall)\n",
        scene.substr(scene.rfind("config/")).c_str(), islands.c_str(), duration_s, node.impacts,
        node.peak_N, sim.impacts, sim.peak_N, (ros::WallTime::now() - started).toSec());
    std::fflush(stdout);
    EXPECT_EQ(sim.status, 0) << scene << "\n" << sim.text;
    EXPECT_EQ(node.status, 0) << scene << "\n" << node.text;
    EXPECT_EQ(node.impacts, sim.impacts) << scene;
    EXPECT_DOUBLE_EQ(node.peak_N, sim.peak_N) << scene;
  }
}

TEST(Scenes, EverySceneInTheNodeAsInSimulate) { expectEveryScene("false"); }

TEST(Scenes, EverySceneInTheNodeAsInSimulateUnderIslands) { expectEveryScene("true"); }

}  // namespace

int main(int argc, char** argv) {
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_scenes");
  ros::NodeHandle nh;
  const int result = RUN_ALL_TESTS();
  ros::shutdown();
  return result;
}
