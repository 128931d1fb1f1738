// The hard-case suite over both integrators (test_hard_cases: the scheme chosen by
// testutil::schemeOverride; test_hard_cases_global: the global scheme). The tests are in one
// file per property family beside this one; fixture.h holds what they share.
#include "fixture.h"

namespace threshing_sim {
namespace hard_cases {

INSTANTIATE_TEST_SUITE_P(HardCases, HardCase, ::testing::Values(kED, kTS), paramName);

}  // namespace hard_cases
}  // namespace threshing_sim
