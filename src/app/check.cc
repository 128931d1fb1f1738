// --check and --check-batch: validation of scenes (with their overrides) without a run.
#include <algorithm>
#include <cctype>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "app.h"
#include "threshing_sim/scene/scene_loader.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace app {

// The cache's key: the scene path and the file paths, tab-separated.
SceneNode sceneWithFiles(const Options& options, TreeCache* cache) {
  std::string key = options.scene_path;
  for (const std::string& path : options.set_files) key += "\t" + path;
  if (cache != nullptr && cache->count(key) != 0) return cache->at(key);
  SceneNode root = readSceneFile(options.scene_path);
  for (const std::string& path : options.set_files) applyOverrideFile(&root, path);
  if (cache != nullptr) (*cache)[key] = root;
  return root;
}

namespace {

// Base scene texts kept at most by --check-batch (the map is emptied when full).
constexpr size_t kMaxBaseTexts = 64;

// Sets every contact restitution of the tree that is a number in [0, 1] to 1, for validation.
// Compiling matches a Hunt-Crossley factor to each restitution (tens of ms, a function of the
// restitution alone, whose only check is that range); with 1 it costs nothing, and every other
// check runs on the real values. Others are kept for the loader to refuse. In place: a copy of
// the tree costs as much as the rest of a check.
void skipRestitutionFit(SceneNode* root) {
  SceneNode* contact = root->find("contact");
  if (contact == nullptr || !contact->isMap()) return;
  for (size_t i = 1; i < contact->items.size(); i += 2) {
    SceneNode* e = contact->items[i].find("restitution");
    double value = 0;
    if (e != nullptr && e->isPlainScalar() &&
        YAML::convert<double>::decode(YAML::Node(e->text), value) && value >= 0.0 && value <= 1.0) {
      *e = SceneNode::scalar("1");
    }
  }
}

}  // namespace

std::string resolvedScene(const Options& options, TreeCache* cache, BaseTexts* bases,
                          const std::string** base, ToothCache* teeth, bool compile) {
  SceneNode root = sceneWithFiles(options, cache);
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
    modelFromTree(root, teeth, &feed);
    damageFromTree(root);
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
