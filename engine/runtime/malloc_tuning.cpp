#include "engine/runtime/malloc_tuning.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace incise {

bool tune_malloc_for_frames() {
#if defined(__GLIBC__)
  // 32 MB is the largest mmap threshold glibc accepts on 64-bit (HEAP_MAX_SIZE / 2).
  const bool ok = mallopt(M_MMAP_THRESHOLD, 32 << 20) == 1;
  return mallopt(M_TRIM_THRESHOLD, 512 << 20) == 1 && ok;
#else
  return false;
#endif
}

}  // namespace incise
