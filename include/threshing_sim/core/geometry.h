// threshing_sim core: planar distance queries between ellipses, points, segments, circles and
// half-planes. All distances are signed: negative means the shapes overlap, and its magnitude
// is then the penetration depth along the returned normal.
#pragma once

#include "threshing_sim/core/model.h"

namespace threshing_sim {

// An ellipse in world: centre, orientation of its a-axis, semi-axes a >= b > 0.
struct Ellipse {
  Vec2 center = Vec2::Zero();  // [m]
  double angle_rad = 0.0;      // angle of the a-axis from world X [rad]
  double a_m = 1.0;            // semi-major [m]
  double b_m = 1.0;            // semi-minor [m]
};

// Result of a distance query between body 1 and body 2.
struct Proximity {
  double distance_m = 0;        // signed distance (negative = overlap depth) [m]
  Vec2 point1 = Vec2::Zero();   // closest (or deepest) point on body 1's surface [m]
  Vec2 point2 = Vec2::Zero();   // closest (or deepest) point on body 2's surface [m]
  Vec2 normal = Vec2::UnitX();  // unit normal from body 1 towards body 2 [-]
  double param = 0;             // segment queries: parameter s in [0, 1] of point on the segment
  double radius2_m = 0;         // radius of curvature of body 2's surface at point2 [m] (inf: flat)
};

// Closest point on the ellipse boundary to p (Eberly's robust bisection).
// Body 1 is the point p, body 2 the ellipse: distance > 0 outside, < 0 inside.
Proximity pointEllipse(const Vec2& p, const Ellipse& e);
// The same with the ellipse's cos(angle_rad) and sin(angle_rad) given (repeated queries).
Proximity pointEllipse(const Vec2& p, const Ellipse& e, double cos_angle, double sin_angle);

// Segment [p0, p1] (body 1) against the ellipse (body 2).
Proximity segmentEllipse(const Vec2& p0, const Vec2& p1, const Ellipse& e);

// Ellipse e1 (body 1) against ellipse e2 (body 2).
Proximity ellipseEllipse(const Ellipse& e1, const Ellipse& e2);
// The same warm-started from the separating direction of the pair's last query (the angle of
// the normal, *warm_theta_rad; NaN: none), which receives this query's: while that direction
// moved by less than 0.05 rad and the ellipses are apart or overlap by less than the sum of
// their least curvature radii (b^2/a), a local refinement around it replaces the search over
// all directions (else the search runs). [rad]
Proximity ellipseEllipse(const Ellipse& e1, const Ellipse& e2, double* warm_theta_rad);

// Half-plane {x : n.(x - p) <= 0} bounded by the line through p with outward unit normal n
// (body 1) against the ellipse (body 2).
Proximity planeEllipse(const Vec2& p, const Vec2& n, const Ellipse& e);

// Disc of radius r at c (body 1) against the ellipse (body 2).
Proximity circleEllipse(const Vec2& c, double r, const Ellipse& e);

// Radius of curvature of the ellipse boundary at its boundary point q [m].
double ellipseCurvatureRadius(const Ellipse& e, const Vec2& q);

// Radius of the smallest circle around the ellipse centre containing it (= a) [m].
inline double boundingRadius(const Ellipse& e) { return e.a_m; }

}  // namespace threshing_sim
