// A small JSON reader and writer for simulate --batch's lines (batch.cc): one value per line,
// read without yaml-cpp, whose general YAML scanner costs a tenth of a short run per line.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace threshing_sim {
namespace app {

// A JSON text that is not valid; the message names the column (1-based) and what was expected.
class JsonError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct JsonValue {
  enum class Kind { kNull, kBool, kNumber, kString, kArray, kObject };
  Kind kind = Kind::kNull;
  std::string text;                                        // a string's value; a number's text
  bool flag = false;                                       // a bool's value
  std::vector<JsonValue> items;                            // an array's items
  std::vector<std::pair<std::string, JsonValue>> members;  // an object's members, in order
};

// The value of the text, which must hold exactly one JSON value (whitespace around it
// allowed), nested at most 32 deep. Throws JsonError.
JsonValue parseJson(const std::string& text);

// The value as compact JSON, cut after `limit` characters (with "...") for messages.
std::string showJson(const JsonValue& value, size_t limit = 200);

// Appends text as a JSON string (quotes, backslashes and control characters escaped).
void appendJsonString(const std::string& text, std::string* out);

}  // namespace app
}  // namespace threshing_sim
