// threshing_sim core, private: planar vector helpers shared by the contact pipeline's stages.
#pragma once

#include <cmath>

#include "../cos_sin_memo.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace internal {

inline Vec2 rotate(double angle_rad, const Vec2& v) {
  const CosSin cs = cosSinOf(angle_rad);
  return Vec2(cs.c * v.x() - cs.s * v.y(), cs.s * v.x() + cs.c * v.y());
}
// The same rotation with its cosine and sine computed once (memoised: cos_sin_memo.h).
struct Rotation2 {
  explicit Rotation2(double angle_rad) : Rotation2(cosSinOf(angle_rad)) {}
  explicit Rotation2(const CosSin& cs) : c(cs.c), s(cs.s) {}
  Vec2 operator*(const Vec2& v) const { return Vec2(c * v.x() - s * v.y(), s * v.x() + c * v.y()); }
  double c, s;  // cos and sin of the angle [-]
};

// (cos angle, sin angle) [-].
inline Vec2 unitVector(double angle_rad) {
  const CosSin cs = cosSinOf(angle_rad);
  return Vec2(cs.c, cs.s);
}

inline Vec2 perp(const Vec2& v) { return Vec2(-v.y(), v.x()); }  // J v
inline double cross(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

}  // namespace internal
}  // namespace threshing_sim
