// The `--set` overrides: "key.path=value" assignments and override files applied to a scene's
// tree, each key checked against the schema (scene_loader.h: applyOverride,
// overridesFromFile, applyOverrideFile).
#include "overrides.h"

#include <algorithm>
#include <optional>
#include <type_traits>
#include <utility>

#include "messages.h"
#include "schema.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace loader {
namespace {

std::string trim(const std::string& s) {
  const size_t first = s.find_first_not_of(" \t");
  if (first == std::string::npos) return "";
  return s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

}  // namespace

Assignment::Assignment(std::string text, std::string key_path, std::string value_text)
    : text_(std::move(text)), key_path_(std::move(key_path)), value_text_(std::move(value_text)) {}

Assignment::Assignment(std::string key_path, const SceneNode* value)
    : key_path_(std::move(key_path)), shown_(value) {}

const std::string& Assignment::valueText() const {
  if (!value_text_) value_text_ = show(*shown_);
  return *value_text_;
}

const std::string& Assignment::text() const {
  if (!text_) text_ = key_path_ + "=" + valueText();
  return *text_;
}

Assignment Assignment::at(std::string key_path) const {
  Assignment item = *this;
  item.key_path_ = std::move(key_path);
  item.text_.reset();
  return item;
}

void Assignment::refuse(const std::string& path, const std::string& what) const {
  throw SceneError((path.empty() ? "" : path + ": ") + what + " in override '" + text() + "'");
}

namespace {

// The key path and the value's text of an assignment "key.path=value"; refuses a missing '='
// or an empty side.
Assignment splitAssignment(const std::string& assignment) {
  const auto refuse = [&](const std::string& path, const std::string& what) {
    Assignment(assignment, "", "").refuse(path, what);
  };
  const size_t equals = assignment.find('=');
  if (equals == std::string::npos) refuse("", "expected key.path=value");
  std::string key_path = trim(assignment.substr(0, equals));
  std::string value_text = trim(assignment.substr(equals + 1));
  if (key_path.empty()) refuse("", "empty key path");
  if (value_text.empty()) refuse(key_path, "empty value");
  return Assignment(assignment, std::move(key_path), std::move(value_text));
}

// Whether YAML reads the text as a plain scalar of that very text: a number-like word (a
// digit first, or a sign or point and then a digit; letters, digits and "_.+-" after). No such
// text is a null ("~", "null"), a document marker ("---", "...") or a list item ("- ").
bool plainNumberLike(const std::string& text) {
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  const bool starts =
      !text.empty() && (digit(text[0]) || (text.size() > 1 && digit(text[1]) &&
                                           (text[0] == '-' || text[0] == '+' || text[0] == '.')));
  return starts && std::all_of(text.begin(), text.end(), [&](char c) {
           return digit(c) || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || c == '_' ||
                  c == '.' || c == '+' || c == '-';
         });
}

// The value of an assignment (YAML, so lists and mappings work); refuses one that is not YAML.
// A number-like word becomes the plain scalar YAML::Load would give (tag "?"), without the
// parser (a tenth of a scene check went to parsing the --set numbers).
template <typename Tree>
Tree parseValue(const Assignment& a) {
  const std::string& value_text = a.valueText();
  try {
    if constexpr (std::is_same_v<Tree, SceneNode>) {
      return plainNumberLike(value_text) ? SceneNode::scalar(value_text)
                                         : parseSceneText(value_text);
    } else {
      if (!plainNumberLike(value_text)) return YAML::Load(value_text);
      YAML::Node scalar(value_text);
      scalar.SetTag("?");
      return scalar;
    }
  } catch (const YAML::ParserException& e) {
    a.refuse(a.keyPath(), "value is not valid YAML (" + e.msg + ")");
  }
}

template <typename Tree>
void applyAssignment(Tree* root, const std::string& assignment) {
  const Assignment a = splitAssignment(assignment);
  checkThenApply(root, a, parseValue<Tree>(a));
}

// Whether yaml-cpp's emitter writes the text quoted (then reading it back gives tag "!"),
// inside a flow list or mapping (nested) or alone. Letters, digits and "_.+-" are written
// plain but for the null words and a lone "-"; other texts are asked of the emitter.
bool emittedQuoted(const std::string& text, bool nested) {
  static const struct Safe {
    bool safe[256] = {};
    Safe() {
      for (int c = 0; c < 256; ++c) {
        safe[c] = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                  c == '_' || c == '.' || c == '+' || c == '-';
      }
    }
  } kSafe;
  bool safe = !text.empty();
  for (const char c : text) safe = safe && kSafe.safe[static_cast<unsigned char>(c)];
  if (safe) {
    return (text.size() == 1 && text[0] == '-') ||
           (text.size() == 4 && (text == "null" || text == "Null" || text == "NULL"));
  }
  YAML::Emitter out;
  if (nested) {
    out << YAML::Flow << YAML::BeginSeq << text << YAML::EndSeq;
  } else {
    out << text;
  }
  const char first = out.c_str()[nested ? 1 : 0];
  return first == '"' || first == '\'';
}

bool isTag(const std::string& tag, char c) { return tag.size() == 1 && tag[0] == c; }

// The tag ('?' plain, '!' quoted) a scalar has after the round trip through text
// (overridesFromFile's "key=value" read back by applyOverride), or 0 when it keeps its own (an
// explicit tag): a nested scalar is quoted exactly when the emitter quotes it; a whole value
// keeps its quotes (show writes them), and gains them when the emitter quotes it.
char readBackTag(const SceneNode& scalar, bool nested) {
  const bool quoted = isTag(scalar.tag, '!');
  if (!quoted && !isTag(scalar.tag, '?')) return 0;
  if (!nested && quoted) return '!';
  return emittedQuoted(scalar.text, nested) ? '!' : '?';
}

// Whether the round trip changes a tag in the value (mapping keys aside: only their text
// counts).
bool readBackChanges(const SceneNode& node, bool nested) {
  if (node.isScalar()) {
    const char tag = readBackTag(node, nested);
    return tag != 0 && !isTag(node.tag, tag);
  }
  const size_t step = node.isMap() ? 2 : 1;
  for (size_t i = node.isMap() ? 1 : 0; i < node.items.size(); i += step)
    if (readBackChanges(node.items[i], true)) return true;
  return false;
}

void readBack(SceneNode* node, bool nested) {
  if (node->isScalar()) {
    const char tag = readBackTag(*node, nested);
    if (tag != 0) node->tag.assign(1, tag);
  }
  const size_t step = node->isMap() ? 2 : 1;
  for (size_t i = node->isMap() ? 1 : 0; i < node->items.size(); i += step)
    readBack(&node->items[i], true);
}

// An override file's value as it was when each entry went through its text (the value
// written in flow style and read back); a copy only when that changes a tag.
const SceneNode& asReadBack(const SceneNode& value, SceneNode* copy) {
  if (!readBackChanges(value, false)) return value;
  *copy = value;
  readBack(copy, false);
  return *copy;
}

}  // namespace

OverrideFile readOverrideFile(const std::string& path) {
  OverrideFile file;
  file.root = readSceneFile(path);
  const SceneNode& root = file.root;
  if (!root.isMap()) {
    throw SceneError(path + ": expected a mapping of key paths to values (got " +
                     showOrDescribe(root) + ")");
  }
  for (size_t i = 0; i < root.items.size(); i += 2) {
    const SceneNode& key = root.items[i];
    if (!key.isScalar() || !quotableKey(trim(key.text))) {
      throw SceneError(path + ": expected a key path (letters, digits, _, . and *), found " +
                       describe(key));
    }
  }
  return file;
}

void applyOverrideEntries(SceneNode* root, OverrideFile file) {
  std::vector<SceneNode>& items = file.root.items;
  for (size_t i = 0; i + 1 < items.size(); i += 2) {
    SceneNode& value = items[i + 1];
    SceneNode copy;
    const SceneNode& read_back = asReadBack(value, &copy);
    checkThenApply(root, Assignment(trim(items[i].text), &value), read_back,
                   &read_back == &copy ? &copy : &value);
  }
}

}  // namespace loader

void applyOverride(YAML::Node* root, const std::string& assignment) {
  loader::applyAssignment(root, assignment);
}

void applyOverride(SceneNode* root, const std::string& assignment) {
  loader::applyAssignment(root, assignment);
}

std::vector<std::string> overridesFromFile(const std::string& path) {
  const SceneNode file = loader::readOverrideFile(path).root;
  std::vector<std::string> assignments;
  for (size_t i = 0; i + 1 < file.items.size(); i += 2)
    assignments.push_back(file.items[i].text + "=" + loader::show(file.items[i + 1]));
  return assignments;
}

void applyOverrideFile(SceneNode* root, const std::string& path) {
  loader::applyOverrideEntries(root, loader::readOverrideFile(path));
}

}  // namespace threshing_sim
