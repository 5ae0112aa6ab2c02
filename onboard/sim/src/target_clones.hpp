#pragma once
// Function multi-versioning for the renderer's hot loops: GCC builds the function once per
// listed target and picks one at load time from the CPU's features. x86-64 GCC only; elsewhere
// the one portable build. The sources using it are compiled with -ffp-contract=off, so a clone
// whose target has FMA computes the same bits as the portable build.

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
/// AVX2 (8 float lanes, native 32-bit multiply) and the portable build.
#define HQ_SIM_CLONES_AVX2 [[gnu::target_clones("avx2", "default")]]
/// AVX-512 (x86-64-v4: native 64-bit multiply), AVX2 and the portable build.
#define HQ_SIM_CLONES_AVX512 [[gnu::target_clones("arch=x86-64-v4", "avx2", "default")]]
#else
#define HQ_SIM_CLONES_AVX2
#define HQ_SIM_CLONES_AVX512
#endif
