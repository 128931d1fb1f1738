// threshing_sim scene files: YAML -> validated, compiled Model.
//
// Every key, its unit, default and range is documented in docs/scene_reference.md.
// Errors are reported as SceneError whose message names the key path and the bad value,
// e.g. "kernels.0.mass: must be > 0 (got -1)".
#pragma once

#include <yaml-cpp/yaml.h>

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/tooth_cache.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Parses a scene file into a YAML tree (no validation yet). Throws SceneError.
YAML::Node loadSceneYaml(const std::string& path);

// Applies one "key.path=value" override in place (e.g. "teeth.0.modes=0",
// "drum.speed=120", "kernels.1.position=[0.01, 0.25]"). The path must name an existing key or
// a known optional key; "*" in place of a list index sets every item of a non-empty list
// ("teeth.*.modes=0"). Throws SceneError naming the path; the tree is unchanged then. The
// tree is changed in place: only the nodes on the path are visited (no copy of the tree), so
// other handles to the same tree see the change (apply to a YAML::Clone to keep the original).
void applyOverride(YAML::Node* root, const std::string& assignment);

// The overrides of an override file: a YAML mapping of key paths to values, e.g.
// "teeth.*.youngs_modulus: 2.06e11", returned as "key.path=value" in file order (values in
// flow style) for applyOverride. Throws SceneError.
std::vector<std::string> overridesFromFile(const std::string& path);

// Validates the tree (unknown keys, missing keys, types, ranges, NaN/inf, semi-axes order,
// kernels overlapping at start), expands a kernel `stream` into kernels appended after the
// listed ones (deterministic from its seed; docs/scene_reference.md) and returns the
// compiled model (its teeth compiled through *tooth_cache when given). A `feed` section appends
// its pool's parked kernel slots after them (core/feed.h) and is returned in *feed when given
// (capacity 0: no feed). Throws SceneError.
Model modelFromYaml(const YAML::Node& root, ToothCache* tooth_cache = nullptr,
                    FeedSpec* feed = nullptr);

// The outcome settings of a scene (section `damage`; defaults for rice when absent). The tree
// must have passed modelFromYaml, which validates the section. Throws SceneError.
DamageThresholds damageFromYaml(const YAML::Node& root);

// loadSceneYaml + applyOverride for each override + modelFromYaml (and damageFromYaml into
// *damage when given). Validation errors are prefixed with the file path.
Model loadScene(const std::string& path, const std::vector<std::string>& overrides = {},
                DamageThresholds* damage = nullptr, FeedSpec* feed = nullptr);

// loadScene with override files: each file is read first (a bad override file is refused
// before the scene file is read), and their entries apply in order (applyOverrideFile,
// scene_tree.h) before the overrides: the model of loadScene(path, the files'
// overridesFromFile followed by overrides), without writing the files' values out as text and
// parsing them back.
Model loadSceneWithFiles(const std::string& path, const std::vector<std::string>& override_files,
                         const std::vector<std::string>& overrides, DamageThresholds* damage,
                         FeedSpec* feed);

// The schema as a Markdown table: every key path with its type, unit, default, accepted range
// (each finite) or words, and meaning. `simulate --print-schema` prints it; docs/
// scene_reference.md's key table is its output (scripts/scene_reference.sh).
std::string sceneSchemaTable();

// Every key's default as the reference prints it, by key path ("" for a section, "required",
// "absent" for an optional section, "[]" for a list).
std::vector<std::pair<std::string, std::string>> sceneSchemaDefaults();

// Every key path a scene may hold, list items written as "*" (e.g. "teeth.*.length"), in
// document order. docs/scene_reference.md has one row per path.
std::vector<std::string> sceneKeyPaths();

}  // namespace threshing_sim
