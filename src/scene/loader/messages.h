// The loader's messages: every refusal names the full key path and the bad value as written.
#pragma once

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {
namespace loader {

// Joins a parent path and a key ("" is the top level).
std::string joinPath(const std::string& parent, const std::string& key);

// Throws SceneError "path: what" ("scene: what" for the top level).
[[noreturn]] void fail(const std::string& path, const std::string& what);

// A node as the user wrote it: flow-style YAML, quoted strings in quotes.
std::string show(const YAML::Node& node);
std::string show(const SceneNode& node);

// Whether a key may be quoted in a message: at most 40 letters, digits, '_', '.' and '*' (a
// file that is no scene, /etc/shadow, must not have its lines quoted back).
bool quotableKey(const std::string& key);

// What kind of node this is and where, quoting none of it: "a scalar of 26 characters at line
// 1, column 1", "a list of 3 items at ...", "a mapping of 2 entries at ...", "null".
std::string describe(const SceneNode& node);

// The node as show() writes it when it is a quotable name, else described.
std::string showOrDescribe(const SceneNode& node);

// yaml-cpp's message of a syntax error without the text it quotes (an unknown escape's
// character): the position says where.
std::string syntaxError(const std::string& message);

// The refusal of a key that is not a key name (described, not quoted), with the known key it
// may be a misspelling of.
std::string notAKeyName(const SceneNode& key, const std::vector<std::string>& known);

// A computed number or vector for a message.
std::string show(double value);
std::string show(const Vec2& v);

// {a, b, c} -> "a, b, c".
std::string joinWords(const std::vector<std::string>& words);

// "unknown key (did you mean 'length'?)", or the list of known keys when nothing is close.
std::string unknownKey(const std::string& key, const std::vector<std::string>& known,
                       const std::string& owner);

}  // namespace loader
}  // namespace threshing_sim
