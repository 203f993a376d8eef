#pragma once
// What the processor the program runs on can do, for code compiled for more than the build's baseline and
// chosen when the program runs (the contact solver's eight lanes, the rigid particles' four).

namespace volpar {

/// Whether the processor has AVX (always false off x86-64). Asked once, then remembered.
[[nodiscard]] bool processorHasAvx();

}  // namespace volpar
