// Hostile scene inputs and command lines (issue 14, defects 5-7): values the loader used to
// accept and the integrator then could not run in bounded work are scene errors naming the key;
// 10,000 kernels load in well under a second; simulate refuses empty option values, directories
// and empty scenes with exit 2 and fails runs that simulated nothing with exit 1.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "script_test_util.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

const std::string kDefaultScene =
    std::string(THRESHING_SIM_SOURCE_DIR) + "/config/default_scene.yaml";

// The SceneError message of loading the default scene with the overrides ("" if it loads).
std::string refusal(const std::vector<std::string>& overrides,
                    const std::string& path = kDefaultScene) {
  try {
    loadScene(path, overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// The simulate hang inputs (> 20 s at --duration 1e-4 before): each a scene error naming
// its key now. density 1e-300 failed at t = 0 (exit 1) instead.
TEST(HostileScene, HangInputsAreSceneErrorsNamingTheKey) {
  const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
      {{"kernels.0.velocity=[1e300, 0]"}, "kernels.0.velocity"},
      {{"gravity=[0, -1e308]"}, "gravity"},
      {{"drum.radius=1e300"}, "drum.radius"},
      {{"teeth.*.modes=0", "drum.speed=1e300"}, "drum.speed"},
      {{"integrator.max_step=1e-300"}, "integrator.max_step"},
      {{"integrator.tolerance=1e-300"}, "integrator.tolerance"},
      {{"integrator.type=time_stepping", "integrator.dt=1e-300"}, "integrator.dt"},
      {{"integrator.dt=1e300"}, "integrator.dt"},
      {{"duration=1e300"}, "duration"},
      {{"kernels.0.pedicel={anchor: [0.235, 0.03], rest_length: 1e200}"},
       "kernels.0.pedicel.rest_length"},
      {{"teeth.0.density=1e-300"}, "teeth.0.density"},
  };
  for (const auto& c : cases) {
    const std::string message = refusal(c.first);
    EXPECT_NE(message.find(c.second + ": "), std::string::npos)
        << c.first.back() << " -> '" << message << "'";
  }
  // The ranges are generous: the config scenes' values load.
  EXPECT_EQ(refusal({"kernels.0.velocity=[30, -5]", "drum.speed=150", "integrator.dt=1e-6"}), "");
}

// The core holds at most 65 centreline stations (compileModel); the loader's range says so.
TEST(HostileScene, StationsRangeIsTheCoresRange) {
  EXPECT_EQ(refusal({"teeth.0.stations=65"}), "");
  EXPECT_NE(refusal({"teeth.0.stations=66"}).find("teeth.0.stations: must be in [2, 65]"),
            std::string::npos);
}

// An empty file and a scalar are refused with or without overrides; a directory names itself.
TEST(HostileScene, EmptyScalarAndDirectoryScenesAreRefused) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "hostile_scenes";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "empty.yaml").close();
  std::ofstream(dir / "scalar.yaml") << "42\n";
  for (const char* name : {"empty.yaml", "scalar.yaml"}) {
    const std::string path = (dir / name).string();
    EXPECT_NE(refusal({}, path).find("expected a mapping"), std::string::npos) << name;
    EXPECT_NE(refusal({"duration=0.1"}, path).find("expected a mapping"), std::string::npos)
        << name;
  }
  EXPECT_NE(refusal({}, dir.string()).find("is a directory"), std::string::npos);
  try {
    overridesFromFile(dir.string());
    ADD_FAILURE() << "a directory as override file was read";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("is a directory"), std::string::npos) << e.what();
  }
}

