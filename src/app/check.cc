// --check and --check-batch: validation of scenes (with their overrides) without a run.
#include <algorithm>
#include <cctype>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "app.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace app {

// The cache's key: the scene path and the file paths, tab-separated.
YAML::Node sceneWithFiles(const Options& options, TreeCache* cache) {
  std::string key = options.scene_path;
  for (const std::string& path : options.set_files) key += "\t" + path;
  if (cache != nullptr && cache->count(key) != 0) return YAML::Clone(cache->at(key));
  YAML::Node root = loadSceneYaml(options.scene_path);
  for (const std::string& path : options.set_files) {
    for (const std::string& assignment : overridesFromFile(path)) applyOverride(&root, assignment);
  }
  if (cache != nullptr) (*cache)[key] = YAML::Clone(root);
  return root;
}

namespace {

// Base scene texts kept at most by --check-batch (the map is emptied when full).
constexpr size_t kMaxBaseTexts = 64;

// The tree as one line of flow-style YAML. Plain scalars made of safe characters are written
// as they are (yaml-cpp's emitter checks every scalar: a large part of a check's time); any
// other scalar goes through the emitter.
void writeFlow(const YAML::Node& node, std::string* out) {
  if (node.IsMap() || node.IsSequence()) {
    *out += node.IsMap() ? "{" : "[";
    bool first = true;
    for (const auto& item : node) {
      if (!first) *out += ", ";
      first = false;
      if (node.IsMap()) {
        writeFlow(item.first, out);
        *out += ": ";
        writeFlow(item.second, out);
      } else {
        writeFlow(item, out);
      }
    }
    *out += node.IsMap() ? "}" : "]";
    return;
  }
  const std::string& text = node.IsScalar() ? node.Scalar() : std::string();
  const bool plain = node.IsScalar() && node.Tag() != "!" && !text.empty() &&
                     std::all_of(text.begin(), text.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' ||
                              c == '+' || c == '-';
                     });
  if (plain) {
    *out += text;
    return;
  }
  YAML::Emitter emitter;
  emitter << YAML::Flow << node;
  std::string emitted = emitter.c_str();
  std::replace(emitted.begin(), emitted.end(), '\n', ' ');
  *out += emitted;
}

// Sets every contact restitution of the tree that is a number in [0, 1] to 1, for validation.
// Compiling matches a Hunt-Crossley factor to each restitution (tens of ms, a function of the
// restitution alone, whose only check is that range); with 1 it costs nothing, and every other
// check runs on the real values. Others are kept for the loader to refuse. In place: a copy of
// the tree costs as much as the rest of a check.
void skipRestitutionFit(YAML::Node* root) {
  // Looked up through const nodes: a non-const operator[] would add missing keys.
  const YAML::Node& tree = *root;
  const YAML::Node contact = tree.IsMap() ? tree["contact"] : YAML::Node();
  if (!contact.IsMap()) return;
  std::vector<std::string> laws;
  for (const auto& pair : contact) {
    const YAML::Node law = pair.second;
    const YAML::Node e = law.IsMap() ? law["restitution"] : YAML::Node();
    double value = 0;
    if (e.IsScalar() && e.Tag() != "!" && YAML::convert<double>::decode(e, value) && value >= 0.0 &&
        value <= 1.0) {
      laws.push_back(pair.first.Scalar());
    }
  }
  for (const std::string& law : laws) (*root)["contact"][law]["restitution"] = 1.0;
}

}  // namespace

std::string resolvedScene(const Options& options, TreeCache* cache, BaseTexts* bases,
                          const std::string** base, ToothCache* teeth, bool compile) {
  YAML::Node root = sceneWithFiles(options, cache);
  if (bases != nullptr && base != nullptr) {
    std::string key = options.scene_path;
    for (const std::string& path : options.set_files) key += "\t" + path;
    auto found = bases->find(key);
    if (found == bases->end()) {
      if (bases->size() >= kMaxBaseTexts) bases->clear();
      std::string text;
      writeFlow(root, &text);
      found = bases->emplace(key, std::move(text)).first;
    }
    *base = &found->second;
  }
  for (const std::string& assignment : options.overrides) applyOverride(&root, assignment);
  std::string text;
  writeFlow(root, &text);  // before the restitutions are set aside
  if (!compile) return text;
  skipRestitutionFit(&root);
  try {
    FeedSpec feed;  // a feed is validated like the rest
    modelFromYaml(root, teeth, &feed);
    damageFromYaml(root);
  } catch (const SceneError& e) {
    throw SceneError(options.scene_path + ": " + e.what());
  }
  return text;
}

// Each line of the file: the arguments of one run (scene, --set, --set-file, ...) separated by
// tabs. Each answer "ok" carries the resolved scene and the base scene (the scene with its
// override files, before the --set overrides), both one line of flow YAML without tabs.
int checkBatch(const std::string& path, bool resolve_only) {
  std::ifstream file;
  if (path != "-") {
    file.open(path);
    if (!file) throw OptionError("cannot open --check-batch file '" + path + "'");
  }
  std::istream& in = path == "-" ? std::cin : file;
  int status = 0;
  TreeCache cache;
  BaseTexts bases;
  ToothCache teeth;  // the combinations share few teeth
  for (std::string line; std::getline(in, line);) {
    std::vector<std::string> args = {"simulate"};
    for (size_t start = 0, tab = 0; tab != std::string::npos; start = tab + 1) {
      tab = line.find('\t', start);
      args.push_back(line.substr(start, tab == std::string::npos ? tab : tab - start));
    }
    std::vector<char*> argv;
    for (std::string& arg : args) argv.push_back(arg.data());
    try {
      const std::string* base = nullptr;
      const std::string scene =
          resolvedScene(parseOptions(static_cast<int>(argv.size()), argv.data()), &cache, &bases,
                        &base, &teeth, !resolve_only);
      std::cout << "ok\t" << scene << "\t" << *base << "\n";
    } catch (const std::exception& e) {
      std::string message = e.what();
      std::replace(message.begin(), message.end(), '\n', ' ');
      std::cout << "error\t" << message << "\n";
      status = 2;
    }
  }
  return status;
}

}  // namespace app
}  // namespace threshing_sim
