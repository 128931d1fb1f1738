// The `--set` overrides (overrides.cc: assignments and files; override_walk.cc: the walk of
// one assignment down its key path, on yaml-cpp's trees and on SceneNode trees alike). The
// public functions are in scene_loader.h and scene_tree.h.
#pragma once

#include <yaml-cpp/yaml.h>

#include <optional>
#include <string>
#include <vector>

#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace loader {

// One override on its way into the tree: its key path and the text it is quoted by in
// messages, "key.path=value". The value of an override file's entry is written out as text
// only for a message (writing a 1000-kernel list out and parsing it back was most of the time
// a --set-file took).
class Assignment {
 public:
  // "key.path=value" as given, split and trimmed.
  Assignment(std::string text, std::string key_path, std::string value_text);
  // An override file's entry: the value as read (must outlive the assignment).
  Assignment(std::string key_path, const SceneNode* value);

  const std::string& keyPath() const { return key_path_; }
  const std::string& valueText() const;
  const std::string& text() const;
  // The same value at another key path (an item of a "*").
  Assignment at(std::string key_path) const;

  [[noreturn]] void refuse(const std::string& path, const std::string& what) const;

 private:
  mutable std::optional<std::string> text_;
  std::string key_path_;
  mutable std::optional<std::string> value_text_;
  const SceneNode* shown_ = nullptr;
};

// Checks the whole assignment first (every item of a "*" included), then applies it: a
// refused assignment leaves the tree as it was, and no copy of the tree is made. A SceneNode
// value given as movable is moved into the tree when it goes to one place (not a "*").
void checkThenApply(YAML::Node* root, const Assignment& a, const YAML::Node& value);
void checkThenApply(SceneNode* root, const Assignment& a, const SceneNode& value,
                    SceneNode* movable = nullptr);

// An override file read: its mapping of key paths to values.
struct OverrideFile {
  SceneNode root;
};

// An override file's mapping of key paths to values; refuses a file that is no mapping and a
// key that is not a key path (before any entry is applied).
OverrideFile readOverrideFile(const std::string& path);

// The entries of readOverrideFile in file order, each as applyOverride of "key.path=value"
// with the value written out (overridesFromFile) would apply it. The values are moved into
// the tree.
void applyOverrideEntries(SceneNode* root, OverrideFile file);

}  // namespace loader
}  // namespace threshing_sim
