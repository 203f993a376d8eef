#pragma once
// --quick for the Google Benchmark programs (collision_bench, narrow_phase_bench): their checks, then every
// benchmark once, as the tests run them.

#include <cstdio>
#include <string_view>

namespace volpar::bench {

/// Takes --quick out of argv, leaving the rest for Google Benchmark (whose --help lists its own options; this
/// prints `program`'s line first); whether --quick was given.
inline bool takeQuickFlag(int& argc, char** argv, const char* program) {
  bool quick = false;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--quick") {
      quick = true;
      continue;
    }
    if (arg == "--help")
      std::printf("%s [--quick] [Google Benchmark options]\n"
                  "  --quick: the checks, then every benchmark once (one iteration)\n\n",
                  program);
    argv[kept++] = argv[i];
  }
  argc = kept;
  return quick;
}

}  // namespace volpar::bench
