// The walk of one override down its key path (overrides.h: checkThenApply), written once for
// both trees: yaml-cpp's nodes (handles to shared nodes, changed in place) and SceneNode trees
// (values, walked by pointer). Only the nodes on the path are visited: the rest of the tree is
// neither copied nor read.
#include <algorithm>
#include <string>
#include <vector>

#include "messages.h"
#include "overrides.h"
#include "schema.h"

namespace threshing_sim {
namespace loader {
namespace {

bool isIndex(const std::string& s) {
  return !s.empty() && std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

std::string entries(size_t n) { return std::to_string(n) + (n == 1 ? " entry" : " entries"); }

// "a.b.0.c" -> {"a", "b", "0", "c"}; empty components are refused.
std::vector<std::string> splitKeyPath(const Assignment& a) {
  const std::string& key_path = a.keyPath();
  std::vector<std::string> parts;
  for (size_t start = 0;;) {
    const size_t dot = key_path.find('.', start);
    parts.push_back(key_path.substr(start, dot - start));
    if (parts.back().empty()) a.refuse(key_path, "empty key path component");
    if (dot == std::string::npos) return parts;
    start = dot + 1;
  }
}

// What the walk does to a tree. Cursor: where the walk is (a handle, or a pointer).
template <typename Tree>
struct Ops;

template <>
struct Ops<YAML::Node> {
  using Cursor = YAML::Node;
  static bool empty(const YAML::Node& n) { return !n.IsDefined() || n.IsNull(); }
  static Cursor start(YAML::Node* root) { return *root; }
  static void makeMap(YAML::Node* root) { root->reset(YAML::Node(YAML::NodeType::Map)); }
  static void moveTo(Cursor* c, const Cursor& to) { c->reset(to); }  // a handle, not the node
  static bool isSequence(const Cursor& c) { return c.IsSequence(); }
  static bool isMap(const Cursor& c) { return c.IsMap(); }
  static size_t size(const Cursor& c) { return c.size(); }
  static Cursor item(const Cursor& c, size_t i) { return c[i]; }  // a const lookup adds no key
  static void setItem(Cursor c, size_t i, const YAML::Node& v) { c[i] = v; }
  static Cursor child(const Cursor& c, const std::string& key) { return c[key]; }
  static bool absent(const Cursor& child) { return empty(child); }
  static void set(Cursor c, const std::string& key, const YAML::Node& v, YAML::Node*) {
    c[key] = v;
  }
  static Cursor addMap(Cursor c, const std::string& key) {
    c[key] = YAML::Node(YAML::NodeType::Map);
    return c[key];
  }
  static Cursor scratchMap(YAML::Node*) { return YAML::Node(YAML::NodeType::Map); }
  static YAML::Node copy(const YAML::Node& v) { return YAML::Clone(v); }
  static std::string shown(const Cursor& c) { return show(c); }
};

template <>
struct Ops<SceneNode> {
  using Cursor = SceneNode*;
  static bool empty(const SceneNode& n) { return !n.defined() || n.isNull(); }
  static Cursor start(SceneNode* root) { return root; }
  static void makeMap(SceneNode* root) { *root = SceneNode::map(); }
  static void moveTo(Cursor* c, Cursor to) { *c = to; }
  static bool isSequence(Cursor c) { return c->isSequence(); }
  static bool isMap(Cursor c) { return c->isMap(); }
  static size_t size(Cursor c) { return c->size(); }
  static Cursor item(Cursor c, size_t i) { return &c->items[i]; }
  static void setItem(Cursor c, size_t i, const SceneNode& v) { c->items[i] = v; }
  static Cursor child(Cursor c, const std::string& key) { return c->find(key); }
  static bool absent(Cursor child) { return child == nullptr || empty(*child); }
  static void set(Cursor c, const std::string& key, const SceneNode& v, SceneNode* movable) {
    SceneNode* found = c->find(key);
    if (found == nullptr) {
      c->items.push_back(SceneNode::scalar(key));
      found = &c->items.emplace_back();
    }
    if (movable != nullptr) {
      *found = std::move(*movable);
    } else {
      *found = v;
    }
  }
  static Cursor addMap(Cursor c, const std::string& key) {
    set(c, key, SceneNode::map(), nullptr);
    return c->find(key);
  }
  static Cursor scratchMap(SceneNode* scratch) {
    *scratch = SceneNode::map();
    return scratch;
  }
  static const SceneNode& copy(const SceneNode& v) { return v; }  // set() copies
  static std::string shown(Cursor c) { return show(*c); }
};

// The walk of one assignment down its key path: with apply false it only checks, leaving the
// tree alone; with apply true it sets the value.
template <typename Tree>
struct Walk {
  using O = Ops<Tree>;
  using Cursor = typename O::Cursor;

  Tree* root;
  const Assignment& a;
  const std::vector<std::string>& parts;
  bool apply;
  const Tree& value;
  Tree* movable;  // the value, to be moved when set in one place (SceneNode only)
  Tree scratch;   // an absent section while checking

  void run();
  void everyItem(const Cursor& list, size_t i, const std::string& parent);
  void intoSection(const KeySpec& spec, const std::string& path, size_t i, Cursor* node);
  void intoItem(size_t i, const std::string& parent, const std::string& path, Cursor* node);
};

// "*" in place of a list index at parts[i]: every item of the list, each its own assignment
// (and its own copy of the value when setting, as two items sharing one node change together).
template <typename Tree>
void Walk<Tree>::everyItem(const Cursor& list, size_t i, const std::string& parent) {
  const size_t n_items = O::size(list);
  if (n_items == 0) a.refuse(parent, "has no entries to set");
  std::string rest;
  for (size_t j = i + 1; j < parts.size(); ++j) rest = joinPath(rest, parts[j]);
  for (size_t index = 0; index < n_items; ++index) {
    const std::string item = joinPath(parent, std::to_string(index));
    const Assignment item_a = a.at(rest.empty() ? item : item + "." + rest);
    const std::vector<std::string> item_parts = splitKeyPath(item_a);
    const Tree item_value = !apply || index == 0 ? value : O::copy(value);
    Walk<Tree>{root, item_a, item_parts, apply, item_value, nullptr, Tree()}.run();
  }
}

// Descends from a mapping into its section parts[i] (at `path`, of schema kind spec.kind): a
// missing section is created (when checking only, a fresh empty mapping stands for it and the
// tree is left alone), other missing containers are refused.
template <typename Tree>
void Walk<Tree>::intoSection(const KeySpec& spec, const std::string& path, size_t i, Cursor* node) {
  const std::string& part = parts[i];
  const Cursor child = O::child(*node, part);
  const bool absent = O::absent(child);
  if (spec.kind == KeyKind::kValue) a.refuse(path, "is a value, not a section");
  if (absent && spec.kind == KeyKind::kList) {
    a.refuse(joinPath(path, parts[i + 1]), "index out of range (" + path + " has no entries)");
  }
  if (absent && spec.kind == KeyKind::kOptionalSection) {
    a.refuse(path,
             "is absent; set the whole " + part + " first (e.g. " + path + "={anchor: [x, y]})");
  }
  O::moveTo(node, !absent ? child : apply ? O::addMap(*node, part) : O::scratchMap(&scratch));
}

// One list index at parts[i]; moves *node to the item unless it is the last part (then the
// value is set there).
template <typename Tree>
void Walk<Tree>::intoItem(size_t i, const std::string& parent, const std::string& path,
                          Cursor* node) {
  const std::string& part = parts[i];
  if (!isIndex(part)) a.refuse(parent, "is a list; expected an index, got '" + part + "'");
  const size_t size = O::size(*node);
  const size_t index = part.size() < 10 ? std::stoul(part) : size;
  if (index >= size)
    a.refuse(path, "index out of range (" + parent + " has " + entries(size) + ")");
  if (i + 1 == parts.size()) {
    if (apply) O::setItem(*node, index, value);
  } else {
    O::moveTo(node, O::item(*node, index));
  }
}

template <typename Tree>
void Walk<Tree>::run() {
  const bool empty_root = O::empty(*root);
  if (empty_root && apply) O::makeMap(root);
  Cursor node = empty_root && !apply ? O::scratchMap(&scratch) : O::start(root);
  std::string path;     // as written, e.g. "teeth.0"
  std::string pattern;  // schema form, e.g. "teeth.*"
  for (size_t i = 0; i < parts.size(); ++i) {
    const std::string& part = parts[i];
    const std::string parent = path;
    path = joinPath(path, part);
    if (O::isSequence(node)) {
      if (part == "*") return everyItem(node, i, parent);
      intoItem(i, parent, path, &node);
      pattern += ".*";
      continue;
    }
    // A key of a mapping: it must be in the schema.
    if (!O::isMap(node)) a.refuse(parent, "is a value, not a section (got " + O::shown(node) + ")");
    const std::string key_pattern = joinPath(pattern, part);
    const KeySpec* spec = findKey(key_pattern);
    if (spec == nullptr) a.refuse(path, unknownKey(part, childKeys(pattern), ""));
    pattern = key_pattern;
    if (i + 1 == parts.size()) {
      if (apply) O::set(node, part, value, movable);
      continue;
    }
    intoSection(*spec, path, i, &node);
  }
}

template <typename Tree>
void checkThenApplyTo(Tree* root, const Assignment& a, const Tree& value, Tree* movable) {
  const std::vector<std::string> parts = splitKeyPath(a);
  Walk<Tree>{root, a, parts, false, value, nullptr, Tree()}.run();
  Walk<Tree>{root, a, parts, true, value, movable, Tree()}.run();
}

}  // namespace

void checkThenApply(YAML::Node* root, const Assignment& a, const YAML::Node& value) {
  checkThenApplyTo(root, a, value, static_cast<YAML::Node*>(nullptr));
}

void checkThenApply(SceneNode* root, const Assignment& a, const SceneNode& value,
                    SceneNode* movable) {
  checkThenApplyTo(root, a, value, movable);
}

}  // namespace loader
}  // namespace threshing_sim
