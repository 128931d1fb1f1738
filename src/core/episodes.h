// Episodes and events (episodes.cc): the bookkeeping both integrators share. Private to
// src/core.
#pragma once

#include "contact/narrow_phase.h"
#include "contact/pair_table.h"
#include "threshing_sim/core/data.h"
#include "threshing_sim/core/model.h"

namespace threshing_sim {
struct Workspace;
namespace internal {

// Tracks the largest tip deflection over L and warns once when it leaves the model's range.
void checkToothDeflection(const Model& m, Data* d);
// Records peak force statistics for one contact at time t.
void recordForce(const Model& m, Data* d, const ContactGeom& g, double fn, double ft, double t);
// Opens / closes contact episodes and emits ContactEvents.
void beginEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                  double energy_net);
void endEpisode(const Model& m, Data* d, PairMemory* mem, const ContactGeom& g, double t,
                double energy_net);
void emitTransition(Data* d, const PairId& pair, ContactState from, ContactState to, double t,
                    const ContactGeom& g);
// Fills data.contacts from the current geoms and memory.
void publishContacts(Data* d, Workspace* ws);
// Detaches pedicels whose force passed the threshold.
void updatePedicels(const Model& m, Data* d);

}  // namespace internal
}  // namespace threshing_sim
