// Time stepping's shared context (folder-private; docs/architecture.md lists the stages). The
// method is summarised at the top of step.cc; timeSteppingStep there calls the stages in order,
// each in the file named below, with the state carried in a TsStep.
#pragma once

#include <cstddef>

#include "../internal.h"

namespace threshing_sim {
namespace internal {
namespace time_stepping {

// What one time step carries from stage to stage.
struct TsStep {
  const Model& m;
  Data* d;
  Workspace& ws;
  double h;                         // step length [s]
  Drive mid{}, end{};               // the drum at the step's midpoint and end
  double energy_before = 0.0;       // mechanical energy at the start, when known [J]
  double H_before = 0.0;            // the teeth's angular momentum at the start [kg m^2/s]
  bool have_energy_before = false;  // energy_before is the start's (else computed on need)
  double drive_work_before_J = 0;   // drive work at the start [J]
  double energy_net_before = 0;     // energy minus drive work at the start, when needed [J]
  double H_after = 0.0;             // angular momentum at the end [kg m^2/s]
  double energy_after = 0.0;        // mechanical energy at the end, once computed [J]
  bool have_energy_after = false;   // energy_after is computed
  bool solved = true;               // every contact problem of the step was solved

  PairMemory& memoryOf(size_t c) const { return ws.memory.entry(ws.ts.candidate_memory[c]).second; }
  // Energy minus drive work at the step end, the energy computed on first use.
  double energyNetAfter() {
    if (!have_energy_after) energy_after = energyOf(m, *d, d->z, d->u, d->omega_radps);
    have_energy_after = true;
    return energy_after - d->stats.drive_work_J;
  }
};

// --- the step's stages, in the order timeSteppingStep (step.cc) calls them -----------------
void beginStep(TsStep* s);            // 1, step.cc
void detectContacts(TsStep* s);       // 2, detect.cc
void freeVelocity(TsStep* s);         // 3, contact_problem.cc
void assembleContactRows(TsStep* s);  // 4, contact_problem.cc
void contactTargets(TsStep* s);       // 5, contact_problem.cc
void solveImpulses(TsStep* s);        // 6, contact_problem.cc
void applyImpulses(TsStep* s);        // 7, impulses.cc
void advanceClock(TsStep* s);         // 8, step.cc
void updateContactStates(TsStep* s);  // 9, contact_states.cc
void finishStep(TsStep* s);           // 10, step.cc

}  // namespace time_stepping
}  // namespace internal
}  // namespace threshing_sim
