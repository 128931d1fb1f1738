// JSON for simulate --batch's lines (RFC 8259: objects, arrays, strings with every escape,
// numbers, true, false, null).
#include "json.h"

#include <cstdio>
#include <cstring>

namespace threshing_sim {
namespace app {
namespace {

constexpr int kMaxDepth = 32;

class Reader {
 public:
  explicit Reader(const std::string& text) : text_(text) {}

  JsonValue document() {
    JsonValue value = parseValue(0);
    skipSpace();
    if (pos_ != text_.size()) fail("expected the end of the line after the value");
    return value;
  }

 private:
  [[noreturn]] void fail(const std::string& what) const {
    throw JsonError("column " + std::to_string(pos_ + 1) + ": " + what);
  }

  void skipSpace() {
    while (pos_ < text_.size() && std::strchr(" \t\r\n", text_[pos_]) != nullptr) ++pos_;
  }

  char peek() const { return pos_ < text_.size() ? text_[pos_] : '\0'; }

  void expect(char c, const char* what) {
    skipSpace();
    if (peek() != c) fail(std::string("expected ") + what);
    ++pos_;
  }

  JsonValue parseValue(int depth) {
    if (depth > kMaxDepth) fail("nested deeper than " + std::to_string(kMaxDepth));
    skipSpace();
    const char c = peek();
    if (c == '{') return parseObject(depth);
    if (c == '[') return parseArray(depth);
    JsonValue value;
    if (c == '"') {
      value.kind = JsonValue::Kind::kString;
      value.text = parseString();
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      value.kind = JsonValue::Kind::kNumber;
      value.text = parseNumber();
    } else if (word("true")) {
      value.kind = JsonValue::Kind::kBool;
      value.flag = true;
    } else if (word("false")) {
      value.kind = JsonValue::Kind::kBool;
    } else if (!word("null")) {
      fail("expected a JSON value");
    }
    return value;
  }

  bool word(const char* w) {
    const size_t n = std::strlen(w);
    if (text_.compare(pos_, n, w) != 0) return false;
    pos_ += n;
    return true;
  }

  JsonValue parseObject(int depth) {
    JsonValue value;
    value.kind = JsonValue::Kind::kObject;
    ++pos_;  // '{'
    skipSpace();
    if (peek() == '}') return ++pos_, value;
    for (;;) {  // each pass consumes a member or fails
      skipSpace();
      if (peek() != '"') fail("expected a key (a string)");
      std::string key = parseString();
      expect(':', "':' after a key");
      value.members.emplace_back(std::move(key), parseValue(depth + 1));
      skipSpace();
      if (peek() == '}') return ++pos_, value;
      expect(',', "',' or '}' in an object");
    }
  }

  JsonValue parseArray(int depth) {
    JsonValue value;
    value.kind = JsonValue::Kind::kArray;
    ++pos_;  // '['
    skipSpace();
    if (peek() == ']') return ++pos_, value;
    for (;;) {  // each pass consumes an item or fails
      value.items.push_back(parseValue(depth + 1));
      skipSpace();
      if (peek() == ']') return ++pos_, value;
      expect(',', "',' or ']' in an array");
    }
  }

  std::string parseNumber() {
    const size_t start = pos_;
    if (peek() == '-') ++pos_;
    auto digits = [&] {
      const size_t first = pos_;
      while (peek() >= '0' && peek() <= '9') ++pos_;
      if (pos_ == first) fail("expected a digit");
    };
    if (peek() == '0') {
      ++pos_;
    } else {
      digits();
    }
    if (peek() == '.') ++pos_, digits();
    if (peek() == 'e' || peek() == 'E') {
      ++pos_;
      if (peek() == '+' || peek() == '-') ++pos_;
      digits();
    }
    return text_.substr(start, pos_ - start);
  }

  unsigned hex4() {
    if (pos_ + 4 > text_.size()) fail("expected four hex digits after \\u");
    unsigned code = 0;
    for (int k = 0; k < 4; ++k) {
      const char h = text_[pos_++];
      const char* digits = "0123456789abcdef";
      const char* at = std::strchr(digits, h >= 'A' && h <= 'F' ? h - 'A' + 'a' : h);
      if (h == '\0' || at == nullptr) fail("expected a hex digit after \\u");
      code = code * 16 + static_cast<unsigned>(at - digits);
    }
    return code;
  }

