// The YAML reader of the scene loader: one mapping of a scene (a section, a list item) read
// key by key against the schema, each value checked against its key's range or words.
#pragma once

#include <string>
#include <vector>

#include "messages.h"
#include "schema.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace loader {

// An unquoted scalar that reads as a number (.nan and .inf included), as yaml-cpp reads it.
bool decodeNumber(const SceneNode& node, double* value);

// An unquoted scalar that reads as an int, as yaml-cpp reads it.
bool decodeInteger(const SceneNode& node, int* value);

// A mapping read key by key; construction refuses unknown, duplicate and non-string keys. An
// absent or null mapping reads as empty. The values are found once, at construction, by their
// place among the known keys. The tree must outlive the section.
class Section {
 public:
  // keys must outlive the section (the schema's children, an obstacle type's keys).
  Section(const SceneNode& node, std::string path, const Children& keys,
          const std::string& owner = "");

  std::string path(const std::string& key) const { return joinPath(path_, key); }
  bool has(const std::string& key) const;
  // The key's value; an undefined node when absent.
  const SceneNode& node(const std::string& key) const;

  // Refuses a missing required key.
  void require(const std::string& key) const;

  // A finite number in the key's schema range.
  double number(const std::string& key, double fallback) const;

  // An integer in the key's schema range.
  int integer(const std::string& key, int fallback) const;

  // [x, y] of two finite numbers, each in the key's schema range.
  Vec2 vec2(const std::string& key, const Vec2& fallback) const;

  // One of the key's schema words.
  std::string word(const std::string& key, const std::string& fallback,
                   const std::string& what) const;

  // A nested mapping; absent or null reads as empty (all defaults).
  Section section(const std::string& key, const std::string& pattern) const;
  Section section(const std::string& key, const Children& keys) const;

  // A list of mappings; absent or null reads as empty.
  std::vector<const SceneNode*> list(const std::string& key) const;

 private:
  // The place of key among the known keys, or -1.
  int indexOf(const std::string& key) const;
  // The schema entry of a key of this section ("teeth.3" + "length" -> "teeth.*.length").
  const KeySpec* specOf(const std::string& key) const;
  static const Bound& rangeOf(const KeySpec* spec);
  // The value of a key, or nullptr when absent (and its schema entry).
  const SceneNode* find(const std::string& key) const;
  const SceneNode* find(const std::string& key, const KeySpec** spec) const;

  std::string path_;
  const Children* keys_;                  // the keys a mapping may hold, with their schema entries
  std::vector<const SceneNode*> values_;  // by place in keys_->keys; nullptr when absent
};

}  // namespace loader
}  // namespace threshing_sim
