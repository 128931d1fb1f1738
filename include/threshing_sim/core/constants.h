// threshing_sim core: constants shared by the core, the scene loader, the programs and the tests.
#pragma once

namespace threshing_sim {

// pi, as the double nearest to it (the same bits as M_PI) [-].
constexpr double kPi = 3.14159265358979323846;

// Largest number of bending modes of a tooth [-] (teeth.*.modes, also its automatic choice): the
// mode shapes are evaluated in a form that stays exact up to this many (beam.cc), and
// fixed-size scratch arrays are sized by it.
constexpr int kMaxModes = 64;

}  // namespace threshing_sim