  // A \u escape (a surrogate pair as one code point) as UTF-8.
  void unicodeEscape(std::string* out) {
    unsigned code = hex4();
    if (code >= 0xD800 && code <= 0xDBFF) {
      if (!word("\\u")) fail("expected the low surrogate of a \\u pair");
      const unsigned low = hex4();
      if (low < 0xDC00 || low > 0xDFFF) fail("expected a low surrogate (\\uDC00-\\uDFFF)");
      code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
    } else if (code >= 0xDC00 && code <= 0xDFFF) {
      fail("a low surrogate without its high one");
    }
    if (code < 0x80) {
      out->push_back(static_cast<char>(code));
    } else if (code < 0x800) {
      out->push_back(static_cast<char>(0xC0 | (code >> 6)));
      out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
    } else if (code < 0x10000) {
      out->push_back(static_cast<char>(0xE0 | (code >> 12)));
      out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
      out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
    } else {
      out->push_back(static_cast<char>(0xF0 | (code >> 18)));
      out->push_back(static_cast<char>(0x80 | ((code >> 12) & 0x3F)));
      out->push_back(static_cast<char>(0x80 | ((code >> 6) & 0x3F)));
      out->push_back(static_cast<char>(0x80 | (code & 0x3F)));
    }
  }

  std::string parseString() {
    ++pos_;  // '"'
    std::string out;
    for (;;) {  // each pass consumes at least one character or fails
      if (pos_ >= text_.size()) fail("unterminated string");
      const char c = text_[pos_++];
      if (c == '"') return out;
      if (static_cast<unsigned char>(c) < 0x20) fail("a control character in a string");
      if (c != '\\') {
        out.push_back(c);
        continue;
      }
      const char e = peek();
      ++pos_;
      const char* from = "\"\\/bfnrt";
      const char* to = "\"\\/\b\f\n\r\t";
      const char* at = e == '\0' ? nullptr : std::strchr(from, e);
      if (at != nullptr) {
        out.push_back(to[at - from]);
      } else if (e == 'u') {
        unicodeEscape(&out);
      } else {
        --pos_;
        fail("unknown escape in a string");
      }
    }
  }

  const std::string& text_;
  size_t pos_ = 0;
};

void appendShown(const JsonValue& value, size_t limit, std::string* out) {
  if (out->size() > limit) return;
  switch (value.kind) {
    case JsonValue::Kind::kNull:
      *out += "null";
      return;
    case JsonValue::Kind::kBool:
      *out += value.flag ? "true" : "false";
      return;
    case JsonValue::Kind::kNumber:
      *out += value.text;
      return;
    case JsonValue::Kind::kString:
      appendJsonString(value.text, out);
      return;
    case JsonValue::Kind::kArray:
      *out += "[";
      for (size_t k = 0; k < value.items.size(); ++k) {
        if (k) *out += ", ";
        appendShown(value.items[k], limit, out);
      }
      *out += "]";
      return;
    case JsonValue::Kind::kObject:
      *out += "{";
      for (size_t k = 0; k < value.members.size(); ++k) {
        if (k) *out += ", ";
        appendJsonString(value.members[k].first, out);
        *out += ": ";
        appendShown(value.members[k].second, limit, out);
      }
      *out += "}";
      return;
  }
}

}  // namespace

JsonValue parseJson(const std::string& text) { return Reader(text).document(); }

std::string showJson(const JsonValue& value, size_t limit) {
  std::string out;
  appendShown(value, limit, &out);
  return out.size() > limit ? out.substr(0, limit) + "..." : out;
}

void appendJsonString(const std::string& text, std::string* out) {
  out->push_back('"');
  for (const char c : text) {
    if (c == '"' || c == '\\') {
      out->push_back('\\');
      out->push_back(c);
    } else if (c == '\n') {
      *out += "\\n";
    } else if (c == '\t') {
      *out += "\\t";
    } else if (static_cast<unsigned char>(c) < 0x20) {
      char escape[8];
      std::snprintf(escape, sizeof(escape), "\\u%04x", static_cast<unsigned>(c));
      *out += escape;
    } else {
      out->push_back(c);
    }
  }
  out->push_back('"');
}

}  // namespace app
}  // namespace threshing_sim
