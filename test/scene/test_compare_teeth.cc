// End-to-end test of scripts/compare_teeth.py: its tiny sweep (--quick) runs the built simulate
// on every scene and writes the markdown report and its plots.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace {

namespace fs = std::filesystem;

std::string readFile(const fs::path& path) {
  std::ifstream file(path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

TEST(CompareTeeth, QuickSweepWritesReportAndPlots) {
  const fs::path out = COMPARE_OUT_DIR;
  fs::remove_all(out);
  const std::string command = std::string("/usr/bin/python3 ") + THRESHING_SIM_SOURCE_DIR +
                              "/scripts/compare_teeth.py --quick --simulate " +
                              THRESHING_SIM_SIMULATE + " --out " + out.string() + " > " +
                              (out.string() + ".log") + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command << "\n" << readFile(out.string() + ".log");

  // The report names every plot, and every plot is a non-empty PNG.
  const std::string report = readFile(out / "report.md");
  ASSERT_FALSE(report.empty()) << "no report.md";
  for (const char* plot :
       {"force_history_single_strike.png", "force_history_knead.png", "force_history_stream.png",
        "peak_forces.png", "knead_force.png", "damage_fraction.png", "detachment_fraction.png",
        "sub_collisions.png", "campbell.png"}) {
    EXPECT_NE(report.find(std::string("](") + plot + ")"), std::string::npos) << plot;
    const std::string png = readFile(out / plot);
    EXPECT_GT(png.size(), 1000u) << plot;
    EXPECT_EQ(png.substr(1, 3), "PNG") << plot;
  }
  // Every scene ran for both teeth of the quick sweep.
  for (const char* scene : {"single_strike", "knead", "stream"}) {
    EXPECT_NE(report.find(std::string("## Scene ") + scene), std::string::npos) << scene;
  }
  EXPECT_NE(report.find("| polyurethane |"), std::string::npos);
}

}  // namespace
