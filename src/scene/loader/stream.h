// The kernel stream generator (scene section `stream`) and the continuous feed's reader
// (section `feed`, core/feed.h).
#pragma once

#include <string>

#include "section.h"
#include "threshing_sim/core/feed.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
namespace loader {

// [lo, hi] with 0 < lo <= hi.
Vec2 positiveRange(const Section& s, const std::string& key, const Vec2& fallback);

// Appends the stream's kernels (none when the scene has no stream); refuses a stream the scene
// cannot hold.
void readStream(const Section& scene, Model* model);

// The feed of the scene (capacity 0 when it has none); refuses a feed the scene cannot run.
FeedSpec readFeed(const Section& scene, const Model& model);

}  // namespace loader
}  // namespace threshing_sim
