#pragma once
// glibc malloc settings for a process that steps frames.
//
// By default glibc maps every block above a dynamic threshold (128 KB at
// start) with mmap and unmaps it on free, and returns the top of the heap to
// the system once 128 KB of it are free. A cut rebuild allocates a new Model
// (about 30 MB in blocks of 0.1-4 MB at 10k DOF) on the cut-ahead thread and
// frees the old one, so every cut frame faulted all of those pages in again
// (zeroed by the kernel), on the cores the frame needs. With mmap only above
// 32 MB and trimming only above 512 MB of free heap, the freed blocks are
// reused: a paced 100-frame incision at 10k DOF went from 172,000 to 52,000
// page faults after set-up (with the CHOLMOD block recycler,
// block_recycler.h; docs/benchmarks.md). The cost is that up to 512 MB of
// freed memory stays with the process.
//
// A process setting, so the library never does it by itself: the incise
// program calls it first thing; an application embedding the engine calls it
// (or sets the same through GLIBC_TUNABLES) if it wants the same.
namespace incise {

// Returns false where the C library is not glibc (nothing is changed).
bool tune_malloc_for_frames();

}  // namespace incise
