#pragma once
// DQO_AVX2_CLONE before a function with hot, vectorised loops (dense alignment and its pyramid)
// compiles it twice, for x86-64's baseline (SSE2, what the package is built for) and for AVX2, and
// the loader picks the second where the CPU has it (GCC's target_clones, an ifunc): the loops run
// twice as wide without building the package for one CPU. The arithmetic is the same in both
// (element by element; "avx2" does not enable FMA, so no multiply-add is contracted), so results
// are bit-identical, which the offline tools' determinism relies on. Elsewhere (other
// architectures, other compilers) it is empty.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define DQO_AVX2_CLONE __attribute__((target_clones("avx2", "default")))
#else
#define DQO_AVX2_CLONE
#endif
