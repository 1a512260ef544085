// GoogleTest main with the two knobs of the randomized property tests:
//   dtis_tests --count=N --seed=S [gtest flags]
// The seed is printed so that any failure can be replayed.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "test_support.hpp"

namespace dtis::test {
long g_count = 200;
unsigned long g_seed = 1;
}  // namespace dtis::test

int main(int argc, char** argv) {
  ::testing::InitGoogleTest(&argc, argv);
  if (const char* env = std::getenv("DTIS_TEST_COUNT")) dtis::test::g_count = std::atol(env);
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--count=", 0) == 0) dtis::test::g_count = std::stol(arg.substr(8));
    if (arg.rfind("--seed=", 0) == 0) dtis::test::g_seed = std::stoul(arg.substr(7));
  }
  std::printf("randomized tests: --count=%ld --seed=%lu\n", dtis::test::g_count,
              dtis::test::g_seed);
  return RUN_ALL_TESTS();
}
