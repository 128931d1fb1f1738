// threshing_sim scene files: YAML -> validated, compiled Model.
//
// One schema table lists every key path; the validator reads each section against it (so an
// unknown key anywhere is refused with a suggestion) and the override walker uses it to decide
// which missing keys may be created. Every refusal names the full key path and the bad value.
#include "threshing_sim/scene/scene_loader.h"

#include <sys/stat.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <utility>

#include "threshing_sim/core/beam.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/geometry.h"
#include "threshing_sim/core/overlap.h"
#include "threshing_sim/core/tooth_cache.h"
#include "threshing_sim/core/uniform.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {
namespace {

// ---------------------------------------------------------------------------------------------
// Schema: every key path, list items written as "*".

// kValue: a number, string or [x, y]; kSection: a mapping an override may create when absent;
// kOptionalSection: a mapping whose presence means something (must be set whole first);
// kList: a list of mappings.
enum class KeyKind { kValue, kSection, kOptionalSection, kList };

// The interval a number (each number of an [x, y] pair, an integer) must lie in. Every range
// is finite: a value the integrator cannot run with in bounded work (1e300 m/s, a step of
// 1e-300 s) is a scene error naming the key, not a hang.
struct Bound {
  double lo = -std::numeric_limits<double>::infinity();
  double hi = std::numeric_limits<double>::infinity();
  bool lo_open = false;
  bool hi_open = false;

