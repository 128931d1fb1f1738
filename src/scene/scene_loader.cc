// threshing_sim scene files: YAML -> validated, compiled Model.
//
// One schema table lists every key path (loader/schema_table.cc); the reader
// (loader/section.cc) reads each section against it, so an unknown key anywhere is refused
// with a suggestion; the bodies (loader/bodies.cc), the kernel stream and the feed
// (loader/stream.cc, loader/feed.cc) build the Model from the sections; the override walker
// (loader/overrides.cc) uses the schema to decide which missing keys may be created. Every
// refusal names the full key path and the bad value.
#include "threshing_sim/scene/scene_loader.h"

#include <sys/stat.h>

#include <stdexcept>

#include "loader/bodies.h"
#include "loader/messages.h"
#include "loader/overrides.h"
#include "loader/schema.h"
#include "loader/section.h"
#include "loader/stream.h"
#include "threshing_sim/scene/scene_tree.h"

namespace threshing_sim {

using loader::fail;
using loader::Section;
using loader::show;

YAML::Node loadSceneYaml(const std::string& path) {
  struct stat info;
  if (::stat(path.c_str(), &info) == 0 && S_ISDIR(info.st_mode))
    throw SceneError(path + ": is a directory, not a YAML file");
  try {
    return YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw SceneError(path + ": cannot open scene file");
  } catch (const YAML::ParserException& e) {
    throw SceneError(path + ":" + std::to_string(e.mark.line + 1) + ":" +
                     std::to_string(e.mark.column + 1) +
                     ": YAML syntax error: " + loader::syntaxError(e.msg));
  }
}

namespace {

// The items of a list of mappings, each read as a section "key.i" against the schema's keys
// of "key.*".
template <typename Read>
void readItems(const Section& scene, const std::string& key, Read read) {
  const std::vector<const SceneNode*> items = scene.list(key);
  const loader::Children& keys = loader::children(key + ".*");
  for (size_t i = 0; i < items.size(); ++i)
    read(Section(*items[i], key + "." + std::to_string(i), keys));
}

// Drum, teeth, kernels, obstacles and the kernel stream.
void readBodies(const Section& scene, Model* model) {
  loader::readDrum(scene, &model->drum);
  readItems(scene, "teeth",
            [&](const Section& s) { model->teeth.push_back(loader::readTooth(s)); });
  readItems(scene, "kernels",
            [&](const Section& s) { model->kernels.push_back(loader::readKernel(s)); });
  const std::vector<const SceneNode*> obstacles = scene.list("obstacles");
  for (size_t i = 0; i < obstacles.size(); ++i) {
    model->obstacles.push_back(
        loader::readObstacle(*obstacles[i], "obstacles." + std::to_string(i)));
  }
  loader::readStream(scene, model);
}

// Contact laws, gravity, integrator and run settings; the damage section is validated here
// (damageFromYaml returns it).
void readSettings(const Section& scene, Model* model) {
  loader::readContact(scene, model);
  model->gravity_mps2 = scene.vec2("gravity", model->gravity_mps2);
  loader::readIntegrator(scene, &model->integrator);
  model->duration_s = scene.number("duration", model->duration_s);
  model->broadphase_margin_m = scene.number("broadphase_margin", model->broadphase_margin_m);
  model->macro_collision_gap_s = scene.number("macro_collision_gap", model->macro_collision_gap_s);
  model->deflection_validity_fraction =
      scene.number("deflection_validity", model->deflection_validity_fraction);
  loader::readDamage(scene);
}

// The start configuration, then the feed's pool (parked far away), the core's own checks and
// derived quantities.
void finishModel(const Section& scene, Model* model, ToothCache* tooth_cache, FeedSpec* feed) {
  loader::checkInitialOverlaps(*model);
  const FeedSpec feed_spec = loader::readFeed(scene, *model);
  if (feed_spec.capacity > 0 && feed == nullptr) {
    fail("feed",
         "this program does not run a feed (simulate SCENE.yaml runs one; the node and "
         "simulate --batch do not yet)");
  }
  try {
    if (feed_spec.capacity > 0) addFeedPool(feed_spec, model);
    if (feed != nullptr) *feed = feed_spec;
    compileModel(model, tooth_cache);
  } catch (const std::invalid_argument& e) {
    throw SceneError(e.what());
  }
}

// A scene file's tree; refuses an empty file, or one holding a single value.
SceneNode sceneRoot(const std::string& path) {
  SceneNode root = readSceneFile(path);
  if (!root.isMap()) {
    throw SceneError(path + ": expected a mapping of sections at the top level (got " +
                     (root.isNull() || !root.defined() ? std::string("an empty file")
                                                       : loader::showOrDescribe(root)) +
                     ")");
  }
  return root;
}

// The model and damage of a tree with its overrides applied; messages prefixed with the path.
Model modelOfScene(const std::string& path, const SceneNode& root, DamageThresholds* damage,
                   FeedSpec* feed) {
  try {
    Model model = modelFromTree(root, nullptr, feed);
    if (damage != nullptr) *damage = damageFromTree(root);
    return model;
  } catch (const SceneError& e) {
    throw SceneError(path + ": " + e.what());
  }
}

}  // namespace

Model modelFromTree(const SceneNode& root, ToothCache* tooth_cache, FeedSpec* feed) {
  if (!root.isMap()) {
    fail("", "expected a mapping of sections at the top level (got " +
                 loader::showOrDescribe(root) + ")");
  }
  const Section scene(root, "", loader::children(""));
  Model model;
  readBodies(scene, &model);
  readSettings(scene, &model);
  finishModel(scene, &model, tooth_cache, feed);
  return model;
}

DamageThresholds damageFromTree(const SceneNode& root) {
  if (!root.isMap()) return DamageThresholds();
  return loader::readDamage(Section(root, "", loader::children("")));
}

Model modelFromYaml(const YAML::Node& root, ToothCache* tooth_cache, FeedSpec* feed) {
  return modelFromTree(sceneNodeFromYaml(root), tooth_cache, feed);
}

DamageThresholds damageFromYaml(const YAML::Node& root) {
  return damageFromTree(sceneNodeFromYaml(root));
}

Model loadScene(const std::string& path, const std::vector<std::string>& overrides,
                DamageThresholds* damage, FeedSpec* feed) {
  SceneNode root = sceneRoot(path);
  for (const std::string& assignment : overrides) applyOverride(&root, assignment);
  return modelOfScene(path, root, damage, feed);
}

Model loadSceneWithFiles(const std::string& path, const std::vector<std::string>& override_files,
                         const std::vector<std::string>& overrides, DamageThresholds* damage,
                         FeedSpec* feed) {
  std::vector<loader::OverrideFile> files;
  for (const std::string& file : override_files) files.push_back(loader::readOverrideFile(file));
  SceneNode root = sceneRoot(path);
  for (loader::OverrideFile& file : files) loader::applyOverrideEntries(&root, std::move(file));
  for (const std::string& assignment : overrides) applyOverride(&root, assignment);
  return modelOfScene(path, root, damage, feed);
}

}  // namespace threshing_sim
