// CLOTH_SIM_VECTORISED: a loop function built twice, for x86-64-v3 (AVX2,
// FMA) and the baseline, the loader picking one for the CPU. Debian builds
// for the baseline (SSE2), where the spring sweeps run 1.5x slower.
#pragma once

#if defined(__GNUC__) && defined(__x86_64__)
#define CLOTH_SIM_VECTORISED __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define CLOTH_SIM_VECTORISED
#endif

#include <type_traits>

namespace cloth_sim {

/// f(std::integral_constant<int, count>()) for count in 1..kMax (nothing
/// otherwise): a kernel over `count` arrays with the count a constant, so
/// the compiler unrolls it (one dispatch for every such kernel).
template <int kMax, int k = 1, typename F>
inline __attribute__((always_inline)) void withCount(int count, F&& f) {
  if (count == k) {
    f(std::integral_constant<int, k>());
    return;
  }
  if constexpr (k < kMax) withCount<kMax, k + 1>(count, f);
}

}  // namespace cloth_sim
