#pragma once
// Heap allocations per thread, for the loops that must not allocate (the
// 1 kHz haptic tick, haptics/haptic_loop.h): alloc_counter.cpp replaces the
// global operator new and delete (every form) of any program that links it,
// counting each allocation in a thread_local before handing it to malloc.
// malloc called directly (C libraries) is not counted; our own code
// allocates through new.
#include <cstdint>

namespace incise {

// Allocations (operator new, any form) the calling thread has made so far.
std::uint64_t thread_allocations();

}  // namespace incise