  bool contains(double x) const {
    return (lo_open ? x > lo : x >= lo) && (hi_open ? x < hi : x <= hi);
  }
  std::string text() const;
};

// No range (sections, lists, words).
const Bound kNoRange{};

// The feed's defaults that set its geometry at load (the others are FeedSpec's, core/feed.h).
constexpr double kFeedDepth_m = 0.005;          // feed.depth [m]
constexpr double kFeedGrateClearance_m = 0.01;  // feed.grate_clearance [m]

// The kernel stream generator's parameters (scene section `stream`); the member values are the
// section's defaults.
struct StreamSpec {
  int count = 0;                      // kernels [-] (required)
  double rate_Hz = 0;                 // kernels per second of drum time [1/s] (required)
  double start_s = 5e-4;              // arrival of the first kernel [s]
  int seed = 1;                       // seed of the scatter [-]
  double depth_m = 0.005;             // centre depth inside the tip circle [m]
  double position_scatter_m = 0.001;  // +- radial and along-path scatter [m]
  double angle_scatter_rad = 0.5;     // +- orientation scatter [rad]
  double pedicel_length_m = 0.003;    // pedicel from the kernel's end to its anchor [m]
  Vec2 mass_kg{2.4e-5, 3.1e-5};       // mass range [kg] (paddy 24-31 mg, docs/model.md §10)
  Vec2 detach_N{0.27, 2.6};           // detachment force range [N] (rice, docs/model.md §10)
  KernelModel base;                   // semi-axes, material, pedicel law
};

// Contact defaults from docs/model.md §10: rice-nylon, rice-rice, wheat-steel.
const ContactParams kContactDefaults[3] = {
    {ContactLaw::kCompliant, 0.48, 0.53},
    {ContactLaw::kRigid, 0.34, 0.66},
    {ContactLaw::kRigid, 0.47, 0.50},
};

// The values a key takes when a scene leaves it out: default-constructed core structs, the
// contact defaults above and the stream generator's defaults. The loader starts from the same
// objects, so a default is written once.
struct SchemaDefaults {
  Model model;
  ToothModel tooth;
  KernelModel kernel;
  PedicelModel pedicel;
  ObstacleModel obstacle;
  StreamSpec stream;
  FeedSpec feed;
  DamageThresholds damage;
};

// A number for the reference: the fewest significant digits that read back as the same double,
// written plainly from 1e-3 to 1e6 (200, 0.0013) and with a short exponent outside (5e-4, 3e9).
std::string num(double value) {
  char text[40];
  int digits = 1;
  for (; digits < 17; ++digits) {
    std::snprintf(text, sizeof(text), "%.*g", digits, value);
    if (std::strtod(text, nullptr) == value) break;
  }
  const double magnitude = std::abs(value);
  if (value == 0 || (magnitude >= 1e-3 && magnitude < 1e6)) {
    const int decimals =
        value == 0 ? 0
                   : std::max(0, digits - 1 - static_cast<int>(std::floor(std::log10(magnitude))));
    std::snprintf(text, sizeof(text), "%.*f", decimals, value);
    return text;
  }
  std::snprintf(text, sizeof(text), "%.*e", digits - 1, value);
  std::string out = text;  // 3e+09 -> 3e9, 1e-06 -> 1e-6
  const size_t e = out.find('e');
  std::string exponent = out.substr(e + 1);
  const bool negative = exponent[0] == '-';
  exponent.erase(0, exponent.find_first_not_of("+-0"));
  return out.substr(0, e) + "e" + (negative ? "-" : "") + exponent;
}
std::string pair(const Vec2& v) { return "[" + num(v.x()) + ", " + num(v.y()) + "]"; }

// The words of the scene file for the core's enumerations and switches (readers and the
// reference use the same ones).
const char* const kAutoModesWord = "auto";  // teeth.*.modes when absent: chosen by compileModel
std::string toothModelWord(ToothBeamModel m) {
  return m == ToothBeamModel::kLargeDeflection ? "large_deflection" : "modal";
}
std::string sectionRotationWord(ToothSectionRotation r) {
  return r == ToothSectionRotation::kEulerBernoulli ? "euler_bernoulli" : "shear_corrected";
}
std::string lawWord(ContactLaw law) { return law == ContactLaw::kRigid ? "rigid" : "compliant"; }
std::string integratorWord(IntegratorType t) {
  return t == IntegratorType::kTimeStepping ? "time_stepping" : "event_driven";
}
std::string onOff(bool on) { return on ? "on" : "off"; }
std::string trueFalse(bool on) { return on ? "true" : "false"; }
std::string freeTeethWord(bool exact) { return exact ? "exact" : "integrated"; }
std::string modalSplitWord(bool exact) { return exact ? "exact" : "none"; }

// A key's default as the reference prints it, from the defaults above; nullptr: none (sections).
using DefaultText = std::string (*)(const SchemaDefaults&);
const DefaultText kNoDefault = nullptr;

struct KeySpec {
  const char* path;
  KeyKind kind;
  const char* type;             // number, integer, [x, y], word, section, list
  const char* unit;             // SI unit ("" = dimensionless or none)
  Bound range;                  // accepted values of a number, integer or of each number of a pair
  DefaultText default_text;     // the value when the key is absent (kNoDefault: a section)
  const char* doc;              // what the key means
  const char* words = nullptr;  // a word key's accepted words, ", "-separated
};

// The one table of scene keys and their ranges: the readers below take each range from here
// (Section::number, integer, vec2), and `simulate --print-schema` prints it
// (docs/scene_reference.md's key table is its output).
const KeySpec kSchema[] = {
    {"drum", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "The rotating drum that carries the teeth."},
    {"drum.radius", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.radius_m); },
     "Distance R from the drum axis to each tooth root."},
    {"drum.speed", KeyKind::kValue, "number", "rad/s", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.initial_speed_radps); },
     "Initial drum speed Omega(0), also the initial target speed; positive is counter-clockwise."},
    {"drum.max_acceleration", KeyKind::kValue, "number", "rad/s^2", Bound{0.0, 1e7, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.drum.max_acceleration_radps2);
     },
     "Bound on the drum's angular acceleration when it follows a new target speed."},
    {"drum.max_speed", KeyKind::kValue, "number", "rad/s", Bound{0.0, 1e4, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.max_speed_radps); },
     "Bound on |Omega| and on any commanded target speed (larger targets are clamped to "
     "max(max_speed, |speed|)); the residual flexibility of the truncated modes is tabulated "
     "up to it at compile time."},
    {"drum.angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.drum.initial_angle_rad); },
     "Initial drum angle theta(0)."},
    {"teeth", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "The flexible teeth: Euler-Bernoulli cantilevers of round section on the drum."},
    {"teeth.*.mount_angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.mount_angle_rad); },
     "Angle alpha of the tooth root and axis in the drum frame."},
    {"teeth.*.length", KeyKind::kValue, "number", "m", Bound{1e-5, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.length_m); },
     "Free length L of the tooth."},
    {"teeth.*.diameter", KeyKind::kValue, "number", "m", Bound{1e-5, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.diameter_m); },
     "Diameter d of the round section; the contact capsule radius is d/2."},
    {"teeth.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.youngs_modulus_Pa); },
     "Young's modulus E of the tooth material."},
    {"teeth.*.density", KeyKind::kValue, "number", "kg/m^3", Bound{1.0, 1e5, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.density_kgpm3); },
     "Density rho of the tooth material."},
    {"teeth.*.modes", KeyKind::kValue, "integer or auto", "", Bound{0.0, kMaxModes, false, false},
     [](const SchemaDefaults&) -> std::string { return kAutoModesWord; },
     "Number of retained bending modes; 0 makes the tooth rigid; `auto` chooses it from the "
     "contact time and the tolerance (README \"Converged tooth forces\"). For a large-deflection "
     "tooth: its Ritz shape functions, at most 40 (`auto`: the modal count, within 6 to 24)."},
    {"teeth.*.damping_ratio", KeyKind::kValue, "number", "", Bound{0.0, 1.0, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.damping_ratio); },
     "Modal damping ratio zeta, the same for every mode."},
    {"teeth.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.poisson_ratio); },
     "Poisson's ratio of the tooth material (Hertz contact law)."},
    {"teeth.*.stations", KeyKind::kValue, "integer", "", Bound{2.0, 65.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.tooth.n_stations); },
     "Number of centreline points sampled for contact detection."},
    {"teeth.*.model", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return toothModelWord(d.tooth.beam_model); },
     "`modal`: assumed modes (linear, valid to about 0.1 L of tip deflection). `large_deflection`: "
     "a geometrically exact planar rod for soft teeth, whose `modes` are its Ritz shape functions "
     "(event-driven or time stepping, global scheme only; "
     "[large_deflection.md](large_deflection.md)).",
     "modal, large_deflection"},
    {"teeth.*.static_correction", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return onOff(d.tooth.static_correction); },
     "Residual flexibility of the truncated modes in series with the contact (README \"Converged "
     "tooth forces\"); `off`: the retained modes only. A large-deflection tooth has none.",
     "on, off"},
    {"teeth.*.section_rotation", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return sectionRotationWord(d.tooth.section_rotation);
     },
     "What turns a modal tooth's sections, and with them the surface points that friction acts "
     "on: `shear_corrected`, each mode's slope w' reduced to the rotation of a shear-flexible "
     "(Timoshenko) section, w' / (1 + (E / kappa G) (I / A) beta^2), so the stick forces converge "
     "in the mode count; `euler_bernoulli`, the slope itself (the paper's model; its stick forces "
     "do not converge). A large-deflection tooth applies the same factor mode by mode of the rod "
     "linearised at rest ([model.md](model.md) §9b).",
     "shear_corrected, euler_bernoulli"},
    {"kernels", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "The grain kernels: rigid ellipses in the drum plane."},
    {"kernels.*.position", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Initial centre c(0) in the world frame (origin on the drum axis, gravity along -Y)."},
    {"kernels.*.angle", KeyKind::kValue, "number", "rad", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.initial_angle_rad); },
     "Initial angle psi(0) of the major axis from world X."},
    {"kernels.*.velocity", KeyKind::kValue, "[x, y]", "m/s", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.kernel.initial_velocity_mps); },
     "Initial velocity of the centre."},
    {"kernels.*.angular_velocity", KeyKind::kValue, "number", "rad/s",
     Bound{-1e5, 1e5, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.kernel.initial_angular_velocity_radps);
     },
     "Initial angular velocity dpsi/dt."},
    {"kernels.*.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return pair(Vec2(d.kernel.semi_axis_a_m, d.kernel.semi_axis_b_m));
     },
     "Semi-major and semi-minor axes of the ellipse. Needs a >= b."},
    {"kernels.*.mass", KeyKind::kValue, "number", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.mass_kg); },
     "Kernel mass; the polar inertia is m (a² + b²) / 4 (uniform elliptic disc)."},
    {"kernels.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus E of the kernel (Hertz contact law)."},
    {"kernels.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of the kernel."},
    {"kernels.*.pedicel", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "Stem holding the kernel to the panicle: a spring-damper from a fixed anchor to a point on "
     "the kernel that breaks for good when its force exceeds the detachment force. Absent means a "
     "free kernel. An override can only set keys inside it once it exists (`--set "
     "kernels.0.pedicel={anchor: [x, y]}` creates it)."},
    {"kernels.*.pedicel.anchor", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Fixed anchor point in the world frame."},
    {"kernels.*.pedicel.attach_point", KeyKind::kValue, "[x, y]", "m",
     Bound{-1.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.pedicel.p_KP_K); },
     "Attachment point in the kernel frame (origin at the centre, x along the major axis). Must "
     "lie inside the kernel: (x/a)² + (y/b)² <= 1."},
    {"kernels.*.pedicel.stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Spring stiffness k."},
    {"kernels.*.pedicel.damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Damping coefficient c."},
    {"kernels.*.pedicel.rest_length", KeyKind::kValue, "number", "m",
     Bound{-1.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.rest_length_m); },
     "Rest length l0. The default -1 makes the pedicel start unloaded; a value >= 0 sets l0 "
     "explicitly (the stem then starts stretched or compressed)."},
    {"kernels.*.pedicel.detachment_force", KeyKind::kValue, "number", "N",
     Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.detachment_force_N); },
     "Spring-damper force at which the pedicel breaks (rice: 0.27 to 2.6 N)."},
    {"stream", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "A stream of kernels on pedicels that tooth 0 meets at a set rate, generated at load time "
     "with seeded scatter and appended after the `kernels` list (see \"Kernel stream\" below). "
     "Needs at least one tooth and a non-zero `drum.speed`."},
    {"stream.count", KeyKind::kValue, "integer", "", Bound{1.0, 10000.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; }, "Number of kernels."},
    {"stream.rate", KeyKind::kValue, "number", "Hz", Bound{0.0, 1e7, true, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Kernels met per second: the axis of tooth 0 passes kernel j's nominal centre at `start + j / "
     "rate`. The whole stream must pass before the next tooth reaches the first kernel's place."},
    {"stream.start", KeyKind::kValue, "number", "s", Bound{0.0, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.start_s); },
     "When the axis of tooth 0 passes the first kernel's nominal centre."},
    {"stream.seed", KeyKind::kValue, "integer", "", Bound{0.0, 2147483647.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.seed); },
     "Seed of the scatter; the same seed gives the same kernels on every platform."},
    {"stream.depth", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.depth_m); },
     "Nominal kernel centres lie this far inside the circle of radius R + L (the tips of tooth 0's "
     "axis)."},
    {"stream.position_scatter", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.position_scatter_m); },
     "Half-width of the uniform scatter of each centre, radially and along the path."},
    {"stream.angle_scatter", KeyKind::kValue, "number", "rad", Bound{0.0, 10.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.angle_scatter_rad); },
     "Half-width of the uniform scatter of each kernel's long axis about the radial direction."},
    {"stream.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return pair(Vec2(d.kernel.semi_axis_a_m, d.kernel.semi_axis_b_m));
     },
     "Semi-axes of every kernel of the stream. Needs a >= b."},
    {"stream.mass_range", KeyKind::kValue, "[lo, hi]", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.stream.mass_kg); },
     "Each kernel's mass is uniform in this range (paddy 24 to 31 mg). Needs lo <= hi."},
    {"stream.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus of every kernel."},
    {"stream.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of every kernel."},
    {"stream.pedicel_length", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.stream.pedicel_length_m); },
     "Each pedicel runs this far outward from the kernel's outer end; its rest length is that "
     "initial distance (it starts unloaded)."},
    {"stream.pedicel_stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Pedicel spring stiffness."},
    {"stream.pedicel_damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Pedicel damping coefficient."},
    {"stream.detachment_force_range", KeyKind::kValue, "[lo, hi]", "N",
     Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.stream.detach_N); },
     "Each pedicel's detachment force is uniform in this range (rice: 0.27 to 2.6 N). Needs lo <= "
     "hi."},
    {"feed", KeyKind::kOptionalSection, "section", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "absent"; },
     "A continuous feed (issue 34): kernels on pedicels whose anchors ride a straw mat along the "
     "concave at `mat_speed`, arriving at `rate` for as long as the run lasts, each leaving when "
     "it "
     "passes the grate, the concave's exit or `bound_radius` (see \"Continuous feed\" below). "
     "Needs at least one tooth, `drum.speed` > 0 and `integrator.islands: false`."},
    {"feed.rate", KeyKind::kValue, "number", "1/s", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "Kernels fed per second of simulated time (the summary also gives it in kg/s)."},
    {"feed.mat_speed", KeyKind::kValue, "number", "m/s", Bound{0.0, 100.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.mat_speed_mps); },
     "Speed of the straw mat, and of every anchor on it, along +x (the drum's bottom moves along "
     "+x for `drum.speed` > 0)."},
    {"feed.start", KeyKind::kValue, "number", "s", Bound{0.0, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.start_s); },
     "Arrival of the first kernel at the inlet; kernel n arrives at start + n / rate."},
    {"feed.seed", KeyKind::kValue, "integer", "", Bound{0.0, 2147483647.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.seed); },
     "Seed of the scatter (the same feed on every platform)."},
    {"feed.capacity", KeyKind::kValue, "integer", "", Bound{1.0, 10000.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "derived"; },
     "Kernel slots of the pool: kernels in the simulation at once. Default ceil(1.5 rate (exit - "
     "inlet + 2 position_scatter) / mat_speed) + 16; refused below rate (exit - inlet + 2 "
     "position_scatter) / mat_speed, the kernels riding the mat."},
    {"feed.inlet", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "x of the concave's inlet, where anchors arrive. Arriving kernels must be clear of the "
     "teeth's reach by 1 mm."},
    {"feed.exit", KeyKind::kValue, "number", "m", Bound{-10.0, 10.0, false, false},
     [](const SchemaDefaults&) -> std::string { return "required"; },
     "x of the concave's exit: a kernel past it (above the grate) is carried over. Needs exit > "
     "inlet."},
    {"feed.depth", KeyKind::kValue, "number", "m", Bound{-1.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kFeedDepth_m); },
     "Depth of the kernels' centres (at the mat's mid-height, hanging straight) inside the tip "
     "circle of tooth 0 at the drum's bottom; negative: below it."},
    {"feed.mat_thickness", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.mat_thickness_m); },
     "Anchors' heights are uniform over the mat's thickness."},
    {"feed.grate_clearance", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, true, false},
     [](const SchemaDefaults&) -> std::string { return num(kFeedGrateClearance_m); },
     "The grate line lies this far below the tip circle of tooth 0; a kernel below it between "
     "inlet and exit is separated."},
    {"feed.bound_radius", KeyKind::kValue, "number", "m", Bound{0.0, 100.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.bound_radius_m); },
     "A kernel farther than this from the drum axis is out of bounds. Needs to exceed the grate "
     "line's distance from the axis."},
    {"feed.position_scatter", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.position_scatter_m); },
     "+- scatter of each anchor along the mat at arrival."},
    {"feed.angle_scatter", KeyKind::kValue, "number", "rad", Bound{0.0, 3.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.angle_scatter_rad); },
     "+- scatter of each kernel's long axis about hanging straight down."},
    {"feed.semi_axes", KeyKind::kValue, "[a, b]", "m", Bound{1e-6, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string {
       return "[" + num(d.kernel.semi_axis_a_m) + ", " + num(d.kernel.semi_axis_b_m) + "]";
     },
     "Semi-axes of every fed kernel. Needs a >= b."},
    {"feed.mass_range", KeyKind::kValue, "[lo, hi]", "kg", Bound{1e-12, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.feed.mass_kg); },
     "Each kernel's mass is uniform in this range. Needs lo <= hi."},
    {"feed.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.youngs_modulus_Pa); },
     "Young's modulus of every fed kernel."},
    {"feed.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.kernel.poisson_ratio); },
     "Poisson's ratio of every fed kernel."},
    {"feed.pedicel_length", KeyKind::kValue, "number", "m", Bound{0.0, 10.0, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.feed.pedicel_length_m); },
     "Pedicel from the kernel's upper end to its anchor (its rest length)."},
    {"feed.pedicel_stiffness", KeyKind::kValue, "number", "N/m", Bound{0.0, 1e9, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.stiffness_Npm); },
     "Pedicel spring stiffness."},
    {"feed.pedicel_damping", KeyKind::kValue, "number", "N s/m", Bound{0.0, 1e6, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.pedicel.damping_Nspm); },
     "Pedicel damping coefficient."},
    {"feed.detachment_force_range", KeyKind::kValue, "[lo, hi]", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.feed.detach_N); },
     "Each pedicel's detachment force is uniform in this range. Needs lo <= hi."},
    {"obstacles", KeyKind::kList, "list", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "[]"; },
     "Fixed obstacles: plane (half-plane), circle (concave bar), segment (plate). Each type takes "
     "only its own keys."},
    {"obstacles.*.type", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return "required"; }, "Obstacle shape.",
     "plane, circle, segment"},
    {"obstacles.*.point", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (plane, segment)"; },
     "Plane: a point on its boundary line. Segment: end A."},
    {"obstacles.*.normal", KeyKind::kValue, "[x, y]", "", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (plane)"; },
     "Plane only: outward normal pointing to the free side; normalised by the loader. Must not be "
     "zero."},
    {"obstacles.*.point_b", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (segment)"; },
     "Segment only: end B. Must differ from `point`."},
    {"obstacles.*.center", KeyKind::kValue, "[x, y]", "m", Bound{-1e3, 1e3, false, false},
     [](const SchemaDefaults&) -> std::string { return "required (circle)"; },
     "Circle only: centre."},
    {"obstacles.*.radius", KeyKind::kValue, "number", "m", Bound{0.0, 1e3, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.radius_m); },
     "Circle: radius. Segment: half-thickness (0 is a line). A circle needs > 0."},
    {"obstacles.*.youngs_modulus", KeyKind::kValue, "number", "Pa", Bound{1e3, 1e13, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.youngs_modulus_Pa); },
     "Young's modulus of the obstacle (Hertz contact law)."},
    {"obstacles.*.poisson_ratio", KeyKind::kValue, "number", "", Bound{0.0, 0.5, false, true},
     [](const SchemaDefaults& d) -> std::string { return num(d.obstacle.poisson_ratio); },
     "Poisson's ratio of the obstacle."},
    {"contact", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Contact laws per pair kind."},
    {"contact.tooth_kernel", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Tooth-kernel contacts. Defaults: rice-nylon (docs/model.md §10)."},
    {"contact.tooth_kernel.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[0].law); },
     "`compliant`: Hertz force with Hunt-Crossley damping (converges as modes are added). `rigid`: "
     "impulse at impact, then multipliers (the paper's method; needs a modal truncation whose "
     "shortest period is long against the contact time).",
     "compliant, rigid"},
    {"contact.tooth_kernel.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[0].restitution); },
     "Coefficient of restitution e (Newton, or the target of Hunt-Crossley)."},
    {"contact.tooth_kernel.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[0].friction); },
     "Coulomb friction coefficient mu (static = kinetic)."},
    {"contact.kernel_kernel", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Kernel-kernel contacts. Defaults: rice-rice."},
    {"contact.kernel_kernel.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[1].law); },
     "As for `contact.tooth_kernel.law`.", "compliant, rigid"},
    {"contact.kernel_kernel.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[1].restitution); },
     "Coefficient of restitution."},
    {"contact.kernel_kernel.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[1].friction); },
     "Coulomb friction coefficient."},
    {"contact.kernel_obstacle", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Kernel-obstacle contacts. Defaults: wheat-steel (no rice-steel restitution is published; "
     "rice-steel friction is 0.35 to 0.59)."},
    {"contact.kernel_obstacle.law", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults&) -> std::string { return lawWord(kContactDefaults[2].law); },
     "As for `contact.tooth_kernel.law`.", "compliant, rigid"},
    {"contact.kernel_obstacle.restitution", KeyKind::kValue, "number", "",
     Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[2].restitution); },
     "Coefficient of restitution."},
    {"contact.kernel_obstacle.friction", KeyKind::kValue, "number", "",
     Bound{0.0, 100.0, false, false},
     [](const SchemaDefaults&) -> std::string { return num(kContactDefaults[2].friction); },
     "Coulomb friction coefficient."},
    {"contact.hc_min_impact_speed", KeyKind::kValue, "number", "m/s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.hc_min_impact_speed_mps); },
     "Floor on the impact speed v_in in the Hunt-Crossley damping chi = c* / v_in, so that very "
     "slow contacts are not over-damped."},
    {"gravity", KeyKind::kValue, "[x, y]", "m/s^2", Bound{-1e4, 1e4, false, false},
     [](const SchemaDefaults& d) -> std::string { return pair(d.model.gravity_mps2); },
     "Gravitational acceleration in the world frame (acts on the kernels)."},
    {"integrator", KeyKind::kSection, "section", "", kNoRange, kNoDefault, "Time integration."},
    {"integrator.type", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return integratorWord(d.model.integrator.type); },
     "`event_driven`: adaptive smooth steps with located contact events (accurate to the "
     "tolerance). `time_stepping`: Moreau-Jean with a fixed step (robust, first order).",
     "event_driven, time_stepping"},
    {"integrator.tolerance", KeyKind::kValue, "number", "", Bound{1e-13, 0.1, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.tolerance); },
     "Event-driven: local error and event-location tolerance."},
    {"integrator.dt", KeyKind::kValue, "number", "s", Bound{1e-9, 1e-2, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.dt_s); },
     "Time stepping: the fixed step h."},
    {"integrator.theta", KeyKind::kValue, "number", "", Bound{0.5, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.theta); },
     "Time stepping: theta of the Moreau-Jean theta-method."},
    {"integrator.zeno_velocity", KeyKind::kValue, "number", "m/s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.integrator.zeno_velocity_mps);
     },
     "Impacts slower than this are plastic; event-driven: they close the contact (stops Zeno "
     "accumulations). Time stepping: a closed rigid contact sinking `dt` × this below its impact "
     "depth is moved back to it."},
    {"integrator.max_step", KeyKind::kValue, "number", "s", Bound{1e-9, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.max_step_s); },
     "Event-driven: largest smooth step."},
    {"integrator.free_teeth", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return freeTeethWord(d.model.integrator.exact_free_teeth);
     },
     "Event-driven: `exact` advances a tooth that touches nothing, while the drum turns at "
     "constant speed, by the exact solution of its linear modal equations (eigendecomposition of "
     "the tooth's state matrix, built once per drum speed) and leaves its modes out of the error "
     "control; `integrated` integrates every tooth with Dormand-Prince.",
     "exact, integrated"},
    {"integrator.modal_split", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string {
       return modalSplitWord(d.model.integrator.modal_split);
     },
     "Event-driven: `exact` steps a modal tooth in contact, while the drum turns at constant "
     "speed, by a Lawson (integrating-factor) Dormand-Prince: its free modal equations by their "
     "exact propagator (as `free_teeth: exact`), the contact force as the only integrated term, "
     "so that the step follows the contact, not the highest mode (over the trial steps in which "
     "its fastest mode turns by a radian or more); `none` integrates it with plain "
     "Dormand-Prince. A drum ramp or a large-deflection rod always takes `none`.",
     "exact, none"},
    {"integrator.contact_steps", KeyKind::kValue, "integer", "", Bound{0.0, 1000.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.integrator.contact_steps); },
     "Event-driven: the contact phase. While an island (or, under `islands: false`, the system) "
     "has a compliant contact closed and no rigid one, it advances by fixed steps of the Hertz "
     "contact time of its contacts (from the closing speed at first touch) over this count: the "
     "kernels by a kick-drift-kick (velocity Verlet) step, the modal teeth by their exact "
     "propagator between the two half kicks, one force evaluation per step, contacts opening and "
     "closing, sticking and slipping by sign at step ends (each transition's time interpolated "
     "inside its step); see [architecture.md](architecture.md). The drum must turn at constant "
     "speed and the teeth be modal; otherwise the adaptive step runs. `0`: every step adaptive "
     "(Dormand-Prince with located events, the reference)."},
    {"integrator.islands", KeyKind::kValue, "word", "", kNoRange,
     [](const SchemaDefaults& d) -> std::string { return trueFalse(d.model.integrator.islands); },
     "Both integrators: `true` runs the asynchronous island-local scheme (lone bodies on their own "
     "clocks in closed form or with their own small integrator, only bodies that can touch "
     "integrated together, each island on its own; see [architecture.md](architecture.md)); "
     "`false` advances every body with every step and event (the reference).",
     "true, false"},
    {"duration", KeyKind::kValue, "number", "s", Bound{0.0, 1e5, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.duration_s); },
     "Length of a run (`simulate` runs to it)."},
    {"broadphase_margin", KeyKind::kValue, "number", "m", Bound{0.0, 1.0, false, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.broadphase_margin_m); },
     "Pairs farther apart than this are not examined by the narrow phase."},
    {"macro_collision_gap", KeyKind::kValue, "number", "s", Bound{0.0, 1e3, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.model.macro_collision_gap_s); },
     "Contact episodes of one pair belong to the same macro-collision while each starts less than "
     "this after the previous one ended; each episode (compliant law) or impact (rigid law) is one "
     "sub-collision."},
    {"deflection_validity", KeyKind::kValue, "number", "", Bound{0.0, 1.0, true, false},
     [](const SchemaDefaults& d) -> std::string {
       return num(d.model.deflection_validity_fraction);
     },
     "Validity range of the small-deflection beam model as a fraction of the tooth length: once a "
     "tooth tip deflects by more than this times L, the run records one warning (`stats.warnings`, "
     "`simulate`'s summary, the node's `/diagnostics` at WARN level) with the time and the ratio; "
     "`max_tip_deflection_ratio` in the JSON summary is the largest \\|w(L)\\|/L of the run."},
    {"damage", KeyKind::kSection, "section", "", kNoRange, kNoDefault,
     "Damage thresholds for the per-kernel outcomes (not part of the physics)."},
    {"damage.plastic_force", KeyKind::kValue, "number", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.damage.plastic_force_N); },
     "A kernel whose largest contact force reaches this is damaged (plastic deformation)."},
    {"damage.fracture_force", KeyKind::kValue, "number", "N", Bound{0.0, 1e6, true, false},
     [](const SchemaDefaults& d) -> std::string { return num(d.damage.fracture_force_N); },
     "A kernel whose largest contact force reaches this is fractured (brittle fracture). Must be "
     ">= `damage.plastic_force`."},
};

