// SceneNode trees (scene_tree.h): lookups, reading files and texts (the loader's reader, or
// yaml-cpp for what it does not take), conversions from and to yaml-cpp's nodes, and the
// one-line flow writing of simulate --check.
#include <sys/stat.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <utility>

#include "threshing_sim/scene/scene_loader.h"
#include "threshing_sim/scene/scene_tree.h"
#include "yaml_reader.h"

namespace threshing_sim {

const SceneNode* SceneNode::find(const std::string& key) const {
  if (kind != Kind::kMap) return nullptr;
  for (size_t i = 0; i + 1 < items.size(); i += 2)
    if (items[i].kind == Kind::kScalar && items[i].text == key) return &items[i + 1];
  return nullptr;
}

SceneNode* SceneNode::find(const std::string& key) {
  return const_cast<SceneNode*>(static_cast<const SceneNode*>(this)->find(key));
}

SceneNode SceneNode::map() {
  SceneNode node;
  node.kind = Kind::kMap;
  node.tag = "?";
  return node;
}

SceneNode SceneNode::scalar(std::string text, std::string tag) {
  SceneNode node;
  node.kind = Kind::kScalar;
  node.text = std::move(text);
  node.tag = std::move(tag);
  return node;
}

// A file whose text holds a control character (a zero byte, say) is no YAML text; it is refused
// by its name and where, quoting none of it (a binary file named as a scene).
void loader::refuseBinary(const std::string& path, const std::string& text) {
  int line = 1;
  size_t line_start = 0;
  for (size_t i = 0; i < text.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(text[i]);
    if (c == '\n') {
      ++line;
      line_start = i + 1;
    } else if ((c < 0x20 && c != '\t' && c != '\r') || c == 0x7f) {
      throw SceneError(path + ": not a YAML text file (a control character at line " +
                       std::to_string(line) + ", column " + std::to_string(i - line_start + 1) +
                       ")");
    }
  }
}

SceneNode parseSceneText(const std::string& text) {
  SceneNode root;
  if (loader::readYamlSubset(text, &root)) return root;
  return sceneNodeFromYaml(YAML::Load(text));
}

SceneNode readSceneFile(const std::string& path) {
  struct stat info;
  if (::stat(path.c_str(), &info) == 0 && S_ISDIR(info.st_mode))
    throw SceneError(path + ": is a directory, not a YAML file");
  std::ifstream file(path, std::ios::binary);
  if (!file) throw SceneError(path + ": cannot open scene file");
  std::ostringstream content;
  content << file.rdbuf();
  const std::string text = content.str();
  SceneNode root;
  if (loader::readYamlSubset(text, &root)) return root;
  loader::refuseBinary(path, text);
  return sceneNodeFromYaml(loadSceneYaml(path));
}

SceneNode sceneNodeFromYaml(const YAML::Node& node) {
  SceneNode out;
  if (!node.IsDefined()) return out;
  out.tag = node.Tag();
  out.line = node.Mark().line;
  out.column = node.Mark().column;
  switch (node.Type()) {
    case YAML::NodeType::Scalar:
      out.kind = SceneNode::Kind::kScalar;
      out.text = node.Scalar();
      break;
    case YAML::NodeType::Sequence:
      out.kind = SceneNode::Kind::kSequence;
      for (const auto& item : node) out.items.push_back(sceneNodeFromYaml(item));
      break;
    case YAML::NodeType::Map:
      out.kind = SceneNode::Kind::kMap;
      for (const auto& entry : node) {
        out.items.push_back(sceneNodeFromYaml(entry.first));
        out.items.push_back(sceneNodeFromYaml(entry.second));
      }
      break;
    default:
      out.kind = SceneNode::Kind::kNull;
  }
  return out;
}

YAML::Node yamlFromSceneNode(const SceneNode& node) {
  YAML::Node out;
  switch (node.kind) {
    case SceneNode::Kind::kUndefined:
      return YAML::Node(YAML::NodeType::Undefined);
    case SceneNode::Kind::kNull:
      return YAML::Node(YAML::NodeType::Null);
    case SceneNode::Kind::kScalar:
      out = YAML::Node(node.text);
      break;
    case SceneNode::Kind::kSequence:
      out = YAML::Node(YAML::NodeType::Sequence);
      for (const SceneNode& item : node.items) out.push_back(yamlFromSceneNode(item));
      break;
    case SceneNode::Kind::kMap:
      out = YAML::Node(YAML::NodeType::Map);
      for (size_t i = 0; i + 1 < node.items.size(); i += 2)
        out.force_insert(yamlFromSceneNode(node.items[i]), yamlFromSceneNode(node.items[i + 1]));
      break;
  }
  if (!node.tag.empty()) out.SetTag(node.tag);
  return out;
}

namespace {

// Letters, digits and "_.+-": a plain scalar of these is written as it is.
struct SafeInFlow {
  bool safe[256] = {};
  SafeInFlow() {
    for (int c = 0; c < 256; ++c) {
      safe[c] = (c >= '0' && c <= '9') || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') ||
                c == '_' || c == '.' || c == '+' || c == '-';
    }
  }
  bool operator()(char c) const { return safe[static_cast<unsigned char>(c)]; }
};
const SafeInFlow kSafeInFlow;

void writeCollection(const SceneNode& node, std::string* out) {
  const bool map = node.isMap();
  *out += map ? '{' : '[';
  const size_t step = map ? 2 : 1;
  for (size_t i = 0; i < node.items.size(); i += step) {
    if (i != 0) out->append(", ", 2);
    writeFlow(node.items[i], out);
    if (map) {
      out->append(": ", 2);
      writeFlow(node.items[i + 1], out);
    }
  }
  *out += map ? '}' : ']';
}

}  // namespace

void writeFlow(const SceneNode& node, std::string* out) {
  if (node.isMap() || node.isSequence()) return writeCollection(node, out);
  const std::string& text = node.text;
  const auto safe = [](char c) { return kSafeInFlow(c); };
  if (node.isPlainScalar() && !text.empty() && std::all_of(text.begin(), text.end(), safe)) {
    out->append(text);
    return;
  }
  YAML::Emitter emitter;
  emitter << YAML::Flow << yamlFromSceneNode(node);
  std::string emitted = emitter.c_str();
  std::replace(emitted.begin(), emitted.end(), '\n', ' ');
  *out += emitted;
}

}  // namespace threshing_sim
