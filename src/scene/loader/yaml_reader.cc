// The loader's own YAML reader (scene_tree.h): the YAML scenes are written in, read in one pass
// over the text into a SceneNode tree, with the tree yaml-cpp's parser gives. Block mappings
// and lists (a list may sit at its key's indentation, a list item may open a mapping), flow
// mappings and lists over any number of lines, plain scalars (~, null, Null, NULL and an empty
// value are nulls), single-quoted and double-quoted scalars without escapes or line breaks,
// and comments. Anything else (anchors, aliases, tags, block scalars, directives, document
// markers, multi-line plain scalars, escapes, tabs, carriage returns, bytes outside printable
// ASCII) and every syntax error is left to yaml-cpp: the reader gives up (Unsupported) and the
// caller parses the text with yaml-cpp, whose tree and messages are then the answer.
#include "yaml_reader.h"

#include <cstdint>
#include <cstring>
#include <utility>

namespace threshing_sim {
namespace loader {
namespace {

// The reader gives up on the text (rare: yaml-cpp reads it instead).
struct Unsupported {};

// The characters a plain scalar's loop looks at twice: line feed, '#', ':', the flow
// indicators, '?' and the bytes outside ASCII.
struct PlainStops {
  bool stop[256] = {};
  PlainStops() {
    for (const char c : std::string("\n#:[]{},?")) stop[static_cast<unsigned char>(c)] = true;
    for (int c = 0x80; c < 0x100; ++c) stop[c] = true;
  }
  bool operator[](unsigned char c) const { return stop[c]; }
};
const PlainStops kPlainStop;

bool isNullWord(const char* text, size_t size) {
  if (size == 1) return text[0] == '~';
  return size == 4 && (std::memcmp(text, "null", 4) == 0 || std::memcmp(text, "Null", 4) == 0 ||
                       std::memcmp(text, "NULL", 4) == 0);
}

class Reader {
 public:
  explicit Reader(const std::string& text) : s_(text.data()), n_(text.size()) {}

  void document(SceneNode* root) {
    checkCharacters();
    skipBlankLines();
    if (pos_ >= n_) return null(0, 0, root);
    if (lineIndent() != 0) throw Unsupported();
    block(-1, root);
    skipBlankLines();
    if (pos_ < n_) throw Unsupported();
  }

 private:
  // Printable ASCII and line feeds; other bytes (UTF-8) only in comments (scalars check
  // their own), and no byte order mark.
  void checkCharacters() const {
    if (n_ >= 3 && static_cast<unsigned char>(s_[0]) == 0xef) throw Unsupported();
    constexpr uint64_t kOnes = 0x0101010101010101ULL, kHigh = 0x8080808080808080ULL;
    size_t i = 0;
    for (; i + 8 <= n_; i += 8) {  // eight bytes at a time: any below 0x20, or 0x7f?
      uint64_t word;
      std::memcpy(&word, s_ + i, 8);
      const uint64_t del = word ^ (0x7f * kOnes);
      if ((((word - 0x20 * kOnes) & ~word) | ((del - kOnes) & ~del)) & kHigh) checkBytes(i, i + 8);
    }
    checkBytes(i, n_);
  }

  static bool ascii(char c) { return static_cast<unsigned char>(c) < 0x80; }

  // Bytes [from, to) one by one: line feeds are the only control characters taken.
  void checkBytes(size_t from, size_t to) const {
    for (size_t i = from; i < to; ++i) {
      const unsigned char c = static_cast<unsigned char>(s_[i]);
      if (c != '\n' && (c < 0x20 || c == 0x7f)) throw Unsupported();
    }
  }

  char at(size_t i) const { return i < n_ ? s_[i] : '\n'; }
  char peek() const { return at(pos_); }
  int column() const { return static_cast<int>(pos_ - line_start_); }
  static bool isSpace(char c) { return c == ' '; }
  static bool endsToken(char c) { return c == ' ' || c == '\n'; }

  void newline() {
    ++pos_;
    ++line_;
    line_start_ = pos_;
  }

