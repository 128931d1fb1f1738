// The scene schema: every key path a scene may hold (list items written as "*"), its kind,
// type, unit, default, range, words and meaning, in one table (schema_table.cc). The readers
// take each range and word list from it, the override walker decides from it which missing
// keys may be created, and `simulate --print-schema` prints it (docs/scene_reference.md).
#pragma once

#include <limits>
#include <string>
#include <vector>

#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {
namespace loader {

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
inline const Bound kNoRange{};

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
inline const ContactParams kContactDefaults[3] = {
    {ContactLaw::kCompliant, 0.48, 0.53},
    {ContactLaw::kRigid, 0.34, 0.66},
    {ContactLaw::kRigid, 0.47, 0.50},
};

// Names of the contact sections, indexed by PairKind.
inline const char* const kPairKeys[3] = {"tooth_kernel", "kernel_kernel", "kernel_obstacle"};

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
std::string num(double value);
std::string pair(const Vec2& v);

// The words of the scene file for the core's enumerations and switches (readers and the
// reference use the same ones).
inline const char* const kAutoModesWord = "auto";  // teeth.*.modes when absent: compileModel's
inline std::string toothModelWord(ToothBeamModel m) {
  return m == ToothBeamModel::kLargeDeflection ? "large_deflection" : "modal";
}
inline std::string sectionRotationWord(ToothSectionRotation r) {
  return r == ToothSectionRotation::kEulerBernoulli ? "euler_bernoulli" : "shear_corrected";
}
inline std::string lawWord(ContactLaw law) {
  return law == ContactLaw::kRigid ? "rigid" : "compliant";
}
inline std::string integratorWord(IntegratorType t) {
  return t == IntegratorType::kTimeStepping ? "time_stepping" : "event_driven";
}
inline std::string onOff(bool on) { return on ? "on" : "off"; }
inline std::string trueFalse(bool on) { return on ? "true" : "false"; }
inline std::string freeTeethWord(bool exact) { return exact ? "exact" : "integrated"; }
inline std::string modalSplitWord(bool exact) { return exact ? "exact" : "none"; }

// A key's default as the reference prints it, from the defaults above; nullptr: none (sections).
using DefaultText = std::string (*)(const SchemaDefaults&);
inline const DefaultText kNoDefault = nullptr;

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

// The one table of scene keys (schema_table.cc), in document order.
extern const KeySpec kSchema[];
extern const size_t kSchemaSize;

// kSchema as a range for range-for loops.
struct SchemaRange {
  const KeySpec* first;
  const KeySpec* last;
  const KeySpec* begin() const { return first; }
  const KeySpec* end() const { return last; }
};
inline SchemaRange schema() { return {kSchema, kSchema + kSchemaSize}; }

// Keys allowed on each obstacle type.
inline const std::vector<std::string> kPlaneKeys = {"type", "point", "normal", "youngs_modulus",
                                                    "poisson_ratio"};
inline const std::vector<std::string> kCircleKeys = {"type", "center", "radius", "youngs_modulus",
                                                     "poisson_ratio"};
inline const std::vector<std::string> kSegmentKeys = {"type",   "point",          "point_b",
                                                      "radius", "youngs_modulus", "poisson_ratio"};

// The schema entry for a pattern such as "teeth.*.length", or nullptr.
const KeySpec* findKey(const std::string& pattern);

// The key names directly below a pattern ("" is the top level), in schema order; none for a
// pattern that is no prefix of a schema path.
const std::vector<std::string>& childKeys(const std::string& pattern);

// Keys a mapping at a schema pattern may hold, with their schema entries (nullptr for a key
// not in the schema), in the same order.
struct Children {
  std::string pattern;  // e.g. "kernels.*"
  std::vector<std::string> keys;
  std::vector<const KeySpec*> specs;
};

// The schema's keys below a pattern (childKeys with their entries), made once; none for a
// pattern that is no prefix of a schema path.
const Children& children(const std::string& pattern);

// Chosen keys below a pattern (an obstacle type's).
Children childrenOf(const std::string& pattern, const std::vector<std::string>& keys);

// The schema pattern of a written path: list indices become "*" ("teeth.3.length" ->
// "teeth.*.length").
std::string patternOf(const std::string& path);

// "a, b, c" -> {a, b, c} (a schema entry's words).
std::vector<std::string> splitWords(const std::string& text);

}  // namespace loader
}  // namespace threshing_sim
