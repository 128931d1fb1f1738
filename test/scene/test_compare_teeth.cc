// End-to-end test of scripts/compare_teeth.py: its tiny sweep (--quick) runs the built simulate
// on every scene and writes the markdown report and its plots, and (--findings, redirected to
// the output folder) the findings page and a copy of docs/threshing_findings.md with its findings
// section rewritten.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "script_test_util.h"

namespace {

namespace fs = std::filesystem;

using threshing_sim::test::readFile;

TEST(CompareTeeth, QuickSweepWritesReportAndPlots) {
  const fs::path out = COMPARE_OUT_DIR;
  fs::remove_all(out);
  fs::create_directories(out);
  const fs::path page = out / "docs" / "threshing_findings.md";
  const fs::path source_page =
      fs::path(THRESHING_SIM_SOURCE_DIR) / "docs" / "threshing_findings.md";
  const std::string readme_before = readFile(source_page);
  ASSERT_FALSE(readme_before.empty());
  fs::create_directories(out / "docs");
  fs::copy_file(source_page, page);
  const std::string command = std::string("/usr/bin/python3 ") + THRESHING_SIM_SOURCE_DIR +
                              "/scripts/compare_teeth.py --quick --findings --simulate " +
                              THRESHING_SIM_SIMULATE + " --out " + out.string() + " --docs " +
                              (out / "docs").string() + " --summary " + page.string() + " > " +
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

  // The findings page judges the three claims.
  const std::string findings = readFile(out / "docs" / "findings.md");
  for (const char* claim : {"## Claim 1:", "## Claim 2:", "## Claim 3:"}) {
    EXPECT_NE(findings.find(claim), std::string::npos) << claim;
  }

  // The page's findings section: rewritten between the markers, the rest untouched; it holds
  // the three verdicts, the agreement paragraph and the command, and its plots exist.
  const std::string begin = "<!-- findings -->", end = "<!-- findings-end -->";
  const std::string readme = readFile(page);
  const size_t b0 = readme_before.find(begin), e0 = readme_before.find(end);
  const size_t b1 = readme.find(begin), e1 = readme.find(end);
  ASSERT_NE(b0, std::string::npos);
  ASSERT_NE(e0, std::string::npos);
  ASSERT_NE(b1, std::string::npos);
  ASSERT_NE(e1, std::string::npos);
  EXPECT_EQ(readme.substr(0, b1), readme_before.substr(0, b0));
  EXPECT_EQ(readme.substr(e1), readme_before.substr(e0));
  const std::string section = readme.substr(b1, e1 - b1);
  for (const char* part :
       {"**Claim 1 (", "**Claim 2 (", "**Claim 3 (", "**Threshing force and contact time.**",
        "43.9-71.9 N", "compare_teeth.py --findings"}) {
    EXPECT_NE(section.find(part), std::string::npos) << part;
  }
  size_t images = 0;
  for (size_t at = section.find("]("); at != std::string::npos; at = section.find("](", at + 2)) {
    const std::string link = section.substr(at + 2, section.find(')', at) - at - 2);
    if (link.size() < 4 || link.substr(link.size() - 4) != ".png") continue;
    ++images;
    EXPECT_TRUE(fs::is_regular_file(out / "docs" / link)) << link;
  }
  EXPECT_GE(images, 4u);
}

}  // namespace
