// SPDX-License-Identifier: MIT
// Counts heap allocations made through global operator new and malloc (the test binaries replace
// both), so tests can prove that a hot loop allocates nothing after warm-up.
#pragma once

#include <cstdint>

namespace gs::test {

uint64_t allocation_count();  // operator new + malloc/calloc/realloc calls so far, all threads

// Counts allocations in a scope: AllocationScope s; ...; CHECK(s.count() == 0);
class AllocationScope {
 public:
  AllocationScope() : start_(allocation_count()) {}
  uint64_t count() const { return allocation_count() - start_; }

 private:
  uint64_t start_;
};

}  // namespace gs::test
