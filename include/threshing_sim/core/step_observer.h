// threshing_sim core: an observer of the island scheme's integrator steps (integrator.islands).
//
// Under the island scheme one scheduling window (up to max_step) is one advance of the global
// state, but each island inside it takes its own accepted steps. A caller that wants to see
// those steps (the ROS node's strike histories and frames) sets Data::observer for an advance;
// the core then calls islandStep() after every accepted step of every island (in island order,
// each island's steps in time order), before the window ends. Observing changes nothing: the
// steps, the state and the statistics are bit for bit those of a run without the observer. The
// global scheme does not call it (each of its steps is an advance a caller can take alone).
#pragma once

#include <vector>

#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {

// One accepted step of one island, in global numbers. Valid only during the call.
class IslandStep {
 public:
  double t_s = 0;                             // the step's end, at most the window's end [s]
  double theta_rad = 0;                       // drum angle at the step's end [rad]
  double omega_radps = 0;                     // drum speed at the step's end [rad/s]
  const std::vector<int>* teeth = nullptr;    // the island's teeth (global indices, ascending)
  const std::vector<int>* kernels = nullptr;  // the island's kernels (global indices, ascending)
  // The island's contacts after the step (as Data::contacts: pairs in global numbers).
  const std::vector<ContactInfo>* contacts = nullptr;
  // The island's events since the window began, up to this step (global pair numbers).
  const std::vector<ContactEvent>* events = nullptr;

  // Writes the island's bodies' positions and velocities at the step's end into z and u, which
  // have the full model's layout (model.n_dof); other entries are left as they are.
  void writeState(const Model& model, VecX* z, VecX* u) const;

  const Model* island_model = nullptr;  // the island's sub-model (local numbering)
  const VecX* island_z = nullptr;       // the island's positions (local layout)
  const VecX* island_u = nullptr;       // the island's velocities (local layout)
};

class StepObserver {
 public:
  virtual ~StepObserver() = default;
  // After every accepted integrator step of an island (model: the full model).
  virtual void islandStep(const Model& model, const IslandStep& step) = 0;
};

}  // namespace threshing_sim
