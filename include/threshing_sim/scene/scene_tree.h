// A scene's YAML as the loader reads it: a plain tree of values (no yaml-cpp nodes), read from a
// file by the loader's own reader for the YAML that scenes are written in (block and flow
// mappings and lists, plain and quoted scalars, comments) and by yaml-cpp for the rest, with
// the same tree either way. A 1000-kernel scene reads, validates and compiles in 7e7
// instructions this way against 9.7e8 through yaml-cpp's nodes (docs/scene_loading.md).
//
// simulate reads, overrides, validates and prints scenes as SceneNode trees; the YAML::Node
// functions of scene_loader.h remain for the node, the tests and the fuzzers.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/core/tooth_cache.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {

// One node of a scene tree, a value: copying a node copies its subtree.
struct SceneNode {
  enum class Kind : unsigned char { kUndefined, kNull, kScalar, kSequence, kMap };

  Kind kind = Kind::kUndefined;
  std::string tag;               // yaml-cpp's: "?" plain, "!" quoted, else an explicit tag
  std::string text;              // a scalar's text
  std::vector<SceneNode> items;  // a sequence's items; a mapping's keys and values in turn
  int line = 0;                  // where the node starts in its file (0-based, as yaml-cpp's Mark)
  int column = 0;

  bool defined() const { return kind != Kind::kUndefined; }
  bool isNull() const { return kind == Kind::kNull; }
  bool isScalar() const { return kind == Kind::kScalar; }
  bool isSequence() const { return kind == Kind::kSequence; }
  bool isMap() const { return kind == Kind::kMap; }
  // A scalar written without quotes (a number can only be such a scalar).
  bool isPlainScalar() const {
    return kind == Kind::kScalar && !(tag.size() == 1 && tag[0] == '!');
  }
  // Items of a sequence, entries of a mapping.
  size_t size() const { return kind == Kind::kMap ? items.size() / 2 : items.size(); }
  // The value of the first entry whose key is a scalar with this text, or nullptr.
  const SceneNode* find(const std::string& key) const;
  SceneNode* find(const std::string& key);

  static SceneNode map();
  static SceneNode scalar(std::string text, std::string tag = "?");
};

// The scene file's tree; refusals as loadSceneYaml's (a directory, a file that cannot be read,
// a YAML syntax error with its line and column). Throws SceneError.
SceneNode readSceneFile(const std::string& path);

// YAML text's tree as YAML::Load reads it; throws YAML::ParserException as it does.
SceneNode parseSceneText(const std::string& text);

// Conversions from and to yaml-cpp's nodes (the same scalars, tags, order and marks).
SceneNode sceneNodeFromYaml(const YAML::Node& node);
YAML::Node yamlFromSceneNode(const SceneNode& node);

// applyOverride, modelFromYaml and damageFromYaml on a SceneNode tree, with the same refusals.
void applyOverride(SceneNode* root, const std::string& assignment);

// Applies an override file's entries in file order, as applyOverride of each assignment of
// overridesFromFile would, without writing the values out as text and parsing them back (a
// quoted scalar in a list or mapping reads as that round trip read it: plain when the YAML
// emitter writes it without quotes). The file must be a mapping whose keys are key paths (at
// most 40 letters, digits, '_', '.' and '*'), checked before the first entry is applied; a
// file that is not (/etc/shadow) is refused by its name and what was found where, quoting
// none of it. Throws SceneError.
void applyOverrideFile(SceneNode* root, const std::string& path);
Model modelFromTree(const SceneNode& root, ToothCache* tooth_cache = nullptr,
                    FeedSpec* feed = nullptr);
DamageThresholds damageFromTree(const SceneNode& root);

// The tree as one line of flow-style YAML: plain scalars of letters, digits and "_.+-" as they
// are, every other scalar as yaml-cpp's emitter writes it (simulate --check's resolved scene).
void writeFlow(const SceneNode& node, std::string* out);

}  // namespace threshing_sim
