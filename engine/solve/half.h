#pragma once
// IEEE 754 binary16 ("half", 11 significant bits, normal range 6.1e-5 ..
// 65504) conversions for the half-precision factor copy (CholmodSolver,
// FactorCopy::Half). The portable versions below are always built (and
// tested against the F16C instructions where the build has them); the
// substitution kernel uses F16C when the compiler targets it.
#include <cmath>
#include <cstdint>
#include <cstring>

namespace incise {

// Exact: every binary16 value is a float.
inline float half_bits_to_float(uint16_t h) {
  const uint32_t sign = static_cast<uint32_t>(h & 0x8000u) << 16;
  const uint32_t exp = (h >> 10) & 0x1fu, mant = h & 0x3ffu;
  uint32_t bits;
  if (exp == 0) {
    const float f = static_cast<float>(mant) * 5.9604644775390625e-8f;  // subnormal: mant * 2^-24
    return sign ? -f : f;
  }
  if (exp == 31) bits = sign | 0x7f800000u | (mant << 13);  // inf, NaN
  else bits = sign | ((exp + 112u) << 23) | (mant << 13);   // rebias 15 -> 127
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

// Round to nearest, ties to even; beyond 65504 (after rounding) -> inf, NaN stays NaN.
inline uint16_t float_to_half_bits(float f) {
  uint32_t x;
  std::memcpy(&x, &f, sizeof x);
  const uint16_t sign = static_cast<uint16_t>((x >> 16) & 0x8000u);
  x &= 0x7fffffffu;
  if (x > 0x7f800000u) return sign | 0x7e00u;  // NaN
  if (x >= 0x477ff000u) return sign | 0x7c00u;  // >= 65520 rounds to inf
  if (x < 0x38800000u) {                        // below 2^-14: subnormal half (or 0)
    float a;
    std::memcpy(&a, &x, sizeof a);
    // a * 2^24 is exact; nearbyint rounds ties to even in the default mode.
    // 1024 encodes the smallest normal, which is what rounding up reaches.
    return sign | static_cast<uint16_t>(std::nearbyint(a * 16777216.0f));
  }
  // Normal: drop 13 mantissa bits with round-to-nearest-even; a carry into the
  // exponent is the correct result.
  return sign | static_cast<uint16_t>((x + 0xfffu + ((x >> 13) & 1u) - 0x38000000u) >> 13);
}

}  // namespace incise
