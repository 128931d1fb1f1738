// threshing_sim core: seeded uniform numbers that are the same on every platform.
#pragma once

#include <random>

namespace threshing_sim {

// Uniform numbers from a 64-bit Mersenne Twister, mapped by hand so that the sequence is the
// same on every standard library (std::uniform_real_distribution is not specified exactly).
class Uniform {
 public:
  explicit Uniform(unsigned long long seed = 1) : engine_(seed) {}
  // A number in [lo, hi) (hi when lo == hi).
  double operator()(double lo, double hi) {
    return lo + (hi - lo) * static_cast<double>(engine_() >> 11) * 0x1.0p-53;
  }

 private:
  std::mt19937_64 engine_;
};

}  // namespace threshing_sim
