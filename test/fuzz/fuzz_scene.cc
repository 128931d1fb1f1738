// libFuzzer target: the scene loader plus a short run. The input is a scene file's text; a
// scene the loader accepts is simulated for min(duration, 1e-4) s. Refusals (SceneError) are
// expected; anything else (a crash, another exception, a sanitizer report, a hang) is a finding.
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace threshing_sim;
  const std::string text(reinterpret_cast<const char*>(data), size);
  Model model;
  try {
    YAML::Node root = YAML::Load(text);
    model = modelFromYaml(root);
    damageFromYaml(root);
  } catch (const SceneError&) {
    return 0;
  } catch (const YAML::Exception&) {
    return 0;  // not YAML (the loader reports it as a syntax error with its position)
  }
  Data d;
  resetData(model, &d);
  const double t_end_s = std::min(model.duration_s, 1e-4);
  for (int chunk = 1; chunk <= 10; ++chunk)
    if (advanceTo(model, &d, t_end_s * chunk / 10) == StepStatus::kFailed) break;
  return 0;
}
