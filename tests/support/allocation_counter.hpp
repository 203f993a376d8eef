#pragma once
// Counting every allocation of a test program: linking allocation_counter.cpp into a program replaces its
// global operators new and delete (on top of malloc and free), so that a test can check that a piece of
// code allocates nothing. Only for programs of their own, which must not meet libraries that allocate
// through another allocator (the sanitizer build's, in the scene loader's).

namespace volpar::test {

/// Allocations the program has made so far, on any thread (through operator new, or blocks of the
/// large-page pool, engine/core/large_pages.hpp).
[[nodiscard]] long allocationCount();

}  // namespace volpar::test
