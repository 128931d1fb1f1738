// Lookups in the scene schema (schema_table.cc) and the reference text made from it.
#include "schema.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>

#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace loader {

// A number for the reference: the fewest significant digits that read back as the same double,
// written plainly from 1e-3 to 1e6 (200, 0.0013) and with a short exponent outside (5e-4, 3e9).
std::string num(double value) {
  char text[40];
  int digits = 1;
  for (; digits < 17; ++digits) {
    std::snprintf(text, sizeof(text), "%.*g", digits, value);
    if (std::strtod(text, nullptr) == value) break;
  }
  const double magnitude = std::abs(value);
  if (value == 0 || (magnitude >= 1e-3 && magnitude < 1e6)) {
    const int decimals =
        value == 0 ? 0
                   : std::max(0, digits - 1 - static_cast<int>(std::floor(std::log10(magnitude))));
    std::snprintf(text, sizeof(text), "%.*f", decimals, value);
    return text;
  }
  std::snprintf(text, sizeof(text), "%.*e", digits - 1, value);
  std::string out = text;  // 3e+09 -> 3e9, 1e-06 -> 1e-6
  const size_t e = out.find('e');
  std::string exponent = out.substr(e + 1);
  const bool negative = exponent[0] == '-';
  exponent.erase(0, exponent.find_first_not_of("+-0"));
  return out.substr(0, e) + "e" + (negative ? "-" : "") + exponent;
}
std::string pair(const Vec2& v) { return "[" + num(v.x()) + ", " + num(v.y()) + "]"; }

std::string Bound::text() const {
  if (std::isinf(hi)) return (lo_open ? "> " : ">= ") + num(lo);
  return std::string("in ") + (lo_open ? "(" : "[") + num(lo) + ", " + num(hi) +
         (hi_open ? ")" : "]");
}

// The schema entry for a pattern such as "teeth.*.length", or nullptr.
const KeySpec* findKey(const std::string& pattern) {
  // By path, made once (the first entry of a path, as the scan of the schema found it).
  static const std::map<std::string, const KeySpec*> table = [] {
    std::map<std::string, const KeySpec*> t;
    for (const KeySpec& spec : schema()) t.emplace(spec.path, &spec);
    return t;
  }();
  const auto found = table.find(pattern);
  return found != table.end() ? found->second : nullptr;
}

// The key names directly below "" and below every schema path and its prefixes, in schema
// order, made once in one pass over the schema (every section of every scene asks for its
// keys).
const std::map<std::string, std::vector<std::string>>& childKeyTable() {
  static const std::map<std::string, std::vector<std::string>> table = [] {
    std::map<std::string, std::vector<std::string>> t;
    t[""];
    for (const KeySpec& spec : schema()) {
      const std::string path = spec.path;
      for (size_t dot = path.find('.'); dot != std::string::npos; dot = path.find('.', dot + 1))
        t[path.substr(0, dot)];
      t[path];
      const size_t last = path.rfind('.');
      t[last == std::string::npos ? "" : path.substr(0, last)].push_back(
          last == std::string::npos ? path : path.substr(last + 1));
    }
    return t;
  }();
  return table;
}

// The key names directly below a pattern ("" is the top level), in schema order. A pattern
// missing from the table is no prefix of a schema path, so it has no keys below it.
const std::vector<std::string>& childKeys(const std::string& pattern) {
  static const std::vector<std::string> kNone;
  const auto& table = childKeyTable();
  const auto found = table.find(pattern);
  return found != table.end() ? found->second : kNone;
}

Children childrenOf(const std::string& pattern, const std::vector<std::string>& keys) {
  Children c{pattern, keys, {}};
  for (const std::string& key : keys)
    c.specs.push_back(findKey(pattern.empty() ? key : pattern + "." + key));
  return c;
}

const Children& children(const std::string& pattern) {
  static const std::map<std::string, Children> table = [] {
    std::map<std::string, Children> t;
    for (const auto& entry : childKeyTable())
      t[entry.first] = childrenOf(entry.first, entry.second);
    return t;
  }();
  static const Children kNone;
  const auto found = table.find(pattern);
  return found != table.end() ? found->second : kNone;
}

// The schema pattern of a written path: list indices become "*" ("teeth.3.length" ->
// "teeth.*.length").
std::string patternOf(const std::string& path) {
  std::string out, part;
  for (size_t i = 0; i <= path.size(); ++i) {
    if (i < path.size() && path[i] != '.') {
      part += path[i];
      continue;
    }
    const bool index = !part.empty() && part.find_first_not_of("0123456789") == std::string::npos;
    out += (out.empty() ? "" : ".") + (index ? std::string("*") : part);
    part.clear();
  }
  return out;
}

// "a, b, c" -> {a, b, c} (a schema entry's words).
std::vector<std::string> splitWords(const std::string& text) {
  std::vector<std::string> words;
  for (size_t start = 0; start <= text.size();) {
    const size_t comma = std::min(text.find(", ", start), text.size());
    words.push_back(text.substr(start, comma - start));
    start = comma + 2;
  }
  return words;
}

}  // namespace loader

using loader::KeySpec;
using loader::schema;

std::string sceneSchemaTable() {
  const loader::SchemaDefaults defaults;
  std::string out =
      "| key path | type | unit | default | range | meaning |\n"
      "|---|---|---|---|---|---|\n";
  for (const KeySpec& spec : schema()) {
    const bool ranged = !std::isinf(spec.range.lo) || !std::isinf(spec.range.hi);
    const std::string dflt = spec.default_text ? spec.default_text(defaults) : "";
    std::string range = ranged ? spec.range.text() : "";
    if (spec.words != nullptr) {
      for (const std::string& w : loader::splitWords(spec.words))
        range += (range.empty() ? "`" : ", `") + w + "`";
    }
    out += std::string("| `") + spec.path + "` | " + spec.type + " | " + spec.unit + " | " + dflt +
           " | " + range + " | " + spec.doc + " |\n";
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> sceneSchemaDefaults() {
  const loader::SchemaDefaults defaults;
  std::vector<std::pair<std::string, std::string>> out;
  for (const KeySpec& spec : schema())
    out.emplace_back(spec.path, spec.default_text ? spec.default_text(defaults) : "");
  return out;
}

std::vector<std::string> sceneKeyPaths() {
  std::vector<std::string> paths;
  for (const KeySpec& spec : schema()) paths.push_back(spec.path);
  return paths;
}

}  // namespace threshing_sim