// Keys allowed on each obstacle type.
const std::vector<std::string> kPlaneKeys = {"type", "point", "normal", "youngs_modulus",
                                             "poisson_ratio"};
const std::vector<std::string> kCircleKeys = {"type", "center", "radius", "youngs_modulus",
                                              "poisson_ratio"};
const std::vector<std::string> kSegmentKeys = {"type",   "point",          "point_b",
                                               "radius", "youngs_modulus", "poisson_ratio"};

// Names of the contact sections, indexed by PairKind.
const char* const kPairKeys[3] = {"tooth_kernel", "kernel_kernel", "kernel_obstacle"};

// The schema entry for a pattern such as "teeth.*.length", or nullptr.
const KeySpec* findKey(const std::string& pattern) {
  // By path, made once (the first entry of a path, as the scan of the schema found it).
  static const std::map<std::string, const KeySpec*> table = [] {
    std::map<std::string, const KeySpec*> t;
    for (const KeySpec& spec : kSchema) t.emplace(spec.path, &spec);
    return t;
  }();
  const auto found = table.find(pattern);
  return found != table.end() ? found->second : nullptr;
}

// The key names directly below a pattern ("" is the top level), in schema order, found by a
// scan of the schema.
std::vector<std::string> scanChildKeys(const std::string& pattern) {
  const std::string prefix = pattern.empty() ? "" : pattern + ".";
  std::vector<std::string> keys;
  for (const KeySpec& spec : kSchema) {
    const std::string path = spec.path;
    if (path.size() <= prefix.size() || path.compare(0, prefix.size(), prefix) != 0) continue;
    const std::string rest = path.substr(prefix.size());
    if (rest.find('.') == std::string::npos) keys.push_back(rest);
  }
  return keys;
}