// stream.count 10000 (the documented maximum) on a 5.26 m circle: the start-overlap test used
// O(n^2) ellipse tests (minutes); through the grid it is O(n), well under a second.
TEST(HostileScene, TenThousandKernelsLoadInUnderASecond) {
  const auto t0 = std::chrono::steady_clock::now();
  const Model m =
      loadScene(kDefaultScene, {"obstacles=[]",
                                "stream={count: 10000, rate: 140000, start: 0, depth: -5, "
                                "position_scatter: 0, angle_scatter: 0}"});
  const double wall_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  RecordProperty("load_wall_s", std::to_string(wall_s));
  EXPECT_EQ(m.kernels.size(), 10001u);
  EXPECT_LT(wall_s, 1.0);
}

// The key table of the reference page is the schema's output, character for character
// (regenerate: scripts/scene_reference.sh, which splices simulate --print-schema).
TEST(HostileScene, SchemaReferencePageIsCurrent) {
  const std::string page =
      test::readFile(std::string(THRESHING_SIM_SOURCE_DIR) + "/docs/scene_reference.md");
  const std::string begin = "<!-- scene-reference -->\n", end = "<!-- scene-reference-end -->";
  const size_t i = page.find(begin), j = page.find(end);
  ASSERT_NE(i, std::string::npos);
  ASSERT_NE(j, std::string::npos);
  EXPECT_EQ(page.substr(i + begin.size(), j - i - begin.size()), sceneSchemaTable())
      << "docs/scene_reference.md is out of date: regenerate it with scripts/scene_reference.sh";
}

// ---------------------------------------------------------------------------------------------
// simulate's command line.

// Exit status of simulate with the arguments (stderr to *err).
int simulate(const std::string& args, std::string* err = nullptr) {
  const std::string log =
      (std::filesystem::temp_directory_path() / "hostile_simulate.log").string();
  const int rc = std::system(
      (std::string(THRESHING_SIM_SIMULATE) + " " + args + " --quiet > /dev/null 2> " + log)
          .c_str());
  if (err) *err = test::readFile(log);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

TEST(HostileCommandLine, EmptyOptionValuesAreRefused) {
  std::string err;
  EXPECT_EQ(simulate(kDefaultScene + " --trace-every ''", &err), 2);
  EXPECT_NE(err.find("--trace-every"), std::string::npos) << err;
  EXPECT_EQ(simulate(kDefaultScene + " --sample-interval ''", &err), 2);
  EXPECT_NE(err.find("--sample-interval"), std::string::npos) << err;
}

TEST(HostileCommandLine, DirectoriesAndEmptyScenesExitTwo) {
  std::string err;
  EXPECT_EQ(simulate(std::string(THRESHING_SIM_SOURCE_DIR) + "/config", &err), 2);
  EXPECT_NE(err.find("is a directory"), std::string::npos) << err;
  EXPECT_EQ(simulate(kDefaultScene + " --set-file " + THRESHING_SIM_SOURCE_DIR + "/config", &err),
            2);
  EXPECT_NE(err.find("is a directory"), std::string::npos) << err;
  EXPECT_EQ(simulate("/dev/null --set duration=0.001", &err), 2);
  EXPECT_NE(err.find("expected a mapping"), std::string::npos) << err;
}

// A batch line naming a file that is not a scene (issue 35: /etc/shadow had its lines quoted
// back into the sweep's logs): as the scene or as an override file, each line is a refusal
// naming the file and saying why, quoting none of its content.
TEST(HostileCommandLine, NonSceneFilesAreRefusedQuotingNone) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "hostile_not_scenes";
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "shadow") << "root:*:20228:0:99999:7:::\n"
                                << "secretuser:$6$saltsalt$hashhash:20228:0:99999:7:::\n";
  std::ofstream(dir / "passwd") << "root:x:0:0:root:/root:/bin/bash\n"
                                << "secretuser:x:1000:1000:Secret User:/home/secretuser:/bin/sh\n";
  std::ofstream(dir / "prose.txt") << "secretuser wrote this text\nand not a scene\n";
  const char binary[] =
      "\x7f"
      "ELF\x02\x01\x01\0\0\0secretuser\\q\"\xff\xfe:\x01";
  std::ofstream(dir / "binary.dat", std::ios::binary).write(binary, sizeof(binary) - 1);
  const std::vector<std::string> names = {"shadow", "passwd", "prose.txt", "binary.dat"};
  const std::filesystem::path lines = dir / "lines.jsonl";
  {
    std::ofstream out(lines);
    for (const std::string& name : names) {
      const std::string path = (dir / name).string();
      out << "{\"id\": \"" << name << "\", \"args\": [\"" << path << "\"]}\n";
      out << "{\"id\": \"" << name << "_set\", \"args\": [\"" << kDefaultScene
          << "\", \"--set-file\", \"" << path << "\"]}\n";
    }
  }
  const std::filesystem::path answers = dir / "answers.jsonl";
  const int rc = std::system((std::string(THRESHING_SIM_SIMULATE) + " --batch " + lines.string() +
                              " > " + answers.string() + " 2> /dev/null")
                                 .c_str());
  EXPECT_EQ(WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, 2);
  std::istringstream text(test::readFile(answers));
  int n_lines = 0;
  for (std::string line; std::getline(text, line); ++n_lines) {
    EXPECT_NE(line.find("\"status\": \"error\""), std::string::npos) << line;
    EXPECT_NE(line.find(dir.string() + "/"), std::string::npos) << "names no file: " << line;
    for (const char* content : {"root", "20228", "secretuser", "Secret", "bin/", "ELF", "wrote",
                                "saltsalt", "hashhash", "\\\\q"}) {
      EXPECT_EQ(line.find(content), std::string::npos) << "quotes '" << content << "': " << line;
    }
  }
  EXPECT_EQ(n_lines, 2 * static_cast<int>(names.size()));
  // The loader itself: the same refusals from loadScene, naming the file.
  for (const std::string& name : names) {
    const std::string message = refusal({}, (dir / name).string());
    EXPECT_NE(message.find((dir / name).string()), std::string::npos) << message;
    EXPECT_EQ(message.find("secretuser"), std::string::npos) << message;
  }
}

