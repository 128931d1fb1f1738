// libFuzzer target: the scene loader plus a short run. The input is a scene file's text; a
// scene the loader accepts is simulated for min(duration, 1e-4) s. Refusals (SceneError) are
// expected; anything else (a crash, another exception, a sanitizer report, a hang) is a finding.
// The loader's own YAML reader (parseSceneText, scene_tree.h) must give yaml-cpp's tree for every
// text yaml-cpp reads, and take no text yaml-cpp refuses.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"
#include "threshing_sim/scene/scene_tree.h"

namespace {

// The same trees: kinds, tags, texts, order, and where each scalar starts.
bool sameTree(const threshing_sim::SceneNode& a, const threshing_sim::SceneNode& b) {
  if (a.kind != b.kind || a.tag != b.tag || a.text != b.text || a.items.size() != b.items.size())
    return false;
  if (a.isScalar() && (a.line != b.line || a.column != b.column)) return false;
  for (size_t i = 0; i < a.items.size(); ++i)
    if (!sameTree(a.items[i], b.items[i])) return false;
  return true;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace threshing_sim;
  const std::string text(reinterpret_cast<const char*>(data), size);
  Model model;
  try {
    YAML::Node root = YAML::Load(text);
    if (!sameTree(parseSceneText(text), sceneNodeFromYaml(root))) __builtin_trap();
    model = modelFromYaml(root);
    damageFromYaml(root);
  } catch (const SceneError&) {
    return 0;
  } catch (const YAML::Exception&) {
    bool read = true;  // not YAML (the loader reports it as a syntax error with its position)
    try {
      parseSceneText(text);
    } catch (const YAML::Exception&) {
      read = false;
    }
    if (read) __builtin_trap();  // the loader's reader took a text yaml-cpp refuses
    return 0;
  }
  Data d;
  resetData(model, &d);
  const double t_end_s = std::min(model.duration_s, 1e-4);
  for (int chunk = 1; chunk <= 10; ++chunk)
    if (advanceTo(model, &d, t_end_s * chunk / 10) == StepStatus::kFailed) break;
  return 0;
}