// scanChildKeys of "" and of every schema path and its prefixes, made once: the scan was a
// sixth of a scene check, as every section of every scene asks for its keys.
const std::map<std::string, std::vector<std::string>>& childKeyTable() {
  static const std::map<std::string, std::vector<std::string>> table = [] {
    std::map<std::string, std::vector<std::string>> t;
    t[""] = scanChildKeys("");
    for (const KeySpec& spec : kSchema) {
      const std::string path = spec.path;
      for (size_t dot = 0; dot != std::string::npos;) {
        dot = path.find('.', dot == 0 ? 0 : dot + 1);
        const std::string prefix = path.substr(0, dot);
        if (t.count(prefix) == 0) t[prefix] = scanChildKeys(prefix);
      }
    }
    return t;
  }();
  return table;
}

// The key names directly below a pattern ("" is the top level), in schema order. A pattern
// missing from the table is no prefix of a schema path, so it has no keys below it.
const std::vector<std::string>& childKeys(const std::string& pattern) {
  static const std::vector<std::string> kNone;
  const auto& table = childKeyTable();
  const auto found = table.find(pattern);
  return found != table.end() ? found->second : kNone;
}

// The schema pattern of a written path: list indices become "*" ("teeth.3.length" ->
// "teeth.*.length").
std::string patternOf(const std::string& path) {
  std::string out, part;
  for (size_t i = 0; i <= path.size(); ++i) {
    if (i < path.size() && path[i] != '.') {
      part += path[i];
      continue;
    }
    const bool index = !part.empty() && part.find_first_not_of("0123456789") == std::string::npos;
    out += (out.empty() ? "" : ".") + (index ? std::string("*") : part);
    part.clear();
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Messages.

// Joins a parent path and a key ("" is the top level).
std::string joinPath(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw SceneError((path.empty() ? std::string("scene") : path) + ": " + what);
}

// A node as the user wrote it: flow-style YAML, quoted strings in quotes.
std::string show(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "null";
  if (node.IsScalar() && node.Tag() == "!") return "\"" + node.Scalar() + "\"";
  YAML::Emitter out;
  out.SetSeqFormat(YAML::Flow);
  out.SetMapFormat(YAML::Flow);
  out << node;
  return out.c_str();
}

// A computed number or vector for a message.
std::string show(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6g", value);
  return text;
}
std::string show(const Vec2& v) { return "[" + show(v.x()) + ", " + show(v.y()) + "]"; }

// "a, b, c" -> {a, b, c} (a schema entry's words).
std::vector<std::string> splitWords(const std::string& text) {
  std::vector<std::string> words;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(", ", start), text.size());
    words.push_back(text.substr(start, comma - start));
    start = comma + 2;
  }
  return words;
}

std::string joinWords(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : ", ") + w;
  return out;
}

// Levenshtein distance, for "did you mean" suggestions.
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// "unknown key (did you mean 'length'?)", or the list of known keys when nothing is close.
std::string unknownKey(const std::string& key, const std::vector<std::string>& known,
                       const std::string& owner) {
  std::string what = "unknown key" + (owner.empty() ? "" : " for " + owner);
  const std::string* best = nullptr;
  size_t best_distance = std::numeric_limits<size_t>::max();
  for (const std::string& candidate : known) {
    const size_t d = editDistance(key, candidate);
    if (d < best_distance) {
      best_distance = d;
      best = &candidate;
    }
  }
  if (best != nullptr && best_distance <= std::max<size_t>(2, key.size() / 3)) {
    return what + " (did you mean '" + *best + "'?)";
  }
  return what + " (known keys: " + joinWords(known) + ")";
}

// ---------------------------------------------------------------------------------------------
// Reading values with their bounds.

std::string Bound::text() const {
  if (std::isinf(hi)) return (lo_open ? "> " : ">= ") + num(lo);
  return std::string("in ") + (lo_open ? "(" : "[") + num(lo) + ", " + num(hi) +
         (hi_open ? ")" : "]");
}

// An unquoted scalar that reads as a number (.nan and .inf included).
bool decodeNumber(const YAML::Node& node, double* value) {
  return node.IsScalar() && node.Tag() != "!" && YAML::convert<double>::decode(node, *value);
}

// A finite number; quoted strings, lists, .nan and .inf are refused.
double toNumber(const YAML::Node& node, const std::string& path) {
  double value = 0;
  if (!decodeNumber(node, &value)) fail(path, "expected a number (got " + show(node) + ")");
  if (!std::isfinite(value)) fail(path, "must be finite (got " + show(node) + ")");
  return value;
}

