// Strata runtime (private): compiling hot loops for several x86-64 levels.
//
// STRATA_KERNEL_CLONES compiles a function twice on x86-64 Linux with GCC,
// for AVX2 and for the baseline, and the loader picks one (ifunc).  Neither
// enables FMA, so both round every operation the same way: results are
// bit-identical on any CPU, and AVX2 doubles the vector width.  Helpers a
// cloned kernel calls are STRATA_KERNEL_INLINE, so each clone inlines them
// compiled for its own target.
#pragma once

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && defined(__linux__)
#define STRATA_KERNEL_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define STRATA_KERNEL_CLONES
#endif
#define STRATA_KERNEL_INLINE __attribute__((always_inline)) inline
