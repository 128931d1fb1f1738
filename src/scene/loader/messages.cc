// The loader's messages (messages.h).
#include "messages.h"

#include <algorithm>
#include <cstdio>
#include <limits>

#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace loader {
namespace {

// Levenshtein distance, for "did you mean" suggestions.
size_t editDistance(const std::string& a, const std::string& b) {
  std::vector<size_t> row(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    size_t diagonal = row[0];
    row[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      const size_t above = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diagonal = above;
    }
  }
  return row[b.size()];
}

// The known key closest to key, when it is close enough to be a misspelling of it.
const std::string* closestKey(const std::string& key, const std::vector<std::string>& known) {
  const std::string* best = nullptr;
  size_t best_distance = std::numeric_limits<size_t>::max();
  for (const std::string& candidate : known) {
    const size_t d = editDistance(key, candidate);
    if (d < best_distance) {
      best_distance = d;
      best = &candidate;
    }
  }
  return best_distance <= std::max<size_t>(2, key.size() / 3) ? best : nullptr;
}

}  // namespace

// Joins a parent path and a key ("" is the top level).
std::string joinPath(const std::string& parent, const std::string& key) {
  return parent.empty() ? key : parent + "." + key;
}

[[noreturn]] void fail(const std::string& path, const std::string& what) {
  throw SceneError((path.empty() ? std::string("scene") : path) + ": " + what);
}

// A node as the user wrote it: flow-style YAML, quoted strings in quotes.
std::string show(const YAML::Node& node) {
  if (!node.IsDefined() || node.IsNull()) return "null";
  if (node.IsScalar() && node.Tag() == "!") return "\"" + node.Scalar() + "\"";
  YAML::Emitter out;
  out.SetSeqFormat(YAML::Flow);
  out.SetMapFormat(YAML::Flow);
  out << node;
  return out.c_str();
}

std::string show(const SceneNode& node) {
  if (!node.defined() || node.isNull()) return "null";
  if (node.isScalar() && node.tag == "!") return "\"" + node.text + "\"";
  return show(yamlFromSceneNode(node));
}

bool quotableKey(const std::string& key) {
  static const struct NameCharacters {
    bool name[256] = {};
    NameCharacters() {
      for (int c = 0; c < 256; ++c) {
        name[c] = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                  c == '_' || c == '.' || c == '*';
      }
    }
  } kName;
  if (key.empty() || key.size() > 40) return false;
  for (const char c : key)
    if (!kName.name[static_cast<unsigned char>(c)]) return false;
  return true;
}

std::string describe(const SceneNode& node) {
  const auto count = [](size_t n, const char* one, const char* many) {
    return std::to_string(n) + " " + (n == 1 ? one : many);
  };
  std::string what;
  if (node.isScalar()) what = "a scalar of " + count(node.text.size(), "character", "characters");
  if (node.isSequence()) what = "a list of " + count(node.size(), "item", "items");
  if (node.isMap()) what = "a mapping of " + count(node.size(), "entry", "entries");
  if (what.empty()) return "null";
  if (node.line < 0) return what;
  return what + " at line " + std::to_string(node.line + 1) + ", column " +
         std::to_string(node.column + 1);
}

std::string showOrDescribe(const SceneNode& node) {
  return node.isScalar() && quotableKey(node.text) ? show(node) : describe(node);
}

std::string syntaxError(const std::string& message) {
  const std::string escape = "unknown escape character";
  return message.compare(0, escape.size(), escape) == 0 ? escape : message;
}

std::string notAKeyName(const SceneNode& key, const std::vector<std::string>& known) {
  const std::string* best = key.isScalar() ? closestKey(key.text, known) : nullptr;
  return "expected a key name (letters, digits and _), found " + describe(key) +
         (best != nullptr ? " (did you mean '" + *best + "'?)" : "");
}

// A computed number or vector for a message.
std::string show(double value) {
  char text[32];
  std::snprintf(text, sizeof(text), "%.6g", value);
  return text;
}
std::string show(const Vec2& v) { return "[" + show(v.x()) + ", " + show(v.y()) + "]"; }

std::string joinWords(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : ", ") + w;
  return out;
}

// "unknown key (did you mean 'length'?)", or the list of known keys when nothing is close.
std::string unknownKey(const std::string& key, const std::vector<std::string>& known,
                       const std::string& owner) {
  const std::string what = "unknown key" + (owner.empty() ? "" : " for " + owner);
  const std::string* best = closestKey(key, known);
  if (best != nullptr) return what + " (did you mean '" + *best + "'?)";
  return what + " (known keys: " + joinWords(known) + ")";
}

}  // namespace loader
}  // namespace threshing_sim
