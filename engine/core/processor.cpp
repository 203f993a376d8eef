#include "volpar/engine/core/processor.hpp"

namespace volpar {

bool processorHasAvx() {
#if defined(__x86_64__) && defined(__GNUC__)
  static const bool available = [] {
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx") != 0;
  }();
  return available;
#else
  return false;
#endif
}

}  // namespace volpar
