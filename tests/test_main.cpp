// GoogleTest main with the two knobs of the randomized property tests:
//   dtis_tests --count=N --seed=S [gtest flags]
// The seed is printed so that any failure can be replayed. Every file a test writes goes into one
// folder of this run's own (Scratch), removed at the end, so that two runs never collide.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "test_support.hpp"

namespace dtis::test {
long g_count = 200;
unsigned long g_seed = 1;
std::string g_scratch;

std::string Scratch(const std::string& name) { return g_scratch + "/" + name; }
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
  std::string dir = ::testing::TempDir();
  dir.append("dtis_tests_XXXXXX");
  if (mkdtemp(dir.data()) == nullptr) {
    std::perror("dtis_tests: cannot create a scratch folder");
    return 1;
  }
  dtis::test::g_scratch = dir;
  const int rc = RUN_ALL_TESTS();
  std::error_code ignored;
  std::filesystem::remove_all(dir, ignored);
  return rc;
}
