// simulate: the headless command-line simulator.
//
// Loads a scene (with --set overrides), runs it to its duration in chunks of simulation time,
// and writes a JSON summary, a state trace, an event log, per-kernel outcomes and contact force
// samples on request (run.cc). Exit status: 0 on success, 1 when the integrator failed, 2 for
// a bad scene or command line. --check only loads and validates the scene (with its
// overrides) and prints it resolved; --check-batch does that for every line of a file
// (check.cc; scripts/sweep validates a whole sweep in one process); --batch runs every line
// of a file in this process, one JSON line of results per run (batch.cc; scripts/sweep's
// runner).
#include <cstdio>
#include <iostream>

#include "app.h"
#include "threshing_sim/core/constants.h"
#include "threshing_sim/core/simulator.h"
#include "threshing_sim/scene/scene_loader.h"

namespace threshing_sim {
namespace {

// Revolutions per minute in one rad/s.
constexpr double kRpmPerRadps = 30.0 / kPi;

// ---------------------------------------------------------------------------------------------
// --modes: natural frequencies of each tooth at rest and at the scene's drum speed.

void printFrequencies(const VecX& frequencies_Hz) {
  for (Eigen::Index j = 0; j < frequencies_Hz.size(); ++j) {
    std::printf("%s%.6g", j ? ", " : " ", frequencies_Hz[j]);
  }
  std::printf(" Hz\n");
}

void printModes(const Model& model) {
  const double omega_radps = model.drum.initial_speed_radps;
  for (size_t k = 0; k < model.teeth.size(); ++k) {
    const ToothModel& tooth = model.teeth[k];
    std::printf("tooth %zu: L %.6g m, d %.6g m, E %.6g Pa, rho %.6g kg/m^3, %d modes\n", k,
                tooth.length_m, tooth.diameter_m, tooth.youngs_modulus_Pa, tooth.density_kgpm3,
                tooth.n_modes);
    if (tooth.modes_auto) {
      std::printf("  modes: auto (Hertz contact time estimate %.3g us, see README)\n",
                  tooth.contact_time_s * 1e6);
    }
    if (tooth.residual_modes > tooth.n_modes) {
      std::printf(
          "  static correction from mode %d on: the truncated modes below it are slower than "
          "the contact (Hertz time %.3g us) and left out (docs/model.md 9b; modes: auto or more "
          "modes keeps them)\n",
          tooth.residual_modes + 1, tooth.residual_contact_time_s * 1e6);
    }
    if (tooth.n_modes == 0) {
      std::printf("  rigid tooth: no bending modes\n");
      continue;
    }
    std::printf("  at rest:");
    printFrequencies(toothFrequenciesHz(tooth, 0.0));
    if (tooth.beam_model == ToothBeamModel::kLargeDeflection) {
      std::printf("  large-deflection rod, %d shape functions, linearised at rest:", tooth.n_modes);
      printFrequencies(tooth.ld_frequencies_Hz);
    }
    std::printf("  at %.6g rad/s (%.6g rpm):", omega_radps, omega_radps * kRpmPerRadps);
    printFrequencies(toothFrequenciesHz(tooth, omega_radps));
  }
}

// The mode the options select; returns the exit status.
int dispatch(const app::Options& options) {
  if (options.help) {
    std::cout << app::kUsage << "\n";
    return 0;
  }
  if (options.print_schema) {
    std::cout << sceneSchemaTable();
    return 0;
  }
  if (!options.check_batch_path.empty())
    return app::checkBatch(options.check_batch_path, options.resolve_only);
  if (!options.batch_path.empty()) return app::runBatch(options.batch_path);
  if (options.check) {
    std::cout << app::resolvedScene(options) << "\n";
    return 0;
  }
  DamageThresholds damage;
  FeedSpec feed;
  const Model model =
      loadSceneWithFiles(options.scene_path, options.set_files, options.overrides, &damage, &feed);
  if (options.modes) {
    printModes(model);
    return 0;
  }
  if (feed.capacity > 0) {
    if (!options.trace_path.empty() || !options.events_path.empty() || !options.forces_path.empty())
      throw app::OptionError("--trace, --events and --forces are not written for a feed scene");
    return app::runFeedToFiles(model, feed, damage, options);
  }
  if (!options.feed_series_path.empty())
    throw app::OptionError("--feed-series needs a scene with a feed section");
  return app::runToFiles(model, damage, options);
}

}  // namespace
}  // namespace threshing_sim

int main(int argc, char** argv) {
  using namespace threshing_sim;
  try {
    return dispatch(app::parseOptions(argc, argv));
  } catch (const app::UsageError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n" << app::kUsage << "\n";
    return 2;
  } catch (const app::OptionError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 2;
  } catch (const SceneError& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "simulate: error: " << e.what() << "\n";
    return 1;
  }
}
