// Numbers from command-line text: the whole text must be the number (no trailing characters),
// and a double must be finite. The callers name the option and the allowed range in their
// messages (simulate's options, bench_work_precision's).
#pragma once

#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>

namespace threshing_sim {

// text as a finite double, or nothing.
inline std::optional<double> doubleFromText(const std::string& text) {
  size_t used = 0;
  double value = 0;
  try {
    value = std::stod(text, &used);
  } catch (const std::logic_error&) {
    return std::nullopt;
  }
  if (text.empty() || used != text.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

// text as an int, or nothing.
inline std::optional<int> intFromText(const std::string& text) {
  size_t used = 0;
  int value = 0;
  try {
    value = std::stoi(text, &used);
  } catch (const std::logic_error&) {
    return std::nullopt;
  }
  if (text.empty() || used != text.size()) return std::nullopt;
  return value;
}

}  // namespace threshing_sim