  // The spaces at the start of the current line (pos_ at its start).
  int lineIndent() const {
    size_t i = pos_;
    while (i < n_ && s_[i] == ' ') ++i;
    return static_cast<int>(i - pos_);
  }

  // From a line's start: past lines holding only spaces and a comment; stays at the start of
  // the next line with content, or at the end. Document markers and directives give up.
  void skipBlankLines() {
    while (pos_ < n_) {
      size_t i = pos_;
      while (i < n_ && s_[i] == ' ') ++i;
      if (i < n_ && s_[i] != '\n' && s_[i] != '#') {
        if (i == pos_ && (s_[i] == '%' || startsWith(i, "---") || startsWith(i, "..."))) {
          throw Unsupported();
        }
        return;
      }
      while (i < n_ && s_[i] != '\n') ++i;
      pos_ = i;
      if (pos_ < n_) newline();
    }
  }

  bool startsWith(size_t i, const char* word) const {
    const size_t len = std::strlen(word);
    return i + len <= n_ && std::memcmp(s_ + i, word, len) == 0;
  }

  // Past spaces and a comment to the end of the line (and past it); gives up on anything else.
  void endLine() {
    while (isSpace(peek()) && pos_ < n_) ++pos_;
    if (pos_ < n_ && peek() == '#') {
      if (pos_ > line_start_ && at(pos_ - 1) != ' ') throw Unsupported();
      while (pos_ < n_ && peek() != '\n') ++pos_;
    }
    if (pos_ < n_ && peek() != '\n') throw Unsupported();
    if (pos_ < n_) newline();
  }

  static void null(int line, int column, SceneNode* node) {
    node->kind = SceneNode::Kind::kNull;
    node->line = line;
    node->column = column;
  }

  // A mapping or list starting at pos_, with room for a few items.
  void collection(SceneNode::Kind kind, SceneNode* node) const {
    node->kind = kind;
    node->tag.push_back('?');
    node->line = line_;
    node->column = column();
    node->items.reserve(kind == SceneNode::Kind::kMap ? 16 : 2);
  }

  // A block node whose first line starts at pos_ (at its indentation), deeper than parent.
  void block(int parent, SceneNode* out) {
    pos_ += lineIndent();
    if (column() <= parent) throw Unsupported();
    if (peek() == '-' && endsToken(at(pos_ + 1))) return blockSequence(column(), out);
    if (keyAhead()) return blockMap(column(), out);
    inlineValue(false, out);
    endLine();
  }

  // Whether a mapping key ("key:" then a space or the line's end) starts at pos_.
  bool keyAhead() const {
    const char c = peek();
    if (c == '[' || c == '{') return false;
    size_t i = pos_;
    if (c == '"' || c == '\'') {
      for (++i; i < n_ && s_[i] != c && s_[i] != '\n'; ++i) {
      }
      for (++i; i < n_ && s_[i] == ' ';) ++i;
      return at(i) == ':';
    }
    for (; i < n_ && s_[i] != '\n'; ++i) {
      if (s_[i] == '#' && i > pos_ && s_[i - 1] == ' ') return false;
      if (s_[i] == ':' && endsToken(at(i + 1))) return true;
    }
    return false;
  }

  // Entries "key: value" at column `indent`, the first at pos_.
  void blockMap(int indent, SceneNode* map) {
    collection(SceneNode::Kind::kMap, map);
    for (;;) {
      blockKey(&map->items.emplace_back());
      blockValue(indent, &map->items.emplace_back());
      skipBlankLines();
      if (pos_ >= n_) return;
      const int next = lineIndent();
      if (next < indent) return;
      if (next > indent) throw Unsupported();
      pos_ += next;
      if (peek() == '-' && endsToken(at(pos_ + 1))) {
        pos_ = line_start_;  // a list at its key's indentation ends here
        return;
      }
      if (!keyAhead()) throw Unsupported();
    }
  }

  // A key and its ':'.
  void blockKey(SceneNode* key) {
    const char c = peek();
    if (c == '"' || c == '\'') {
      quoted(key);
    } else {
      plain(false, true, key);
    }
    while (isSpace(peek())) ++pos_;
    if (peek() != ':') throw Unsupported();
    ++pos_;
  }

