// The loader's own YAML reader (yaml_reader.cc) and the trees' conversions (tree.cc).
#pragma once

#include <string>

#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace loader {

// The text's tree when the reader takes the whole text (the YAML scenes are written in), with
// the tree yaml-cpp's parser gives; false when yaml-cpp must read it (other YAML, or an
// error), *out then unspecified.
bool readYamlSubset(const std::string& text, SceneNode* out);

// Refuses a file text holding a control character (no YAML text: a binary file), naming the
// file and where, quoting none of it. Throws SceneError.
void refuseBinary(const std::string& path, const std::string& text);

}  // namespace loader
}  // namespace threshing_sim
