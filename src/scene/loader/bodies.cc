// The body and settings readers (bodies.h).
#include "bodies.h"

#include <cmath>

#include "messages.h"
#include "schema.h"
#include "threshing_sim/core/overlap.h"

namespace threshing_sim {
namespace loader {

void readDrum(const Section& scene, DrumModel* drum) {
  const Section s = scene.section("drum", "drum");
  drum->radius_m = s.number("radius", drum->radius_m);
  drum->initial_speed_radps = s.number("speed", drum->initial_speed_radps);
  drum->max_acceleration_radps2 = s.number("max_acceleration", drum->max_acceleration_radps2);
  drum->max_speed_radps = s.number("max_speed", drum->max_speed_radps);
  drum->initial_angle_rad = s.number("angle", drum->initial_angle_rad);
}

ToothModel readTooth(const Section& s) {
  ToothModel t;
  t.mount_angle_rad = s.number("mount_angle", t.mount_angle_rad);
  t.length_m = s.number("length", t.length_m);
  t.diameter_m = s.number("diameter", t.diameter_m);
  t.youngs_modulus_Pa = s.number("youngs_modulus", t.youngs_modulus_Pa);
  t.density_kgpm3 = s.number("density", t.density_kgpm3);
  // modes: auto (the default) lets compileModel choose the count (model.cc, chooseModeCount).
  const bool auto_modes = !s.has("modes") || (s.node("modes").isPlainScalar() &&
                                              s.node("modes").text == kAutoModesWord);
  t.n_modes = auto_modes ? kAutoModes : s.integer("modes", t.n_modes);
  t.damping_ratio = s.number("damping_ratio", t.damping_ratio);
  t.poisson_ratio = s.number("poisson_ratio", t.poisson_ratio);
  t.n_stations = s.integer("stations", t.n_stations);
  // modal: assumed modes (small deflection); large_deflection: the exact planar rod, whose
  // `modes` are its Ritz shape functions (docs/large_deflection.md).
  const std::string model = s.word("model", toothModelWord(t.beam_model), "tooth model");
  t.beam_model =
      model == "large_deflection" ? ToothBeamModel::kLargeDeflection : ToothBeamModel::kModal;
  t.static_correction =
      s.word("static_correction", onOff(t.static_correction), "static correction") == "on";
  t.section_rotation = s.word("section_rotation", sectionRotationWord(t.section_rotation),
                              "section rotation") == "euler_bernoulli"
                           ? ToothSectionRotation::kEulerBernoulli
                           : ToothSectionRotation::kShearCorrected;
  return t;
}

// The optional pedicel; the attachment point must lie inside the kernel.
PedicelModel readPedicel(const Section& s, const KernelModel& kernel) {
  PedicelModel p;
  p.present = true;
  s.require("anchor");
  p.p_WA_W = s.vec2("anchor", p.p_WA_W);
  p.p_KP_K = s.vec2("attach_point", p.p_KP_K);
  const double ellipse_norm = std::pow(p.p_KP_K.x() / kernel.semi_axis_a_m, 2) +
                              std::pow(p.p_KP_K.y() / kernel.semi_axis_b_m, 2);
  if (ellipse_norm > 1.0) {
    fail(s.path("attach_point"), "must lie inside the kernel, (x/a)^2 + (y/b)^2 <= 1 (got " +
                                     show(s.node("attach_point")) + " with semi-axes " +
                                     show(Vec2(kernel.semi_axis_a_m, kernel.semi_axis_b_m)) + ")");
  }
  p.stiffness_Npm = s.number("stiffness", p.stiffness_Npm);
  p.damping_Nspm = s.number("damping", p.damping_Nspm);
  p.rest_length_m = s.number("rest_length", p.rest_length_m);
  p.detachment_force_N = s.number("detachment_force", p.detachment_force_N);
  return p;
}

KernelModel readKernel(const Section& s) {
  KernelModel k;
  s.require("position");
  k.initial_position_m = s.vec2("position", k.initial_position_m);
  k.initial_angle_rad = s.number("angle", k.initial_angle_rad);
  k.initial_velocity_mps = s.vec2("velocity", k.initial_velocity_mps);
  k.initial_angular_velocity_radps = s.number("angular_velocity", k.initial_angular_velocity_radps);
  // Semi-axes: both positive, the first the larger.
  const Vec2 axes = s.vec2("semi_axes", Vec2(k.semi_axis_a_m, k.semi_axis_b_m));
  if (axes.minCoeff() <= 0) {
    fail(s.path("semi_axes"), "must be > 0 (got " + show(s.node("semi_axes")) + ")");
  }
  if (axes.x() < axes.y()) {
    fail(s.path("semi_axes"), "a must be >= b (got " + show(s.node("semi_axes")) + ")");
  }
  k.semi_axis_a_m = axes.x();
  k.semi_axis_b_m = axes.y();
  k.mass_kg = s.number("mass", k.mass_kg);
  k.youngs_modulus_Pa = s.number("youngs_modulus", k.youngs_modulus_Pa);
  k.poisson_ratio = s.number("poisson_ratio", k.poisson_ratio);
  const SceneNode& pedicel = s.node("pedicel");
  if (pedicel.defined() && !pedicel.isNull()) {
    static const Children& kPedicelKeys = children("kernels.*.pedicel");
    k.pedicel = readPedicel(s.section("pedicel", kPedicelKeys), k);
  }
  return k;
}

// The type decides which keys are allowed; geometry keys are required.
ObstacleModel readObstacle(const SceneNode& node, const std::string& path) {
  static const Children kPlane = childrenOf("obstacles.*", kPlaneKeys);
  static const Children kCircle = childrenOf("obstacles.*", kCircleKeys);
  static const Children kSegment = childrenOf("obstacles.*", kSegmentKeys);
  const Section any(node, path, children("obstacles.*"));
  any.require("type");
  const std::string type = any.word("type", "", "obstacle type");
  ObstacleModel o;
  if (type == "plane") {
    const Section s(node, path, kPlane, "a plane obstacle");
    o.type = ObstacleType::kPlane;
    s.require("point");
    s.require("normal");
    o.point_m = s.vec2("point", o.point_m);
    const Vec2 normal = s.vec2("normal", o.normal);
    if (normal.norm() == 0) {
      fail(s.path("normal"), "must not be zero (got " + show(s.node("normal")) + ")");
    }
    o.normal = normal.normalized();
  } else if (type == "circle") {
    const Section s(node, path, kCircle, "a circle obstacle");
    o.type = ObstacleType::kCircle;
    s.require("center");
    o.center_m = s.vec2("center", o.center_m);
    o.radius_m = s.number("radius", o.radius_m);
    if (!(o.radius_m > 0))
      fail(s.path("radius"), "must be > 0 for a circle (got " + show(s.node("radius")) + ")");
  } else {
    const Section s(node, path, kSegment, "a segment obstacle");
    o.type = ObstacleType::kSegment;
    s.require("point");
    s.require("point_b");
    o.point_m = s.vec2("point", o.point_m);
    o.point_b_m = s.vec2("point_b", o.point_b_m);
    if (o.point_b_m == o.point_m) {
      fail(s.path("point_b"), "must differ from point (got " + show(s.node("point_b")) + ")");
    }
    o.radius_m = s.number("radius", o.radius_m);
  }
  o.youngs_modulus_Pa = any.number("youngs_modulus", o.youngs_modulus_Pa);
  o.poisson_ratio = any.number("poisson_ratio", o.poisson_ratio);
  return o;
}

void readContact(const Section& scene, Model* model) {
  const Section s = scene.section("contact", "contact");
  for (int kind = 0; kind < 3; ++kind) {
    const std::string key = kPairKeys[kind];
    const Section pair = s.section(key, "contact." + key);
    ContactParams p = kContactDefaults[kind];
    const std::string law = pair.word("law", lawWord(p.law), "contact law");
    p.law = law == "rigid" ? ContactLaw::kRigid : ContactLaw::kCompliant;
    p.restitution = pair.number("restitution", p.restitution);
    p.friction = pair.number("friction", p.friction);
    model->contact[kind] = p;
  }
  model->hc_min_impact_speed_mps = s.number("hc_min_impact_speed", model->hc_min_impact_speed_mps);
}

void readIntegrator(const Section& scene, IntegratorParams* integrator) {
  const Section s = scene.section("integrator", "integrator");
  const std::string type = s.word("type", integratorWord(integrator->type), "integrator type");
  integrator->type =
      type == "time_stepping" ? IntegratorType::kTimeStepping : IntegratorType::kEventDriven;
  integrator->tolerance = s.number("tolerance", integrator->tolerance);
  integrator->dt_s = s.number("dt", integrator->dt_s);
  integrator->theta = s.number("theta", integrator->theta);
  integrator->zeno_velocity_mps = s.number("zeno_velocity", integrator->zeno_velocity_mps);
  integrator->max_step_s = s.number("max_step", integrator->max_step_s);
  integrator->contact_steps = s.integer("contact_steps", integrator->contact_steps);
  const std::string free_teeth =
      s.word("free_teeth", freeTeethWord(integrator->exact_free_teeth), "free tooth propagation");
  integrator->exact_free_teeth = free_teeth == "exact";
  const std::string modal_split =
      s.word("modal_split", modalSplitWord(integrator->modal_split), "modal split");
  integrator->modal_split = modal_split == "exact";
  const std::string islands =
      s.word("islands", trueFalse(integrator->islands), "island-local scheme");
  integrator->islands = islands == "true";
}

DamageThresholds readDamage(const Section& scene) {
  const Section s = scene.section("damage", "damage");
  DamageThresholds d;
  d.plastic_force_N = s.number("plastic_force", d.plastic_force_N);
  d.fracture_force_N = s.number("fracture_force", d.fracture_force_N);
  if (d.fracture_force_N < d.plastic_force_N) {
    fail(s.path(s.has("fracture_force") ? "fracture_force" : "plastic_force"),
         "the fracture force must be >= the plastic force (got plastic " + show(d.plastic_force_N) +
             " N, fracture " + show(d.fracture_force_N) + " N)");
  }
  return d;
}

// Every kernel against the earlier kernels, the teeth and the obstacles (the core's test,
// O(n) ellipse tests through a grid).
void checkInitialOverlaps(const Model& model) {
  const Overlap o = findInitialOverlap(model, model.drum.initial_angle_rad);
  if (!o.found) return;
  fail("kernels." + std::to_string(o.kernel) + ".position",
       "kernel overlaps " + bodyName(o.other_kind, o.other) + " at start by " +
           show(-o.distance_m) + " m (got " + show(model.kernels[o.kernel].initial_position_m) +
           ")");
}

}  // namespace loader
}  // namespace threshing_sim
