// threshing_sim core, private: Eigen's dense solvers (eigenvalues, LU) for beam.cc and
// large_deflection.cc. GCC 12 at -O2 reports a false -Wmaybe-uninitialized inside Eigen 3.4's
// SelfAdjointEigenSolver unless Eigen is a system include, as it is in the CMake build; the
// guard keeps plain -I builds with -Werror clean as well.
#pragma once

#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic pop
#endif