// A time step longer than the run simulates nothing: exit 1 and a status saying so (was 0, ok).
TEST(HostileCommandLine, NothingSimulatedIsAFailure) {
  std::string err;
  const std::string summary =
      (std::filesystem::temp_directory_path() / "hostile_nothing.json").string();
  EXPECT_EQ(simulate(kDefaultScene +
                         " --integrator time_stepping --dt 1e-2 --duration 1e-4 "
                         "--summary " +
                         summary,
                     &err),
            1);
  EXPECT_NE(test::readFile(summary).find("failed: simulated 0 s"), std::string::npos)
      << test::readFile(summary);
}

// Out-of-range values through the sugar options are scene errors (exit 2), not hangs.
TEST(HostileCommandLine, HangValuesExitTwoQuickly) {
  const auto t0 = std::chrono::steady_clock::now();
  for (const char* args : {"--dt 1e-300 --integrator time_stepping", "--duration 1e300",
                           "--tolerance 1e-300", "--set drum.radius=1e300"}) {
    std::string err;
    EXPECT_EQ(simulate(kDefaultScene + " --duration 1e-4 " + args, &err), 2) << args << ": " << err;
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
}

}  // namespace
}  // namespace threshing_sim

// ---------------------------------------------------------------------------------------------
// A continuous feed (issue 34): hostile feed values are scene errors naming the key and the
// value; a feed scene runs only where a feed is run.
namespace threshing_sim {
namespace {

const std::string kFeedScene = std::string(THRESHING_SIM_SOURCE_DIR) + "/config/scenes/feed.yaml";

// The SceneError message of loading the feed scene with the overrides ("" if it loads).
std::string feedRefusal(const std::vector<std::string>& overrides) {
  try {
    FeedSpec feed;
    loadScene(kFeedScene, overrides, nullptr, &feed);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

TEST(HostileFeed, BadValuesAreRefusedNamingKeyAndValue) {
  const std::vector<std::pair<std::string, std::pair<std::string, std::string>>> cases = {
      {"feed.rate=0", {"feed.rate: ", "(got 0)"}},
      {"feed.rate=-5", {"feed.rate: ", "(got -5)"}},
      {"feed.rate=.nan", {"feed.rate: ", "(got .nan)"}},
      {"feed.rate=1e12", {"feed.rate: ", "(got 1e12)"}},
      {"feed.rate=1e6", {"feed.rate: ", "more than 10000"}},  // the pool it needs
      {"feed.mat_speed=0", {"feed.mat_speed: ", "(got 0)"}},
      {"feed.mat_speed=-1", {"feed.mat_speed: ", "(got -1)"}},
      {"feed.capacity=0", {"feed.capacity: ", "(got 0)"}},
      {"feed.capacity=20", {"feed.capacity: ", "(got 20)"}},  // 200/s x 0.264 m / 1 m/s = 53
      {"feed.capacity=1e9", {"feed.capacity: ", "(got 1e9)"}},
      {"feed.inlet=-0.05", {"feed.inlet: ", "teeth's reach"}},
      {"feed.exit=-0.2", {"feed.exit: ", "(got -0.2)"}},
      {"feed.bound_radius=0.1", {"feed.bound_radius: ", "(got 0.1)"}},
      {"integrator.islands=true", {"integrator.islands: ", "with a feed"}},
      {"drum.speed=-83.78", {"drum.speed: ", "(got -83.78)"}},
  };
  for (const auto& c : cases) {
    const std::string message = feedRefusal({c.first});
    EXPECT_NE(message.find(c.second.first), std::string::npos) << c.first << " -> " << message;
    EXPECT_NE(message.find(c.second.second), std::string::npos) << c.first << " -> " << message;
  }
  EXPECT_EQ(feedRefusal({}), "");
  // A program that does not run a feed refuses the scene rather than run it without one.
  try {
    loadScene(kFeedScene);
    ADD_FAILURE() << "a feed scene loaded without its feed";
  } catch (const SceneError& e) {
    EXPECT_NE(std::string(e.what()).find("feed: this program does not run a feed"),
              std::string::npos)
        << e.what();
  }
}

TEST(HostileFeed, SimulateRefusesBadFeedsAndRunsAGoodOne) {
  std::string err;
  EXPECT_EQ(simulate(kFeedScene + " --set feed.rate=-1", &err), 2);
  EXPECT_NE(err.find("feed.rate"), std::string::npos) << err;
  EXPECT_EQ(simulate(kDefaultScene + " --feed-series /dev/null", &err), 2);
  EXPECT_NE(err.find("--feed-series"), std::string::npos) << err;
  EXPECT_EQ(simulate(kFeedScene + " --feed-interval 0", &err), 2);
  EXPECT_NE(err.find("--feed-interval"), std::string::npos) << err;
  // A short run: the series has a header and one row per 0.01 s, the summary balances.
  const auto dir = std::filesystem::temp_directory_path();
  const std::string series = (dir / "hostile_feed_series.csv").string();
  const std::string summary = (dir / "hostile_feed.json").string();
  ASSERT_EQ(
      simulate(kFeedScene + " --duration 0.05 --feed-series " + series + " --summary " + summary,
               &err),
      0)
      << err;
  const std::string rows = test::readFile(series);
  EXPECT_EQ(std::count(rows.begin(), rows.end(), '\n'), 1 + 5) << rows;
  EXPECT_EQ(rows.rfind("t_start_s,t_end_s,fed,threshed,damaged,separated,", 0), 0u) << rows;
  const std::string json = test::readFile(summary);
  EXPECT_NE(json.find("\"status\": \"ok\""), std::string::npos) << json;
  EXPECT_NE(json.find("\"balanced\": true"), std::string::npos) << json;
  EXPECT_NE(json.find("\"fed\": 11,"), std::string::npos) << json;  // arrivals 0 .. 0.05 s
}

}  // namespace
}  // namespace threshing_sim
