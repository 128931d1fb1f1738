// The YAML reader (section.h).
#include "section.h"

#include <algorithm>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <utility>

namespace threshing_sim {
namespace loader {
namespace {

bool isDigit(char c) { return c >= '0' && c <= '9'; }

// Whether text is a plain decimal [+-]digits[.digits][e[+-]digits] (or [+-].digits...), the
// form whose value yaml-cpp's stream conversion and strtod agree on.
bool simpleDecimal(const std::string& text) {
  size_t i = 0;
  const size_t n = text.size();
  if (n == 0 || n > 32) return false;
  if (text[i] == '+' || text[i] == '-') ++i;
  size_t digits = 0;
  for (; i < n && isDigit(text[i]); ++i) ++digits;
  if (i < n && text[i] == '.') {
    for (++i; i < n && isDigit(text[i]); ++i) ++digits;
  }
  if (digits == 0) return false;
  if (i < n && (text[i] == 'e' || text[i] == 'E')) {
    ++i;
    if (i < n && (text[i] == '+' || text[i] == '-')) ++i;
    size_t exponent_digits = 0;
    for (; i < n && isDigit(text[i]); ++i) ++exponent_digits;
    if (exponent_digits == 0) return false;
  }
  return i == n;
}

// Whether the mantissa of a simple decimal is all zeros (its value is exactly 0).
bool zeroMantissa(const std::string& text) {
  for (char c : text) {
    if (c == 'e' || c == 'E') return true;
    if (isDigit(c) && c != '0') return false;
  }
  return true;
}

// The text's value when it is a simple decimal whose value is 0 or a finite normal double
// (where the stream conversion yaml-cpp uses gives strtod's value); false otherwise, for the
// caller to ask yaml-cpp.
bool fastDouble(const std::string& text, double* value) {
  if (!simpleDecimal(text)) return false;
  const char* first = text.data() + (text[0] == '+' ? 1 : 0);  // from_chars takes no '+'
  double v = 0;
  const auto read = std::from_chars(first, text.data() + text.size(), v);
  if (read.ec != std::errc() || read.ptr != text.data() + text.size()) return false;
  if (v == 0 ? !zeroMantissa(text) : !(std::abs(v) >= DBL_MIN && std::abs(v) <= DBL_MAX)) {
    return false;
  }
  *value = v;
  return true;
}

// The text's value when it is [+-]0 or [+-] and 1 to 9 digits without a leading zero (no octal
// or hexadecimal reading, no overflow); false otherwise.
bool fastInt(const std::string& text, int* value) {
  const size_t sign = !text.empty() && (text[0] == '+' || text[0] == '-') ? 1 : 0;
  const size_t digits = text.size() - sign;
  if (digits == 0 || digits > 9) return false;
  if (text[sign] == '0' && digits > 1) return false;
  for (size_t i = sign; i < text.size(); ++i)
    if (!isDigit(text[i])) return false;
  *value = static_cast<int>(std::strtol(text.c_str(), nullptr, 10));
  return true;
}

const SceneNode kUndefined;

}  // namespace

bool decodeNumber(const SceneNode& node, double* value) {
  if (!node.isPlainScalar()) return false;
  return fastDouble(node.text, value) ||
         YAML::convert<double>::decode(YAML::Node(node.text), *value);
}

bool decodeInteger(const SceneNode& node, int* value) {
  if (!node.isPlainScalar()) return false;
  return fastInt(node.text, value) || YAML::convert<int>::decode(YAML::Node(node.text), *value);
}

double toNumber(const SceneNode& node, const std::string& path) {
  double value = 0;
  if (!decodeNumber(node, &value)) fail(path, "expected a number (got " + show(node) + ")");
  if (!std::isfinite(value)) fail(path, "must be finite (got " + show(node) + ")");
  return value;
}

Section::Section(const SceneNode& node, std::string path, const std::vector<std::string>& known,
                 const std::string& owner)
    : path_(std::move(path)), pattern_(patternOf(path_)), known_(&known) {
  if (&known == &childKeys(pattern_)) {
    shared_specs_ = &childSpecs(pattern_);
  } else {
    own_specs_ = specsOf(pattern_, known);
  }
  if (!node.defined() || node.isNull()) return;
  if (!node.isMap()) fail(path_, "expected a mapping of keys (got " + show(node) + ")");
  values_.resize(known.size(), nullptr);
  for (size_t i = 0; i + 1 < node.items.size(); i += 2) {
    const SceneNode& key = node.items[i];
    if (!key.isScalar() || !quotableKey(key.text)) fail(path_, notAKeyName(key));
    const int index = indexOf(key.text);
    if (index < 0) fail(joinPath(path_, key.text), unknownKey(key.text, known, owner));
    if (values_[index] != nullptr) fail(joinPath(path_, key.text), "duplicate key");
    values_[index] = &node.items[i + 1];
  }
}

int Section::indexOf(const std::string& key) const {
  const auto found = std::find(known_->begin(), known_->end(), key);
  return found == known_->end() ? -1 : static_cast<int>(found - known_->begin());
}

const SceneNode* Section::find(const std::string& key) const {
  if (values_.empty()) return nullptr;
  const int index = indexOf(key);
  return index >= 0 ? values_[index] : nullptr;
}

bool Section::has(const std::string& key) const { return find(key) != nullptr; }

const SceneNode& Section::node(const std::string& key) const {
  const SceneNode* found = find(key);
  return found != nullptr ? *found : kUndefined;
}

void Section::require(const std::string& key) const {
  if (!has(key)) fail(path(key), "required key is missing");
}

const KeySpec* Section::specOf(const std::string& key) const {
  const std::vector<const KeySpec*>& specs = shared_specs_ != nullptr ? *shared_specs_ : own_specs_;
  const int index = indexOf(key);
  return index >= 0 ? specs[index] : findKey(loader::joinPath(pattern_, key));
}

const Bound& Section::rangeOf(const std::string& key) const {
  const KeySpec* spec = specOf(key);
  return spec != nullptr ? spec->range : kNoRange;
}

double Section::number(const std::string& key, double fallback) const {
  const SceneNode* found = find(key);
  if (found == nullptr) return fallback;
  const SceneNode& n = *found;
  double value = 0;
  if (!decodeNumber(n, &value)) fail(path(key), "expected a number (got " + show(n) + ")");
  if (!std::isfinite(value)) fail(path(key), "must be finite (got " + show(n) + ")");
  const Bound& bound = rangeOf(key);
  if (!bound.contains(value)) fail(path(key), "must be " + bound.text() + " (got " + show(n) + ")");
  return value;
}

int Section::integer(const std::string& key, int fallback) const {
  if (!has(key)) return fallback;
  const SceneNode& n = node(key);
  int value = 0;
  if (!decodeInteger(n, &value)) fail(path(key), "expected an integer (got " + show(n) + ")");
  const Bound& bound = rangeOf(key);
  if (!bound.contains(value)) fail(path(key), "must be " + bound.text() + " (got " + show(n) + ")");
  return value;
}

Vec2 Section::vec2(const std::string& key, const Vec2& fallback) const {
  const SceneNode* found = find(key);
  if (found == nullptr) return fallback;
  const SceneNode& n = *found;
  const auto refuse = [&](const std::string& what) { fail(path(key), what + show(n) + ")"); };
  if (!n.isSequence() || n.size() != 2) refuse("expected a list of 2 numbers [x, y] (got ");
  Vec2 v;
  const Bound& bound = rangeOf(key);
  for (int i = 0; i < 2; ++i) {
    if (!decodeNumber(n.items[i], &v[i])) refuse("expected a list of 2 numbers [x, y] (got ");
    if (!std::isfinite(v[i])) refuse("must be finite (got ");
    if (!bound.contains(v[i])) refuse("each number must be " + bound.text() + " (got ");
  }
  return v;
}

std::string Section::word(const std::string& key, const std::string& fallback,
                          const std::string& what) const {
  if (!has(key)) return fallback;
  const SceneNode& n = node(key);
  const KeySpec* spec = specOf(key);
  const std::vector<std::string> allowed = spec != nullptr && spec->words != nullptr
                                               ? splitWords(spec->words)
                                               : std::vector<std::string>();
  if (!n.isScalar() || std::find(allowed.begin(), allowed.end(), n.text) == allowed.end()) {
    const std::string got = n.isScalar() ? "'" + n.text + "'" : show(n);
    fail(path(key),
         "unknown " + what + " " + got + " (expected one of: " + joinWords(allowed) + ")");
  }
  return n.text;
}

Section Section::section(const std::string& key, const std::string& pattern) const {
  return Section(node(key), path(key), childKeys(pattern));
}

std::vector<const SceneNode*> Section::list(const std::string& key) const {
  const SceneNode& n = node(key);
  std::vector<const SceneNode*> items;
  if (!n.defined() || n.isNull()) return items;
  if (!n.isSequence()) fail(path(key), "expected a list (got " + show(n) + ")");
  items.reserve(n.size());
  for (const SceneNode& item : n.items) items.push_back(&item);
  return items;
}

}  // namespace loader
}  // namespace threshing_sim
