// Helpers shared by the end-to-end tests of the scripts (test_bench, test_compare_teeth).
#pragma once

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace threshing_sim::test {

// Whole contents of a text file; empty if it cannot be read.
inline std::string readFile(const std::filesystem::path& path) {
  std::ifstream file(path);
  std::stringstream text;
  text << file.rdbuf();
  return text.str();
}

}  // namespace threshing_sim::test