// A mapping read key by key; construction refuses unknown, duplicate and non-string keys. An
// absent mapping (yaml-cpp's invalid node) is held as null, which reads as empty.
class Section {
 public:
  Section(const YAML::Node& node, std::string path, const std::vector<std::string>& known,
          const std::string& owner = "")
      : node_(node.IsDefined() ? node : YAML::Node()), path_(std::move(path)) {
    if (!node.IsDefined() || node.IsNull()) return;
    if (!node.IsMap()) fail(path_, "expected a mapping of keys (got " + show(node) + ")");
    std::vector<std::string> seen;
    for (const auto& entry : node) {
      if (!entry.first.IsScalar()) {
        fail(path_, "expected a key name (got " + show(entry.first) + ")");
      }
      const std::string& key = entry.first.Scalar();
      if (std::find(known.begin(), known.end(), key) == known.end()) {
        fail(joinPath(path_, key), unknownKey(key, known, owner));
      }
      if (std::find(seen.begin(), seen.end(), key) != seen.end()) {
        fail(joinPath(path_, key), "duplicate key");
      }
      seen.push_back(key);
    }
  }

  std::string path(const std::string& key) const { return joinPath(path_, key); }
  bool has(const std::string& key) const { return node_.IsMap() && node_[key].IsDefined(); }
  YAML::Node node(const std::string& key) const {
    return node_.IsMap() ? node_[key] : YAML::Node(YAML::NodeType::Undefined);
  }

  // Refuses a missing required key.
  void require(const std::string& key) const {
    if (!has(key)) fail(path(key), "required key is missing");
  }

  // A finite number in the key's schema range.
  double number(const std::string& key, double fallback) const {
    if (!has(key)) return fallback;
    const double value = toNumber(node(key), path(key));
    const Bound& bound = rangeOf(key);
    if (!bound.contains(value)) {
      fail(path(key), "must be " + bound.text() + " (got " + show(node(key)) + ")");
    }
    return value;
  }

  // An integer in the key's schema range.
  int integer(const std::string& key, int fallback) const {
    if (!has(key)) return fallback;
    const YAML::Node n = node(key);
    int value = 0;
    if (!n.IsScalar() || n.Tag() == "!" || !YAML::convert<int>::decode(n, value)) {
      fail(path(key), "expected an integer (got " + show(n) + ")");
    }
    const Bound& bound = rangeOf(key);
    if (!bound.contains(value)) {
      fail(path(key), "must be " + bound.text() + " (got " + show(n) + ")");
    }
    return value;
  }

  // [x, y] of two finite numbers, each in the key's schema range.
  Vec2 vec2(const std::string& key, const Vec2& fallback) const {
    if (!has(key)) return fallback;
    const YAML::Node n = node(key);
    if (!n.IsSequence() || n.size() != 2) {
      fail(path(key), "expected a list of 2 numbers [x, y] (got " + show(n) + ")");
    }
    Vec2 v;
    const Bound& bound = rangeOf(key);
    for (int i = 0; i < 2; ++i) {
      if (!decodeNumber(n[i], &v[i])) {
        fail(path(key), "expected a list of 2 numbers [x, y] (got " + show(n) + ")");
      }
      if (!std::isfinite(v[i])) fail(path(key), "must be finite (got " + show(n) + ")");
      if (!bound.contains(v[i])) {
        fail(path(key), "each number must be " + bound.text() + " (got " + show(n) + ")");
      }
    }
    return v;
  }

  // The schema words of a word key of this section.
  std::vector<std::string> wordsOf(const std::string& key) const {
    const KeySpec* spec = findKey(patternOf(path(key)));
    return spec != nullptr && spec->words != nullptr ? splitWords(spec->words)
                                                     : std::vector<std::string>();
  }

  // The schema range of a key of this section ("teeth.3" + "length" -> "teeth.*.length").
  const Bound& rangeOf(const std::string& key) const {
    const KeySpec* spec = findKey(patternOf(path(key)));
    return spec != nullptr ? spec->range : kNoRange;
  }

  // One of the key's schema words.
  std::string word(const std::string& key, const std::string& fallback,
                   const std::string& what) const {
    if (!has(key)) return fallback;
    const YAML::Node n = node(key);
    const std::vector<std::string> allowed = wordsOf(key);
    if (!n.IsScalar() || std::find(allowed.begin(), allowed.end(), n.Scalar()) == allowed.end()) {
      const std::string got = n.IsScalar() ? "'" + n.Scalar() + "'" : show(n);
      fail(path(key),
           "unknown " + what + " " + got + " (expected one of: " + joinWords(allowed) + ")");
    }
    return n.Scalar();
  }

  // A nested mapping; absent or null reads as empty (all defaults).
  Section section(const std::string& key, const std::string& pattern) const {
    return Section(node(key), path(key), childKeys(pattern));
  }

  // A list of mappings; absent or null reads as empty.
  std::vector<YAML::Node> list(const std::string& key) const {
    const YAML::Node n = node(key);
    std::vector<YAML::Node> items;
    if (!n.IsDefined() || n.IsNull()) return items;
    if (!n.IsSequence()) fail(path(key), "expected a list (got " + show(n) + ")");
    for (const auto& item : n) items.push_back(item);
    return items;
  }

 private:
  YAML::Node node_;
  std::string path_;
};

// ---------------------------------------------------------------------------------------------
// Sections -> Model.

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
  const bool auto_modes =
      !s.has("modes") || (s.node("modes").IsScalar() && s.node("modes").Tag() != "!" &&
                          s.node("modes").Scalar() == kAutoModesWord);
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
  const YAML::Node pedicel = s.node("pedicel");
  if (pedicel.IsDefined() && !pedicel.IsNull()) {
    k.pedicel = readPedicel(s.section("pedicel", "kernels.*.pedicel"), k);
  }
  return k;
}

