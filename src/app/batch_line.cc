// --batch's run lines (batch_line.h): reading a line, its options and its model.
#include "batch_line.h"

#include <algorithm>
#include <functional>
#include <iterator>

#include "threshing_sim/scene/scene_loader.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace app {

// ---------------------------------------------------------------------------------------------
// The lines in.

using Kind = JsonValue::Kind;

std::vector<std::string> stringList(const JsonValue& value, const char* key) {
  if (value.kind != Kind::kArray)
    throw OptionError(std::string(key) + ": expected a list of strings (got " + showJson(value) +
                      ")");
  std::vector<std::string> items;
  for (const JsonValue& item : value.items) {
    if (item.kind != Kind::kString)
      throw OptionError(std::string(key) + ": expected a string (got " + showJson(item) + ")");
    items.push_back(item.text);
  }
  return items;
}

namespace {

// "return": output names among kOutputs.
void readReturned(const JsonValue& value, BatchLine* line) {
  std::fill(std::begin(line->returned), std::end(line->returned), false);
  for (const std::string& name : stringList(value, "return")) {
    size_t k = 0;
    while (k < kNumOutputs && name != kOutputs[k].name) ++k;
    if (k == kNumOutputs)
      throw OptionError("return: unknown output '" + name +
                        "' (expected summary, outcomes, events, forces or trace)");
    line->returned[k] = true;
  }
}

// A line's id: a string or a number.
void readId(const JsonValue& object, BatchLine* line) {
  for (const auto& [key, value] : object.members) {
    if (key != "id") continue;
    if (value.kind != Kind::kString && value.kind != Kind::kNumber)
      throw OptionError("id: expected a string or number (got " + showJson(value) + ")");
    line->id = value.text;
  }
}

}  // namespace

JsonValue parseLine(const std::string& text) {
  JsonValue object;
  try {
    object = parseJson(text);
  } catch (const JsonError& e) {
    throw OptionError(std::string("not a JSON line (") + e.what() + ")");
  }
  if (object.kind != Kind::kObject)
    throw OptionError("expected a JSON object (got " + showJson(object) + ")");
  return object;
}

void readLine(const JsonValue& object, BatchLine* line) {
  readId(object, line);
  for (const auto& [key, value] : object.members) {
    if (key == "args") {
      line->args = stringList(value, "args");
    } else if (key == "scene_yaml") {
      if (value.kind != Kind::kString)
        throw OptionError("scene_yaml: expected the scene's text (got " + showJson(value) + ")");
      line->inline_scene = true;
      line->scene_yaml = value.text;
    } else if (key == "scene_name") {
      if (value.kind != Kind::kString || value.text.empty())
        throw OptionError("scene_name: expected a name (got " + showJson(value) + ")");
      line->scene_name = value.text;
    } else if (key == "return") {
      readReturned(value, line);
    } else if (key != "id") {
      throw OptionError("unknown key '" + key +
                        "' (expected id, args, scene_yaml, scene_name, return)");
    }
  }
}

// ---------------------------------------------------------------------------------------------
// One run.

Options lineOptions(const BatchLine& line) {
  std::vector<std::string> args = {"simulate"};
  if (line.inline_scene) args.push_back(line.scene_name);
  args.insert(args.end(), line.args.begin(), line.args.end());
  std::vector<char*> argv;
  for (std::string& arg : args) argv.push_back(arg.data());
  Options options = parseOptions(static_cast<int>(argv.size()), argv.data());
  if (options.modes || options.check || options.help || options.print_schema ||
      !options.check_batch_path.empty() || !options.batch_path.empty()) {
    throw UsageError(
        "--modes, --check, --check-batch, --batch, --help and --print-schema are not runs "
        "(not allowed in a --batch line)");
  }
  options.quiet = true;  // stdout holds the result lines
  return options;
}

namespace {

// The scene's text parsed as loadSceneYaml parses a file.
SceneNode sceneOfText(const std::string& text, const std::string& name) {
  try {
    return parseSceneText(text);
  } catch (const YAML::ParserException& e) {
    throw SceneError(name + ":" + std::to_string(e.mark.line + 1) + ":" +
                     std::to_string(e.mark.column + 1) + ": YAML syntax error: " + e.msg);
  }
}

// The line's scene tree with its override files applied (parsed once per scene and files).
// A scene text is kept from its second line on (a copy for the cache costs a tenth of a short
// run, wasted on a resolved scene that no other line carries), or from its first when the line
// has --set values: then it is a base scene, which the runner sends for many runs.
SceneNode baseTree(const BatchLine& line, const Options& options, SceneCache* cache) {
  if (cache->trees.size() >= kMaxCachedTrees) cache->trees.clear();
  if (cache->seen.size() >= kMaxSeenScenes) cache->seen.clear();
  if (!line.inline_scene) return sceneWithFiles(options, &cache->trees);
  std::string key = std::string(1, '\1') + line.scene_yaml;
  for (const std::string& path : options.set_files) key += "\t" + path;
  const auto found = cache->trees.find(key);
  if (found != cache->trees.end()) return found->second;
  SceneNode root = sceneOfText(line.scene_yaml, line.scene_name);
  if (root.isMap()) {
    for (const std::string& path : options.set_files) applyOverrideFile(&root, path);
  }
  // A line with --set values names a base scene that other lines share (the runner's lines).
  if (!options.overrides.empty() || !cache->seen.insert(std::hash<std::string>()(key)).second)
    cache->trees[key] = root;
  return root;
}

}  // namespace

// The compiled model of the line (as loadScene builds it) and its damage thresholds.
Model lineModel(const BatchLine& line, const Options& options, SceneCache* cache,
                DamageThresholds* damage) {
  SceneNode root = baseTree(line, options, cache);
  if (!root.isMap())
    throw SceneError(options.scene_path + ": expected a mapping of sections at the top level");
  for (const std::string& assignment : options.overrides) applyOverride(&root, assignment);
  try {
    Model model = modelFromTree(root, &cache->teeth);
    *damage = damageFromTree(root);
    return model;
  } catch (const SceneError& e) {
    throw SceneError(options.scene_path + ": " + e.what());
  }
}

}  // namespace app
}  // namespace threshing_sim
