// Test runner: Catch2's session, plus the rule that `gpu` tests are reported
// as skipped (exit 77, ctest's SKIP_RETURN_CODE) where no CUDA device exists.
#if __has_include(<catch2/catch_session.hpp>)
#include <catch2/catch_session.hpp>
#else
#define CATCH_CONFIG_RUNNER
#include <catch2/catch.hpp>
#endif

#include <cstdio>
#include <cstring>

#include "sph/solver.h"

int main(int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    if (std::strstr(argv[i], "[gpu]") && !std::strstr(argv[i], "~[gpu]") && !sphray::cuda_available()) {
      std::printf("no CUDA device (or no CUDA backend in this build): gpu tests skipped\n");
      return 77;
    }
  }
  return Catch::Session().run(argc, argv);
}
