// The YAML reader (section.h).
#include "section.h"

#include <algorithm>
#include <cfloat>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
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

// Clinger's fast path: a decimal of at most 15 significant digits times 10^e with |e| <= 22
// is one correctly rounded product or quotient of two exact doubles, strtod's value.
bool clingerDecimal(const std::string& text, double* value) {
  size_t i = 0;
  const size_t n = text.size();
  const bool negative = n > 0 && text[0] == '-';
  if (n > 0 && (text[0] == '+' || text[0] == '-')) ++i;
  uint64_t mantissa = 0;
  int significant = 0, scale = 0, digits = 0;
  bool point = false;
  for (; i < n && (isDigit(text[i]) || (text[i] == '.' && !point)); ++i) {
    if (text[i] == '.') {
      point = true;
      continue;
    }
    ++digits;
    if (mantissa != 0 || text[i] != '0') ++significant;
    mantissa = mantissa * 10 + static_cast<uint64_t>(text[i] - '0');
    if (point) --scale;
    if (significant > 15) return false;
  }
  if (digits == 0) return false;
  if (i < n && (text[i] == 'e' || text[i] == 'E')) {
    const bool down = i + 1 < n && text[i + 1] == '-';
    i += i + 1 < n && (text[i + 1] == '-' || text[i + 1] == '+') ? 2 : 1;
    if (i >= n) return false;
    int exponent = 0;
    for (; i < n && isDigit(text[i]) && exponent < 1000; ++i)
      exponent = exponent * 10 + (text[i] - '0');
    scale += down ? -exponent : exponent;
  }
  if (i != n || scale < -22 || scale > 22) return false;
  static const double kPow10[] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,
                                  1e8,  1e9,  1e10, 1e11, 1e12, 1e13, 1e14, 1e15,
                                  1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
  const double m = static_cast<double>(mantissa);
  const double v = scale >= 0 ? m * kPow10[scale] : m / kPow10[-scale];
  *value = negative ? -v : v;
  return true;
}

// The text's value when it is a simple decimal whose value is 0 or a finite normal double
// (where the stream conversion yaml-cpp uses gives strtod's value); false otherwise, for the
// caller to ask yaml-cpp.
bool fastDouble(const std::string& text, double* value) {
  if (clingerDecimal(text, value)) return true;
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

Section::Section(const SceneNode& node, std::string path, const Children& keys,
                 const std::string& owner)
    : path_(std::move(path)), keys_(&keys) {
  if (!node.defined() || node.isNull()) return;
  if (!node.isMap()) fail(path_, "expected a mapping of keys (got " + show(node) + ")");
  values_.resize(keys.keys.size(), nullptr);
  for (size_t i = 0; i + 1 < node.items.size(); i += 2) {
    const SceneNode& key = node.items[i];
    const int index = key.isScalar() ? indexOf(key.text) : -1;
    if (index < 0 && !(key.isScalar() && quotableKey(key.text)))
      fail(path_, notAKeyName(key, keys.keys));
    if (index < 0) fail(joinPath(path_, key.text), unknownKey(key.text, keys.keys, owner));
    if (values_[index] != nullptr) fail(joinPath(path_, key.text), "duplicate key");
    values_[index] = &node.items[i + 1];
  }
}

int Section::indexOf(const std::string& key) const {
  const std::vector<std::string>& keys = keys_->keys;
  const size_t size = key.size();
  for (size_t i = 0; i < keys.size(); ++i) {
    const std::string& k = keys[i];
    if (k.size() == size && k[0] == key[0] && std::memcmp(k.data(), key.data(), size) == 0) {
      return static_cast<int>(i);
    }
  }
  return -1;
}

const SceneNode* Section::find(const std::string& key) const {
  const KeySpec* spec = nullptr;
  return find(key, &spec);
}

const SceneNode* Section::find(const std::string& key, const KeySpec** spec) const {
  const int index = indexOf(key);
  *spec = index >= 0 ? keys_->specs[index] : nullptr;
  return index >= 0 && !values_.empty() ? values_[index] : nullptr;
}

const Bound& Section::rangeOf(const KeySpec* spec) {
  return spec != nullptr ? spec->range : kNoRange;
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
  const int index = indexOf(key);
  return index >= 0 ? keys_->specs[index] : nullptr;
}

double Section::number(const std::string& key, double fallback) const {
  const KeySpec* spec = nullptr;
  const SceneNode* found = find(key, &spec);
  if (found == nullptr) return fallback;
  const SceneNode& n = *found;
  double value = 0;
  if (!decodeNumber(n, &value)) fail(path(key), "expected a number (got " + show(n) + ")");
  if (!std::isfinite(value)) fail(path(key), "must be finite (got " + show(n) + ")");
  const Bound& bound = rangeOf(spec);
  if (!bound.contains(value)) fail(path(key), "must be " + bound.text() + " (got " + show(n) + ")");
  return value;
}

int Section::integer(const std::string& key, int fallback) const {
  const KeySpec* spec = nullptr;
  const SceneNode* found = find(key, &spec);
  if (found == nullptr) return fallback;
  const SceneNode& n = *found;
  int value = 0;
  if (!decodeInteger(n, &value)) fail(path(key), "expected an integer (got " + show(n) + ")");
  const Bound& bound = rangeOf(spec);
  if (!bound.contains(value)) fail(path(key), "must be " + bound.text() + " (got " + show(n) + ")");
  return value;
}

Vec2 Section::vec2(const std::string& key, const Vec2& fallback) const {
  const KeySpec* spec = nullptr;
  const SceneNode* found = find(key, &spec);
  if (found == nullptr) return fallback;
  const SceneNode& n = *found;
  const auto refuse = [&](const std::string& what) { fail(path(key), what + show(n) + ")"); };
  if (!n.isSequence() || n.size() != 2) refuse("expected a list of 2 numbers [x, y] (got ");
  Vec2 v;
  const Bound& bound = rangeOf(spec);
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
  return section(key, children(pattern));
}

Section Section::section(const std::string& key, const Children& keys) const {
  return Section(node(key), path(key), keys);
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
