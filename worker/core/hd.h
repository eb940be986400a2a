// SPDX-License-Identifier: Apache-2.0
// Host/device qualifiers: per-cell math is written once and compiled for the
// CPU backend (g++) and the CUDA backend (nvcc) from the same source.
#pragma once

#if defined(__CUDACC__)
#define ERG_HD __host__ __device__ __forceinline__
#else
#define ERG_HD inline
#endif

// Fully unroll a short fixed loop (the 8 neighbours) so that the loop
// around it can be vectorised.
#if defined(__CUDACC__)
#define ERG_UNROLL _Pragma("unroll")
#elif defined(__GNUC__) && !defined(__clang__)
#define ERG_UNROLL _Pragma("GCC unroll 8")
#else
#define ERG_UNROLL
#endif

#include <cmath>
#include <cstdint>

namespace erg {

// Branch-free min/max: GCC does not vectorise fminf/fmaxf without
// -ffinite-math-only (NaN rules), so the per-cell math uses these.
template <class T>
ERG_HD T min_of(T a, T b) {
  return a < b ? a : b;
}
template <class T>
ERG_HD T max_of(T a, T b) {
  return a > b ? a : b;
}
template <class T>
ERG_HD T clamp_to(T x, T lo, T hi) {
  return min_of(max_of(x, lo), hi);
}

}  // namespace erg
