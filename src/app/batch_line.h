// --batch's run lines (batch.cc): a line read into a BatchLine (batch_line.cc), its options,
// and its compiled model through a cache of scene trees.
#pragma once

#include <string>
#include <unordered_set>
#include <vector>

#include "app.h"
#include "json.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/tooth_cache.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {
namespace app {

// Scene trees kept at most (the cache is emptied when full: a sweep's runs come in order).
inline constexpr size_t kMaxCachedTrees = 64;

// Hashes of the inline scenes seen, kept at most (then forgotten).
inline constexpr size_t kMaxSeenScenes = 4096;

// Parsed scene trees (with their override files applied), the inline scenes seen once, and
// the compiled teeth (the runs of a sweep share few teeth).
struct SceneCache {
  TreeCache trees;
  std::unordered_set<size_t> seen;
  ToothCache teeth;
};

// The scene path shown in messages for a line whose scene is "scene_yaml".
inline const char kInlineScene[] = "(scene_yaml)";

// The outputs a run can write, with the option that names their file.
struct OutputKind {
  const char* name;
  std::string Options::*path;
};
inline const OutputKind kOutputs[] = {
    {"summary", &Options::summary_path}, {"outcomes", &Options::outcomes_path},
    {"events", &Options::events_path},   {"forces", &Options::forces_path},
    {"trace", &Options::trace_path},
};
inline constexpr size_t kNumOutputs = sizeof(kOutputs) / sizeof(kOutputs[0]);

// A line of the batch, read.
struct BatchLine {
  std::string id;
  std::vector<std::string> args;
  bool inline_scene = false;
  std::string scene_yaml;
  std::string scene_name = kInlineScene;  // the scene_yaml's name in messages
  bool returned[kNumOutputs] = {true, true, false, false, false};
};

// A list of strings (a line's "args", "return", "run"); throws OptionError naming the key.
std::vector<std::string> stringList(const JsonValue& value, const char* key);

// An input line as a JSON object; throws OptionError.
JsonValue parseLine(const std::string& text);

// One run line into *line (its id first, for the error line); throws OptionError naming the
// bad key or value.
void readLine(const JsonValue& object, BatchLine* line);

// The line's options: simulate's command line, with the scene placeholder for "scene_yaml".
Options lineOptions(const BatchLine& line);

// The compiled model of the line (as loadScene builds it) and its damage thresholds.
Model lineModel(const BatchLine& line, const Options& options, SceneCache* cache,
                DamageThresholds* damage);

}  // namespace app
}  // namespace threshing_sim
