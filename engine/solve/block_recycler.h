#pragma once
// Recycled large blocks for CHOLMOD's allocations.
//
// The background factorization analyzes every new pattern of an incision and
// CHOLMOD then allocates a fresh numeric factor (25-30 MB at 10k DOF). glibc
// serves a block that size from new pages, so each factorization took about
// 6,000 page faults, each a kernel entry plus zeroing 4 KB: 51,000 of the
// 208,000 faults of a paced 100-frame incision run (perf), on the core the
// job shares with everything else. Blocks of at least kMinBlock freed by
// CHOLMOD are kept (up to kMaxKept of them, kMaxBytes in all) and handed to
// the next request they fit, so a factor of the same size or a little larger
// (the carried ordering grows by a few percent per cut) reuses pages that are
// already mapped.
//
// install_cholmod_block_recycler() points SuiteSparse_config's malloc,
// calloc, realloc and free at these functions. It must run before the first
// CHOLMOD allocation of the process (CholmodSolver's constructor calls it),
// since a block has to be freed by the allocator that made it; a program that
// uses CHOLMOD before creating a CholmodSolver keeps glibc's functions (the
// recycler then stays off). Under AddressSanitizer it is never installed, so
// use-after-free inside CHOLMOD stays detectable.
#include <cstddef>

namespace incise {

// Whether CHOLMOD's allocations go through the recycler (false: not installed,
// or installed too late, or a sanitizer build).
bool install_cholmod_block_recycler();

struct RecyclerStats {
  long reused = 0;     // large requests served from a kept block
  long grown = 0;      // large requests served by growing a smaller kept block (realloc)
  long fresh = 0;      // large requests served by malloc
  size_t kept_bytes = 0;
};
RecyclerStats cholmod_block_recycler_stats();

namespace recycler {
void* allocate(size_t size);
void* allocate_zeroed(size_t count, size_t size);
void* reallocate(void* p, size_t size);
void release(void* p);
}  // namespace recycler

}  // namespace incise
