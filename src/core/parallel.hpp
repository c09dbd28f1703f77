// solver.threads: how a loop over nodes or spring slots is split among
// threads (OpenMP). Each thread takes one contiguous range, the same ranges
// every time, so a run is deterministic for a given thread count; the
// products and sweeps compute each entry as one thread would (bit-identical),
// only the multigrid smoother's parts change the arithmetic (multigrid.hpp).
#pragma once

#include <algorithm>

#ifdef _OPENMP
#include <omp.h>
#endif

namespace cloth_sim {
namespace parallel {

// Inside a `#pragma omp parallel` region: this thread's number and the team's
// size. Built without OpenMP (the sanitized clang build) the pragmas are
// ignored and a region runs once, as thread 0 of 1, over every part.
#ifdef _OPENMP
inline int thread() { return omp_get_thread_num(); }
inline int team() { return omp_get_num_threads(); }
#else
inline int thread() { return 0; }
inline int team() { return 1; }
#endif

/// Below this many nodes a loop stays on one thread: a fork and join costs
/// a few microseconds, a sweep over 1000 nodes about as much.
constexpr int kMinNodes = 1024;

/// The threads a loop over `n` entries runs on.
inline int partsFor(int threads, int n) { return n >= kMinNodes ? std::max(threads, 1) : 1; }

/// Entry range [first, last) of part `part` of `parts` over n entries; the
/// cuts fall on multiples of 8, so each part's vector loops start aligned.
inline void range(int part, int parts, int n, int* first, int* last) {
  auto cut = [&](int k) { return k >= parts ? n : std::min(n, (n / parts * k) & ~7); };
  *first = cut(part);
  *last = cut(part + 1);
}

}  // namespace parallel
}  // namespace cloth_sim
