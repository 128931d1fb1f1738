// threshing_sim core, private: the cosine and sine of an angle, memoised.
//
// The contact pipeline turns the same few angles (a kernel's orientation, the drum angle of the
// evaluation) many times per right-hand side: per pair, per query of the narrow phase, per
// force. A small direct-mapped cache keyed by the angle's bits returns the values std::cos and
// std::sin gave for those bits, so the results are the same bits as without it (deterministic,
// no accuracy change) for a lookup instead of a sincos. One cache per thread.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>

namespace threshing_sim {
namespace internal {

struct CosSin {
  double c, s;  // cos and sin of the angle [-]
};

inline CosSin cosSinOf(double angle_rad) {
  struct Entry {
    std::uint64_t bits = ~std::uint64_t{0};  // the angle's bits (a NaN payload: never an input)
    CosSin value{1.0, 0.0};
  };
  constexpr int kSlots = 64;  // power of two
  thread_local Entry cache[kSlots];
  std::uint64_t bits;
  std::memcpy(&bits, &angle_rad, sizeof bits);
  // Mix the mantissa's low and high bits: nearby angles land in different slots.
  const std::uint64_t mixed = bits ^ (bits >> 17) ^ (bits >> 31) ^ (bits >> 47);
  Entry& e = cache[mixed & (kSlots - 1)];
  if (e.bits != bits) {
    e.bits = bits;
    e.value = {std::cos(angle_rad), std::sin(angle_rad)};
  }
  return e.value;
}

}  // namespace internal
}  // namespace threshing_sim
