#pragma once
// 64-bit FNV-1a over bytes: the State's field hashes (engine/dynamics/state.h),
// the replay file's chunk checksums and mesh hash (engine/runtime/replay_file.h).
// Not cryptographic: it detects changes and corruption, not tampering.
#include <cstddef>
#include <cstdint>

namespace incise {

inline constexpr std::uint64_t kFnvOffset = 1469598103934665603ULL, kFnvPrime = 1099511628211ULL;

inline std::uint64_t fnv1a(const void* data, size_t bytes, std::uint64_t h = kFnvOffset) {
  const unsigned char* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * kFnvPrime;
  return h;
}

}  // namespace incise
