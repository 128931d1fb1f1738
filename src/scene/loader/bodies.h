// The body and settings readers: each scene section into its part of the Model.
#pragma once

#include <string>

#include "section.h"
#include "threshing_sim/core/model.h"
#include "threshing_sim/scene/outcomes.h"

namespace threshing_sim {
namespace loader {

void readDrum(const Section& scene, DrumModel* drum);
ToothModel readTooth(const Section& s);
// The attachment point must lie inside the kernel.
PedicelModel readPedicel(const Section& s, const KernelModel& kernel);
KernelModel readKernel(const Section& s);
// The type decides which keys are allowed; geometry keys are required.
ObstacleModel readObstacle(const SceneNode& node, const std::string& path);
void readContact(const Section& scene, Model* model);
void readIntegrator(const Section& scene, IntegratorParams* integrator);
// The outcome settings (section `damage`).
DamageThresholds readDamage(const Section& scene);

// Every kernel against the earlier kernels, the teeth and the obstacles (the core's test,
// O(n) ellipse tests through a grid); refuses the first overlap.
void checkInitialOverlaps(const Model& model);

}  // namespace loader
}  // namespace threshing_sim
