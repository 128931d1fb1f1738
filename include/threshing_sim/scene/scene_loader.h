// threshing_sim scene files: YAML -> validated, compiled Model.
//
// Every key, its unit, default and range is documented in docs/scene_reference.md.
// Errors are reported as SceneError whose message names the key path and the bad value,
// e.g. "kernels.0.mass: must be > 0 (got -1)".
#pragma once

#include <yaml-cpp/yaml.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "threshing_sim/core/model.h"

namespace threshing_sim {

class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Parses a scene file into a YAML tree (no validation yet). Throws SceneError.
YAML::Node loadSceneYaml(const std::string& path);

// Applies one "key.path=value" override in place (e.g. "teeth.0.modes=0",
// "drum.speed=120", "kernels.1.position=[0.01, 0.25]"). The path must name an existing key or
// a known optional key. Throws SceneError naming the path.
void applyOverride(YAML::Node* root, const std::string& assignment);

// Validates the tree (unknown keys, missing keys, types, ranges, NaN/inf, semi-axes order,
// kernels overlapping at start) and returns the compiled model. Throws SceneError.
Model modelFromYaml(const YAML::Node& root);

// loadSceneYaml + applyOverride for each override + modelFromYaml. Validation errors are
// prefixed with the file path.
Model loadScene(const std::string& path, const std::vector<std::string>& overrides = {});

// Every key path a scene may hold, list items written as "*" (e.g. "teeth.*.length"), in
// document order. docs/scene_reference.md has one row per path.
std::vector<std::string> sceneKeyPaths();

}  // namespace threshing_sim
