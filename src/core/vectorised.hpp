// CLOTH_SIM_VECTORISED: a loop function built twice, for x86-64-v3 (AVX2,
// FMA) and the baseline, the loader picking one for the CPU. Debian builds
// for the baseline (SSE2), where the spring sweeps run 1.5x slower.
#pragma once

#if defined(__GNUC__) && defined(__x86_64__)
#define CLOTH_SIM_VECTORISED __attribute__((target_clones("arch=x86-64-v3", "default")))
#else
#define CLOTH_SIM_VECTORISED
#endif
