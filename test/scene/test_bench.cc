// End-to-end test of scripts/bench.py: its tiny version (--quick) runs the built
// bench_work_precision on the single strike (references, two knob values per integrator, a few
// scaling points) and itself asserts that the errors fall with the knob and that the two
// references agree; here the report, the CSV and the plots are checked too.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "script_test_util.h"

namespace {

namespace fs = std::filesystem;

using threshing_sim::test::readFile;

TEST(Bench, QuickRunWritesTablesAndPlots) {
  const fs::path out = BENCH_OUT_DIR;
  fs::remove_all(out);
  const std::string command = std::string("/usr/bin/python3 ") + THRESHING_SIM_SOURCE_DIR +
                              "/scripts/bench.py --quick --jobs 1 --bin " + BENCH_BIN_DIR +
                              " --out " + out.string() + " > " + (out.string() + ".log") + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command << "\n" << readFile(out.string() + ".log");

  // The report holds the reference check, the work-precision table and the scaling table.
  const std::string report = readFile(out / "bench.md");
  ASSERT_FALSE(report.empty()) << "no bench.md";
  EXPECT_NE(report.find("| single_strike | 4 | event-driven 1e-09 | time stepping 1e-07 |"),
            std::string::npos);
  EXPECT_NE(report.find("| single_strike | event-driven | 0.0001 |"), std::string::npos);
  EXPECT_NE(report.find("| single_strike | time-stepping | 1e-06 |"), std::string::npos);
  EXPECT_NE(report.find("| kernels | 10 |"), std::string::npos);
  EXPECT_NE(report.find("| modes | 2 |"), std::string::npos);

  // CSV: a header and one row per point (2 knob values x 2 integrators).
  const std::string csv = readFile(out / "bench" / "work_precision.csv");
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), 5) << csv;
  EXPECT_EQ(csv.rfind("scene,integrator,knob,", 0), 0u) << csv;

  // Every plot is a non-empty PNG.
  for (const char* plot : {"wp_single_strike.png", "scaling.png"}) {
    const std::string png = readFile(out / "bench" / plot);
    EXPECT_GT(png.size(), 1000u) << plot;
    EXPECT_EQ(png.substr(1, 3), "PNG") << plot;
  }
}

}  // namespace