  // The value after "key:" of a block mapping at column indent.
  void blockValue(int indent, SceneNode* value) {
    while (isSpace(peek()) && pos_ < n_) ++pos_;
    if (peek() == '\n' || peek() == '#') {
      const int line = line_, col = column();
      endLine();
      skipBlankLines();
      if (pos_ >= n_) return null(line, col, value);
      const int next = lineIndent();
      if (next > indent) return block(indent, value);
      if (next == indent && at(pos_ + next) == '-' && endsToken(at(pos_ + next + 1))) {
        pos_ += next;
        return blockSequence(indent, value);
      }
      return null(line, col, value);
    }
    inlineValue(false, value);
    endLine();
    noDeeperLine(indent);
  }

  // After an inline value: a deeper line next would continue it (a multi-line scalar).
  void noDeeperLine(int indent) {
    const size_t keep = pos_;
    const int keep_line = line_;
    const size_t keep_start = line_start_;
    skipBlankLines();
    const bool deeper = pos_ < n_ && lineIndent() > indent;
    pos_ = keep;
    line_ = keep_line;
    line_start_ = keep_start;
    if (deeper) throw Unsupported();
  }

  // Items "- value" at column indent, the first at pos_.
  void blockSequence(int indent, SceneNode* list) {
    collection(SceneNode::Kind::kSequence, list);
    for (;;) {
      ++pos_;  // the '-'
      sequenceItem(indent, &list->items.emplace_back());
      skipBlankLines();
      if (pos_ >= n_) return;
      const int next = lineIndent();
      if (next < indent) return;
      if (next > indent) throw Unsupported();
      if (!(at(pos_ + next) == '-' && endsToken(at(pos_ + next + 1)))) {
        return;  // the next key of the mapping this list is a value of
      }
      pos_ += next;
    }
  }

  void sequenceItem(int indent, SceneNode* item) {
    while (isSpace(peek()) && pos_ < n_) ++pos_;
    if (peek() == '\n' || peek() == '#') {
      const int line = line_, col = column();
      endLine();
      skipBlankLines();
      if (pos_ < n_ && lineIndent() > indent) return block(indent, item);
      return null(line, col, item);
    }
    if (peek() == '-' && endsToken(at(pos_ + 1))) throw Unsupported();
    if (keyAhead()) return blockMap(column(), item);
    inlineValue(false, item);
    endLine();
    noDeeperLine(indent);
  }

  // A scalar or flow collection on the current line (a flow collection may go on).
  void inlineValue(bool flow, SceneNode* out) {
    const char c = peek();
    if (c == '[') return flowSequence(out);
    if (c == '{') return flowMap(out);
    if (c == '"' || c == '\'') return quoted(out);
    plain(flow, false, out);
  }

  // A plain scalar; in flow context it ends at ",]}", in block context at the line's end.
  void plain(bool flow, bool key, SceneNode* node) {
    const char c = peek();
    const bool starts = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') ||
                        (c >= 'A' && c <= 'Z') || c == '.' || c == '_' || c == '+' || c == '/' ||
                        c == '~' || (c == '-' && !endsToken(at(pos_ + 1)) && at(pos_ + 1) != ',');
    if (!starts ||
        ((c == '-' || c == '.') && (startsWith(pos_, "---") || startsWith(pos_, "...")))) {
      throw Unsupported();
    }
    const int line = line_, col = column();
    const size_t start = pos_;
    size_t end = pos_;  // past the last non-space character
    for (; pos_ < n_; ++pos_) {
      const char d = s_[pos_];
      if (kPlainStop[static_cast<unsigned char>(d)]) {
        if (d == '\n') break;
        if (d == '#' && s_[pos_ - 1] == ' ') break;
        if (d == ':' && (flow || endsToken(at(pos_ + 1)))) break;
        if (d == '[' || d == ']' || d == '{' || d == '}' || d == ',') {
          if (!flow) throw Unsupported();
          break;
        }
        if (d == '?' || !ascii(d)) throw Unsupported();
      }
      if (d != ' ') end = pos_ + 1;
    }
    if (key ? peek() != ':' : (peek() == ':' && !flow)) throw Unsupported();
    pos_ = end;
    if (isNullWord(s_ + start, end - start)) return null(line, col, node);
    node->kind = SceneNode::Kind::kScalar;
    node->text.assign(s_ + start, end - start);
    node->tag.push_back('?');
    node->line = line;
    node->column = col;
  }