// The type decides which keys are allowed; geometry keys are required.
ObstacleModel readObstacle(const YAML::Node& node, const std::string& path) {
  const Section any(node, path, childKeys("obstacles.*"));
  any.require("type");
  const std::string type = any.word("type", "", "obstacle type");
  ObstacleModel o;
  if (type == "plane") {
    const Section s(node, path, kPlaneKeys, "a plane obstacle");
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
    const Section s(node, path, kCircleKeys, "a circle obstacle");
    o.type = ObstacleType::kCircle;
    s.require("center");
    o.center_m = s.vec2("center", o.center_m);
    o.radius_m = s.number("radius", o.radius_m);
    if (!(o.radius_m > 0))
      fail(s.path("radius"), "must be > 0 for a circle (got " + show(s.node("radius")) + ")");
  } else {
    const Section s(node, path, kSegmentKeys, "a segment obstacle");
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

// ---------------------------------------------------------------------------------------------
// Bodies overlapping at the start.

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

// Smallest signed distance from kernel k to the kernels in the grid, the undeformed teeth at
// the initial drum angle and the obstacles; *other names the nearest body.
double clearance(const Model& model, const KernelGrid& grid, const KernelModel& k,
                 std::string* other) {
  const Ellipse e = kernelEllipseAt(k, k.initial_position_m, k.initial_angle_rad);
  Overlap nearest;
  double nearest_m = clearanceFromFixedBodies(model, model.drum.initial_angle_rad, e, &nearest);
  grid.forEachNear(e.center, [&](int j) {
    const KernelModel& kj = model.kernels[j];
    if ((kj.initial_position_m - e.center).norm() > kj.semi_axis_a_m + e.a_m) return;
    const double d_m =
        ellipseEllipse(kernelEllipseAt(kj, kj.initial_position_m, kj.initial_angle_rad), e)
            .distance_m;
    if (d_m < nearest_m) {
      nearest_m = d_m;
      nearest.other_kind = PairKind::kKernelKernel;
      nearest.other = j;
    }
  });
  if (nearest.other >= 0) *other = bodyName(nearest.other_kind, nearest.other);
  return nearest_m;
}

// ---------------------------------------------------------------------------------------------
// Kernel stream: kernels on pedicels that tooth 0 meets at a set rate, with seeded scatter.

// The scatter's numbers: Uniform (core/uniform.h), the same on every standard library.

// [lo, hi] with 0 < lo <= hi.
Vec2 positiveRange(const Section& s, const std::string& key, const Vec2& fallback) {
  const Vec2 range = s.vec2(key, fallback);
  if (!(range.x() > 0 && range.x() <= range.y())) {
    fail(s.path(key), "must be [lo, hi] with 0 < lo <= hi (got " + show(s.node(key)) + ")");
  }
  return range;
}

// Angle of drum rotation from tooth 0 to the next tooth ahead of it in the direction of
// rotation (2 pi with one tooth) [rad].
double angleToNextTooth(const Model& model, double direction) {
  double gap_rad = 2 * kPi;
  for (size_t t = 1; t < model.teeth.size(); ++t) {
    double delta = std::fmod(
        direction * (model.teeth[t].mount_angle_rad - model.teeth[0].mount_angle_rad), 2 * kPi);
    if (delta <= 0) delta += 2 * kPi;
    gap_rad = std::min(gap_rad, delta);
  }
  return gap_rad;
}

// The stream's parameters, and the kernel every draw starts from.

StreamSpec readStreamSpec(const Section& s) {
  StreamSpec spec;
  s.require("count");
  s.require("rate");
  spec.count = s.integer("count", spec.count);
  spec.rate_Hz = s.number("rate", spec.rate_Hz);
  spec.start_s = s.number("start", spec.start_s);
  spec.seed = s.integer("seed", spec.seed);
  spec.depth_m = s.number("depth", spec.depth_m);
  spec.position_scatter_m = s.number("position_scatter", spec.position_scatter_m);
  spec.angle_scatter_rad = s.number("angle_scatter", spec.angle_scatter_rad);
  KernelModel& base = spec.base;
  const Vec2 axes = s.vec2("semi_axes", Vec2(base.semi_axis_a_m, base.semi_axis_b_m));
  if (axes.minCoeff() <= 0 || axes.x() < axes.y()) {
    fail(s.path("semi_axes"),
         "must be [a, b] with a >= b > 0 (got " + show(s.node("semi_axes")) + ")");
  }
  base.semi_axis_a_m = axes.x();
  base.semi_axis_b_m = axes.y();
  spec.mass_kg = positiveRange(s, "mass_range", spec.mass_kg);
  base.youngs_modulus_Pa = s.number("youngs_modulus", base.youngs_modulus_Pa);
  base.poisson_ratio = s.number("poisson_ratio", base.poisson_ratio);
  spec.pedicel_length_m = s.number("pedicel_length", spec.pedicel_length_m);
  base.pedicel.present = true;
  base.pedicel.stiffness_Npm = s.number("pedicel_stiffness", base.pedicel.stiffness_Npm);
  base.pedicel.damping_Nspm = s.number("pedicel_damping", base.pedicel.damping_Nspm);
  base.pedicel.rest_length_m = -1.0;
  base.pedicel.p_KP_K = Vec2(base.semi_axis_a_m, 0.0);
  spec.detach_N = positiveRange(s, "detachment_force_range", spec.detach_N);
  return spec;
}

// The radius of the kernels' centres; refuses a depth that puts them at the drum axis, and a
// stream that would not pass before the next tooth reaches the first kernel's place.
double streamRadius(const Section& s, const Model& model, const StreamSpec& spec) {
  const double omega_radps = model.drum.initial_speed_radps;
  const double direction = omega_radps > 0 ? 1.0 : -1.0;
  const double tip_radius_m = model.drum.radius_m + model.teeth[0].length_m;
  const double radius_m = tip_radius_m - spec.depth_m;
  if (radius_m - spec.position_scatter_m <= spec.base.semi_axis_a_m) {
    fail(s.path("depth"), "puts the kernels at the drum axis (centre radius " + show(radius_m) +
                              " m, got " + show(s.node("depth")) + ")");
  }
  const double span_rad = std::abs(omega_radps) * (spec.start_s + (spec.count - 1) / spec.rate_Hz) +
                          spec.position_scatter_m / (radius_m - spec.position_scatter_m);
  const double gap_rad = angleToNextTooth(model, direction);
  if (span_rad >= gap_rad) {
    fail(s.path("rate"), "the stream spans " + show(span_rad) +
                             " rad of drum rotation but the next tooth follows tooth 0 after " +
                             show(gap_rad) + " rad; lower count or start, or raise rate (got " +
                             show(s.node("rate")) + ")");
  }
  return radius_m;
}

// One draw of kernel j (arriving at arrival_s) at centre radius radius_m: position, angle,
// pedicel anchor, mass and detachment force with their scatter.
void drawStreamKernel(const Model& model, const StreamSpec& spec, double radius_m, double arrival_s,
                      Uniform* uniform, KernelModel* k) {
  const double theta0_rad = model.drum.initial_angle_rad + model.teeth[0].mount_angle_rad;
  const double scatter_m = spec.position_scatter_m;
  const double r_m = radius_m + (*uniform)(-scatter_m, scatter_m);
  const double phi_rad = theta0_rad + model.drum.initial_speed_radps * arrival_s +
                         (*uniform)(-scatter_m, scatter_m) / r_m;
  const double psi_rad = phi_rad + (*uniform)(-spec.angle_scatter_rad, spec.angle_scatter_rad);
  const Vec2 axis(std::cos(psi_rad), std::sin(psi_rad));
  k->initial_position_m = r_m * Vec2(std::cos(phi_rad), std::sin(phi_rad));
  k->initial_angle_rad = psi_rad;
  k->pedicel.p_WA_W = k->initial_position_m + (k->semi_axis_a_m + spec.pedicel_length_m) * axis;
  k->mass_kg = (*uniform)(spec.mass_kg.x(), spec.mass_kg.y());
  k->pedicel.detachment_force_N = (*uniform)(spec.detach_N.x(), spec.detach_N.y());
}

// Appends the stream's kernels. Kernel j sits where the axis of tooth 0 is at time
// start + j / rate (drum at its initial speed), depth inside the tip circle, its long axis
// radial, held at its outer end by a pedicel running on outward; then scatter: uniform
// +-position_scatter radially and along the path, +-angle_scatter on the orientation, mass and
// detachment force uniform in their ranges. A draw that overlaps a body is redrawn.
void readStream(const Section& scene, Model* model) {
  const YAML::Node node = scene.node("stream");
  if (!node.IsDefined() || node.IsNull()) return;
  const Section s = scene.section("stream", "stream");
  if (model->teeth.empty()) fail("stream", "needs at least one tooth (teeth is empty)");
  if (model->drum.initial_speed_radps == 0)
    fail("drum.speed", "must not be 0 with a kernel stream");
  const StreamSpec spec = readStreamSpec(s);
  const double radius_m = streamRadius(s, *model, spec);
  // Kernels, each redrawn until it clears every body placed before it.
  Uniform uniform(static_cast<unsigned long long>(spec.seed));
  constexpr int kMaxDraws = 100;
  double largest_a_m = spec.base.semi_axis_a_m;
  for (const KernelModel& k : model->kernels) largest_a_m = std::max(largest_a_m, k.semi_axis_a_m);
  KernelGrid grid(2.0 * largest_a_m);
  for (size_t i = 0; i < model->kernels.size(); ++i)
    grid.insert(static_cast<int>(i), model->kernels[i].initial_position_m);
  for (int j = 0; j < spec.count; ++j) {
    KernelModel k = spec.base;
    std::string other;
    double distance_m = -1;
    for (int draw = 0; draw < kMaxDraws && distance_m < 0; ++draw) {
      drawStreamKernel(*model, spec, radius_m, spec.start_s + j / spec.rate_Hz, &uniform, &k);
      distance_m = clearance(*model, grid, k, &other);
    }
    if (distance_m < 0) {
      fail("stream", "kernel " + std::to_string(j) + " still overlaps " + other + " after " +
                         std::to_string(kMaxDraws) +
                         " draws; lower the scatter or the rate, or change the seed");
    }
    grid.insert(static_cast<int>(model->kernels.size()), k.initial_position_m);
    model->kernels.push_back(k);
  }
}

// ---------------------------------------------------------------------------------------------
// Continuous feed (core/feed.h): the section's values, the geometry from tooth 0's tip circle,
// the pool's capacity.

// The section's values and the kernel every fed kernel starts from.
FeedSpec readFeedValues(const Section& s) {
  FeedSpec spec;
  s.require("rate");
  s.require("inlet");
  s.require("exit");
  spec.rate_per_s = s.number("rate", spec.rate_per_s);
  spec.mat_speed_mps = s.number("mat_speed", spec.mat_speed_mps);
  spec.start_s = s.number("start", spec.start_s);
  spec.seed = s.integer("seed", spec.seed);
  spec.inlet_x_m = s.number("inlet", spec.inlet_x_m);
  spec.exit_x_m = s.number("exit", spec.exit_x_m);
  if (!(spec.exit_x_m > spec.inlet_x_m)) {
    fail(s.path("exit"), "must be greater than feed.inlet (" + show(spec.inlet_x_m) + " m) (got " +
                             show(spec.exit_x_m) + ")");
  }
  spec.mat_thickness_m = s.number("mat_thickness", spec.mat_thickness_m);
  spec.bound_radius_m = s.number("bound_radius", spec.bound_radius_m);
  spec.position_scatter_m = s.number("position_scatter", spec.position_scatter_m);
  spec.angle_scatter_rad = s.number("angle_scatter", spec.angle_scatter_rad);
  KernelModel& base = spec.base;
  const Vec2 axes = s.vec2("semi_axes", Vec2(base.semi_axis_a_m, base.semi_axis_b_m));
  if (axes.x() < axes.y()) {
    fail(s.path("semi_axes"), "must be [a, b] with a >= b (got " + show(s.node("semi_axes")) + ")");
  }
  base.semi_axis_a_m = axes.x();
  base.semi_axis_b_m = axes.y();
  spec.mass_kg = positiveRange(s, "mass_range", spec.mass_kg);
  base.youngs_modulus_Pa = s.number("youngs_modulus", base.youngs_modulus_Pa);
  base.poisson_ratio = s.number("poisson_ratio", base.poisson_ratio);
  spec.pedicel_length_m = s.number("pedicel_length", spec.pedicel_length_m);
  base.pedicel.stiffness_Npm = s.number("pedicel_stiffness", base.pedicel.stiffness_Npm);
  base.pedicel.damping_Nspm = s.number("pedicel_damping", base.pedicel.damping_Nspm);
  spec.detach_N = positiveRange(s, "detachment_force_range", spec.detach_N);
  return spec;
}

// Refuses an inlet within the teeth's reach: every point a kernel can occupy at arrival (within
// 2 a + pedicel length of an anchor in the box of the position scatter and the mat's thickness)
// must lie outside every tooth's tip circle grown by its radius and 1 mm.
void checkInletClear(const Section& s, const Model& model, const FeedSpec& spec) {
  double reach_m = 0;
  for (const ToothModel& t : model.teeth)
    reach_m = std::max(reach_m, model.drum.radius_m + t.length_m + 0.5 * t.diameter_m);
  const double x_m = std::max(spec.inlet_x_m - spec.position_scatter_m,
                              std::min(0.0, spec.inlet_x_m + spec.position_scatter_m));
  const double y_m = std::max(spec.anchor_y_m - 0.5 * spec.mat_thickness_m,
                              std::min(0.0, spec.anchor_y_m + 0.5 * spec.mat_thickness_m));
  const double kernel_m = 2 * spec.base.semi_axis_a_m + spec.pedicel_length_m;
  const double gap_m = std::hypot(x_m, y_m) - kernel_m - reach_m;
  if (!(gap_m > 1e-3)) {
    fail(s.path("inlet"), "puts arriving kernels within the teeth's reach (" + show(reach_m) +
                              " m from the axis, " + show(gap_m) +
                              " m clear; needs 1 mm): move it away from the drum (got " +
                              show(s.node("inlet")) + ")");
  }
}

// The mat's and the grate's heights from tooth 0's tip circle, then the pool's capacity
// (given, or derived from the kernels riding the mat).
void placeFeed(const Section& s, const Model& model, FeedSpec* spec) {
  const double tip_radius_m = model.drum.radius_m + model.teeth[0].length_m;
  const double depth_m = s.number("depth", kFeedDepth_m);
  spec->anchor_y_m = -(tip_radius_m - depth_m) + spec->base.semi_axis_a_m + spec->pedicel_length_m;
  spec->grate_y_m = -(tip_radius_m + s.number("grate_clearance", kFeedGrateClearance_m));
  if (!(spec->grate_y_m < spec->anchor_y_m - spec->base.semi_axis_a_m - spec->pedicel_length_m)) {
    fail(s.path("grate_clearance"), "puts the grate above the kernels (depth " + show(depth_m) +
                                        " m) (got " + show(s.node("grate_clearance")) + ")");
  }
  if (!(spec->bound_radius_m > -spec->grate_y_m)) {
    fail(s.path("bound_radius"), "must exceed the grate's distance from the axis, " +
                                     show(-spec->grate_y_m) + " m (got " +
                                     show(spec->bound_radius_m) + ")");
  }
  checkInletClear(s, model, *spec);
  const double on_mat = spec->rate_per_s *
                        (spec->exit_x_m - spec->inlet_x_m + 2 * spec->position_scatter_m) /
                        spec->mat_speed_mps;
  if (s.has("capacity")) {
    spec->capacity = s.integer("capacity", 0);
    if (spec->capacity < on_mat) {
      fail(s.path("capacity"), "cannot hold the " + show(std::ceil(on_mat)) +
                                   " kernels riding the mat (rate x span / mat_speed) (got " +
                                   show(s.node("capacity")) + ")");
    }
    return;
  }
  const double derived = std::ceil(1.5 * on_mat) + 16;
  if (derived > 10000) {
    fail(s.path("rate"),
         "needs a pool of " + show(derived) +
             " kernel slots, more than 10000 (rate x span / mat_speed = " + show(on_mat) +
             " kernels on the mat); lower it or raise "
             "feed.mat_speed (got " +
             show(s.node("rate")) + ")");
  }
  spec->capacity = static_cast<int>(derived);
}

// The feed of the scene (capacity 0 when it has none); refuses a feed the scene cannot run.
FeedSpec readFeed(const Section& scene, const Model& model) {
  const YAML::Node node = scene.node("feed");
  if (!node.IsDefined() || node.IsNull()) return FeedSpec();
  const Section s = scene.section("feed", "feed");
  FeedSpec spec = readFeedValues(s);
  if (model.teeth.empty()) fail("feed", "needs at least one tooth (teeth is empty)");
  if (!(model.drum.initial_speed_radps > 0)) {
    fail("drum.speed",
         "must be > 0 with a feed (the mat moves along +x, with the drum's bottom) "
         "(got " +
             show(model.drum.initial_speed_radps) + ")");
  }
  if (model.integrator.islands) {
    fail("integrator.islands",
         "must be false with a feed (its moving anchors are in the global "
         "scheme only) (got true)");
  }
  placeFeed(s, model, &spec);
  return spec;
}

// ---------------------------------------------------------------------------------------------
// Outcome settings.

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

// ---------------------------------------------------------------------------------------------
// Overrides.

std::string trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

bool isIndex(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string entries(size_t n) { return std::to_string(n) + (n == 1 ? " entry" : " entries"); }

[[noreturn]] void refuseOverride(const std::string& assignment, const std::string& path,
                                 const std::string& what) {
  throw SceneError((path.empty() ? "" : path + ": ") + what + " in override '" + assignment + "'");
}

// "a.b.0.c" -> {"a", "b", "0", "c"}; empty components are refused.
std::vector<std::string> splitKeyPath(const std::string& assignment, const std::string& key_path) {
  std::vector<std::string> parts;
  for (size_t start = 0;;) {
    const size_t dot = key_path.find('.', start);
    parts.push_back(key_path.substr(start, dot - start));
    if (parts.back().empty()) refuseOverride(assignment, key_path, "empty key path component");
    if (dot == std::string::npos) return parts;
    start = dot + 1;
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public API.

YAML::Node loadSceneYaml(const std::string& path) {
  struct stat info;
  if (::stat(path.c_str(), &info) == 0 && S_ISDIR(info.st_mode))
    throw SceneError(path + ": is a directory, not a YAML file");
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw SceneError(path + ": cannot open scene file");
  } catch (const YAML::ParserException& e) {
    throw SceneError(path + ":" + std::to_string(e.mark.line + 1) + ":" +
                     std::to_string(e.mark.column + 1) + ": YAML syntax error: " + e.msg);
  }
}

// The key path and the value's text of an assignment "key.path=value"; refuses a missing '='
// or an empty side.
void splitAssignment(const std::string& assignment, std::string* key_path,
                     std::string* value_text) {
  const size_t equals = assignment.find('=');
  if (equals == std::string::npos) refuseOverride(assignment, "", "expected key.path=value");
  *key_path = trim(assignment.substr(0, equals));
  *value_text = trim(assignment.substr(equals + 1));
  if (key_path->empty()) refuseOverride(assignment, "", "empty key path");
  if (value_text->empty()) refuseOverride(assignment, *key_path, "empty value");
}

// Whether YAML reads the text as a plain scalar of that very text: a number-like word (a
// digit first, or a sign or point and then a digit; letters, digits and "_.+-" after). No such
// text is a null ("~", "null"), a document marker ("---", "...") or a list item ("- ").
bool plainNumberLike(const std::string& text) {
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  const bool starts =
      !text.empty() && (digit(text[0]) || (text.size() > 1 && digit(text[1]) &&
                                           (text[0] == '-' || text[0] == '+' || text[0] == '.')));
  return starts && std::all_of(text.begin(), text.end(), [&](char c) {
           return digit(c) || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' ||
                  c == '.' || c == '+' || c == '-';
         });
}

// The value of an assignment (YAML, so lists and mappings work); refuses one that is not YAML.
// A number-like word becomes the plain scalar YAML::Load would give (tag "?"), without the
// parser (a tenth of a scene check went to parsing the --set numbers).
YAML::Node parseValue(const std::string& assignment, const std::string& key_path,
                      const std::string& value_text) {
  if (plainNumberLike(value_text)) {
    YAML::Node scalar(value_text);
    scalar.SetTag("?");
    return scalar;
  }
  try {
    return YAML::Load(value_text);
  } catch (const YAML::ParserException& e) {
    refuseOverride(assignment, key_path, "value is not valid YAML (" + e.msg + ")");
  }
  return YAML::Node();
}

// Descends from a mapping into its section `part` (at `path`, of schema kind spec.kind) on the
// way to `next_part`: a missing section is created (when checking only, a fresh empty mapping
// stands for it and the tree is left alone), other missing containers are refused.
void descendIntoSection(const std::string& assignment, const KeySpec& spec, const std::string& path,
                        const std::string& part, const std::string& next_part, bool apply,
                        YAML::Node* node) {
  const auto refuse = [&](const std::string& at, const std::string& what) {
    refuseOverride(assignment, at, what);
  };
  const YAML::Node& current = *node;  // a const lookup adds no key
  const YAML::Node child = current[part];
  const bool absent = !child.IsDefined() || child.IsNull();
  if (spec.kind == KeyKind::kValue) refuse(path, "is a value, not a section");
  if (absent && spec.kind == KeyKind::kList) {
    refuse(joinPath(path, next_part), "index out of range (" + path + " has no entries)");
  }
  if (absent && spec.kind == KeyKind::kOptionalSection) {
    refuse(path,
           "is absent; set the whole " + part + " first (e.g. " + path + "={anchor: [x, y]})");
  }
  if (!absent) {
    node->reset(child);
  } else if (apply) {
    (*node)[part] = YAML::Node(YAML::NodeType::Map);
    node->reset((*node)[part]);
  } else {
    node->reset(YAML::Node(YAML::NodeType::Map));
  }
}

// One pass of applyOverride over the tree: with apply false it only walks the path and throws
// what the assignment would throw, leaving the tree alone; with apply true it sets the value.
// `given` is the value when it was parsed already (by the first pass), else it is parsed here
// (into *parsed when not null); each item of a "*" gets a node of its own, as two items
// sharing one node would change together. Only the nodes on the path are visited: the rest of
// the tree is neither copied nor read.
void overridePass(YAML::Node* root, const std::string& assignment, bool apply,
                  const YAML::Node* given, YAML::Node* parsed) {
  const auto refuse = [&](const std::string& path, const std::string& what) {
    refuseOverride(assignment, path, what);
  };
  std::string key_path, value_text;
  splitAssignment(assignment, &key_path, &value_text);
  const YAML::Node value = given != nullptr ? *given : parseValue(assignment, key_path, value_text);
  if (parsed != nullptr) parsed->reset(value);
  const std::vector<std::string> parts = splitKeyPath(assignment, key_path);
  const bool empty_root = !root->IsDefined() || root->IsNull();
  if (empty_root && apply) root->reset(YAML::Node(YAML::NodeType::Map));
  YAML::Node node = empty_root && !apply ? YAML::Node(YAML::NodeType::Map) : *root;
  std::string path;     // as written, e.g. "teeth.0"
  std::string pattern;  // schema form, e.g. "teeth.*"
  for (size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    const bool last = i + 1 == parts.size();
    const std::string parent = path;
    path = joinPath(path, part);

    // A list item: the index must exist; "*" sets every item (each its own assignment, with
    // its own copy of the value).
    if (node.IsSequence()) {
      if (part == "*") {
        const size_t n_items = node.size();
        if (n_items == 0) refuse(parent, "has no entries to set");
        std::string rest;
        for (size_t j = i + 1; j < parts.size(); ++j) rest = joinPath(rest, parts[j]);
        for (size_t index = 0; index < n_items; ++index) {
          const std::string item = joinPath(parent, std::to_string(index));
          // Checking needs no node of its own; setting does, except for the first item.
          const YAML::Node* item_value = (!apply || index == 0) ? &value : nullptr;
          overridePass(root, (rest.empty() ? item : item + "." + rest) + "=" + value_text, apply,
                       item_value, nullptr);
        }
        return;
      }
      if (!isIndex(part)) refuse(parent, "is a list; expected an index, got '" + part + "'");
      const size_t index = part.size() < 10 ? std::stoul(part) : node.size();
      if (index >= node.size()) {
        refuse(path, "index out of range (" + parent + " has " + entries(node.size()) + ")");
      }
      pattern += ".*";
      if (last) {
        if (apply) node[index] = value;
      } else {
        const YAML::Node& list = node;
        node.reset(list[index]);
      }
      continue;
    }

    // A key of a mapping: it must be in the schema.
    if (!node.IsMap()) refuse(parent, "is a value, not a section (got " + show(node) + ")");
    const std::string key_pattern = joinPath(pattern, part);
    const KeySpec* spec = findKey(key_pattern);
    if (spec == nullptr) refuse(path, unknownKey(part, childKeys(pattern), ""));
    pattern = key_pattern;
    if (last) {
      if (apply) node[part] = value;
      continue;
    }

    descendIntoSection(assignment, *spec, path, part, parts[i + 1], apply, &node);
  }
}

// Checks the whole assignment first (every item of a "*" included), then applies it: a
// refused assignment leaves the tree as it was, and no copy of the tree is made.
void applyOverride(YAML::Node* root, const std::string& assignment) {
  YAML::Node value;
  overridePass(root, assignment, false, nullptr, &value);
  overridePass(root, assignment, true, &value, nullptr);
}

std::vector<std::string> overridesFromFile(const std::string& path) {
  const YAML::Node root = loadSceneYaml(path);
  if (!root.IsMap()) {
    throw SceneError(path + ": expected a mapping of key paths to values (got " + show(root) + ")");
  }
  std::vector<std::string> assignments;
  for (const auto& entry : root) {
    if (!entry.first.IsScalar()) {
      throw SceneError(path + ": expected a key path (got " + show(entry.first) + ")");
    }
    assignments.push_back(entry.first.Scalar() + "=" + show(entry.second));
  }
  return assignments;
}

Model modelFromYaml(const YAML::Node& root, ToothCache* tooth_cache, FeedSpec* feed) {
  if (!root.IsMap()) {
    fail("", "expected a mapping of sections at the top level (got " + show(root) + ")");
  }
  const Section scene(root, "", childKeys(""));
  Model model;

  // Drum and teeth.
  readDrum(scene, &model.drum);
  const std::vector<YAML::Node> teeth = scene.list("teeth");
  for (size_t i = 0; i < teeth.size(); ++i) {
    model.teeth.push_back(
        readTooth(Section(teeth[i], "teeth." + std::to_string(i), childKeys("teeth.*"))));
  }

  // Kernels and obstacles.
  const std::vector<YAML::Node> kernels = scene.list("kernels");
  for (size_t i = 0; i < kernels.size(); ++i) {
    model.kernels.push_back(
        readKernel(Section(kernels[i], "kernels." + std::to_string(i), childKeys("kernels.*"))));
  }
  const std::vector<YAML::Node> obstacles = scene.list("obstacles");
  for (size_t i = 0; i < obstacles.size(); ++i) {
    model.obstacles.push_back(readObstacle(obstacles[i], "obstacles." + std::to_string(i)));
  }
  readStream(scene, &model);

  // Contact laws, gravity, integrator and run settings.
  readContact(scene, &model);
  model.gravity_mps2 = scene.vec2("gravity", model.gravity_mps2);
  readIntegrator(scene, &model.integrator);
  model.duration_s = scene.number("duration", model.duration_s);
  model.broadphase_margin_m = scene.number("broadphase_margin", model.broadphase_margin_m);
  model.macro_collision_gap_s = scene.number("macro_collision_gap", model.macro_collision_gap_s);
  model.deflection_validity_fraction =
      scene.number("deflection_validity", model.deflection_validity_fraction);
  readDamage(scene);  // validated here; damageFromYaml() returns it

  // Start configuration, then the feed's pool (parked far away), the core's own checks and
  // derived quantities.
  checkInitialOverlaps(model);
  const FeedSpec feed_spec = readFeed(scene, model);
  if (feed_spec.capacity > 0 && feed == nullptr) {
    fail("feed",
         "this program does not run a feed (simulate SCENE.yaml runs one; the node and "
         "simulate --batch do not yet)");
  }
  try {
    if (feed_spec.capacity > 0) addFeedPool(feed_spec, &model);
    if (feed != nullptr) *feed = feed_spec;
    compileModel(&model, tooth_cache);
  } catch (const std::invalid_argument& e) {
    throw SceneError(e.what());
  }
  return model;
}

DamageThresholds damageFromYaml(const YAML::Node& root) {
  if (!root.IsMap()) return DamageThresholds();
  return readDamage(Section(root, "", childKeys("")));
}

Model loadScene(const std::string& path, const std::vector<std::string>& overrides,
                DamageThresholds* damage, FeedSpec* feed) {
  YAML::Node root = loadSceneYaml(path);
  // An empty file, or one holding a single value, is no scene, with or without overrides.
  if (!root.IsMap())
    throw SceneError(
        path + ": expected a mapping of sections at the top level (got " +
        (root.IsNull() || !root.IsDefined() ? std::string("an empty file") : show(root)) + ")");
  for (const std::string& assignment : overrides) applyOverride(&root, assignment);
  try {
    Model model = modelFromYaml(root, nullptr, feed);
    if (damage != nullptr) *damage = damageFromYaml(root);
    return model;
  } catch (const SceneError& e) {
    throw SceneError(path + ": " + e.what());
  }
}

std::string sceneSchemaTable() {
  const SchemaDefaults defaults;
  std::string out =
      "| key path | type | unit | default | range | meaning |\n"
      "|---|---|---|---|---|---|\n";
  for (const KeySpec& spec : kSchema) {
    const bool ranged = !std::isinf(spec.range.lo) || !std::isinf(spec.range.hi);
    const std::string dflt = spec.default_text ? spec.default_text(defaults) : "";
    std::string range = ranged ? spec.range.text() : "";
    if (spec.words != nullptr) {
      for (const std::string& w : splitWords(spec.words))
        range += (range.empty() ? "`" : ", `") + w + "`";
    }
    out += std::string("| `") + spec.path + "` | " + spec.type + " | " + spec.unit + " | " + dflt +
           " | " + range + " | " + spec.doc + " |\n";
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> sceneSchemaDefaults() {
  const SchemaDefaults defaults;
  std::vector<std::pair<std::string, std::string>> out;
  for (const KeySpec& spec : kSchema)
    out.emplace_back(spec.path, spec.default_text ? spec.default_text(defaults) : "");
  return out;
}

std::vector<std::string> sceneKeyPaths() {
  std::vector<std::string> paths;
  for (const KeySpec& spec : kSchema) paths.push_back(spec.path);
  return paths;
}

}  // namespace threshing_sim
