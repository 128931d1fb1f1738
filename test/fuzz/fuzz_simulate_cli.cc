// libFuzzer target: simulate's command line. The input is split at NUL bytes or newlines into
// arguments; the first selects a scene of config/ (by its first byte), and "--duration 1e-4
// --quiet" is appended so that every run is short. Arguments holding '/' or ".." are dropped,
// so that output files stay in the current (scratch) directory. The exit status must be 0, 1
// or 2 (simulate's documented meanings); a crash, sanitizer report or hang is a finding.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

int simulate_main(int argc, char** argv);

namespace {
const char* const kScenes[] = {
    "config/default_scene.yaml",
    "config/scenes/single_strike.yaml",
    "config/scenes/knead.yaml",
    "config/hard/01_zeno.yaml",
    "config/hard/04_simultaneous.yaml",
    "config/hard/08_wedged.yaml",
    "config/bench/single_strike_rigid.yaml",
};
}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Scenes are read relative to the repository (FUZZ_ROOT); outputs go to a scratch directory.
  const char* root = std::getenv("FUZZ_ROOT");
  static std::string scratch = "/tmp/fuzz_simulate_cli." + std::to_string(getpid());
  std::system(("mkdir -p " + scratch).c_str());
  if (root != nullptr) setenv("FUZZ_SCENES", root, 1);
  if (chdir(scratch.c_str()) != 0) std::abort();
  std::freopen("/dev/null", "w", stdout);
  // "--batch -" and "--check-batch -" read standard input: give them an empty one, never a
  // terminal or an open pipe that would block the fuzzer.
  std::freopen("/dev/null", "r", stdin);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const char* root = std::getenv("FUZZ_SCENES");
  std::vector<std::string> args = {"simulate",
                                   std::string(root ? root : ".") + "/" +
                                       kScenes[data[0] % (sizeof(kScenes) / sizeof(*kScenes))]};
  std::string current;
  for (std::size_t i = 1; i <= size; ++i) {
    if (i == size || data[i] == 0 || data[i] == '\n') {
      if (current.find('/') == std::string::npos && current.find("..") == std::string::npos)
        args.push_back(current);
      current.clear();
    } else {
      current += static_cast<char>(data[i]);
    }
  }
  for (const char* a : {"--duration", "1e-4", "--quiet"}) args.push_back(a);
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  const int rc = simulate_main(static_cast<int>(args.size()), argv.data());
  if (rc < 0 || rc > 2) std::abort();
  return 0;
}