  // A quoted scalar on one line: '' in single quotes, no escapes in double quotes.
  void quoted(SceneNode* node) {
    const char quote = peek();
    const int line = line_, col = column();
    std::string& text = node->text;
    for (++pos_;; ++pos_) {
      const char d = peek();
      if (pos_ >= n_ || d == '\n' || !ascii(d) || (quote == '"' && d == '\\')) throw Unsupported();
      if (d == quote) {
        if (quote == '\'' && at(pos_ + 1) == '\'') {
          text += '\'';
          ++pos_;
          continue;
        }
        ++pos_;
        break;
      }
      text += d;
    }
    node->kind = SceneNode::Kind::kScalar;
    node->tag.push_back('!');
    node->line = line;
    node->column = col;
  }

  // In flow context: past spaces, line breaks and comments.
  void skipFlowSpace() {
    while (pos_ < n_) {
      const char c = peek();
      if (c == ' ') {
        ++pos_;
      } else if (c == '\n') {
        newline();
        if (at(pos_) == '%' || startsWith(pos_, "---") || startsWith(pos_, "...")) {
          throw Unsupported();
        }
      } else if (c == '#' && pos_ > line_start_ && at(pos_ - 1) == ' ') {
        while (pos_ < n_ && peek() != '\n') ++pos_;
      } else {
        return;
      }
    }
  }

  // After a flow item: ',' (and more items) or the closing bracket.
  bool moreItems(char close) {
    skipFlowSpace();
    if (peek() == ',') {
      ++pos_;
      skipFlowSpace();
      if (peek() == close) throw Unsupported();
      return true;
    }
    if (peek() != close) throw Unsupported();
    ++pos_;
    return false;
  }

  void flowSequence(SceneNode* list) {
    collection(SceneNode::Kind::kSequence, list);
    ++pos_;
    skipFlowSpace();
    if (peek() == ']') {
      ++pos_;
      return;
    }
    do {
      inlineValue(true, &list->items.emplace_back());
      skipFlowSpace();
      if (peek() == ':') throw Unsupported();  // a single-pair mapping
    } while (moreItems(']'));
  }

  void flowMap(SceneNode* map) {
    collection(SceneNode::Kind::kMap, map);
    ++pos_;
    skipFlowSpace();
    if (peek() == '}') {
      ++pos_;
      return;
    }
    do {
      const char c = peek();
      SceneNode* key = &map->items.emplace_back();
      if (c == '"' || c == '\'') {
        quoted(key);
      } else {
        plain(true, false, key);
      }
      while (isSpace(peek()) && pos_ < n_) ++pos_;  // a key and its ':' share a line
      if (peek() != ':') throw Unsupported();
      const int line = line_, col = column();
      ++pos_;
      if (!(endsToken(peek()) || peek() == ',' || peek() == '}')) {
        if (key->tag != "!") throw Unsupported();  // "a:b" is one plain scalar
      }
      skipFlowSpace();
      SceneNode* value = &map->items.emplace_back();
      if (peek() == ',' || peek() == '}') {
        null(line, col, value);
      } else {
        inlineValue(true, value);
      }
    } while (moreItems('}'));
  }

  const char* s_;
  size_t n_;
  size_t pos_ = 0;
  int line_ = 0;
  size_t line_start_ = 0;
};

}  // namespace

bool readYamlSubset(const std::string& text, SceneNode* out) {
  try {
    *out = SceneNode();
    Reader(text).document(out);
    return true;
  } catch (const Unsupported&) {
    return false;
  }
}

}  // namespace loader
}  // namespace threshing_sim
