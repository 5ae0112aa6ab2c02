#pragma once
// Function multi-versioning for the hot loops: GCC builds a marked function once per listed
// target and picks one at load time from the CPU's features, so the binaries stay portable
// x86-64 and still use the wider vectors where the machine has them. x86-64 GCC only; elsewhere
// the one portable build. Functions a clone calls but does not inline run their own (portable)
// build: mark those too, or keep them inline.
//
// A clone whose target has FMA fuses multiplies and adds wherever it can, unless its source is
// compiled with -ffp-contract=off (the simulator's renderer is: its frames must be the same
// bits on every machine).

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
/// AVX2 (8 float lanes, native 32-bit multiply) and the portable build.
#define HQ_CLONES_AVX2 [[gnu::target_clones("avx2", "default")]]
/// AVX-512 (x86-64-v4: native 64-bit multiply), AVX2 and the portable build.
#define HQ_CLONES_AVX512 [[gnu::target_clones("arch=x86-64-v4", "avx2", "default")]]
/// x86-64-v3 (AVX2 with FMA) and the portable build.
#define HQ_CLONES_X86_64_V3 [[gnu::target_clones("arch=x86-64-v3", "default")]]
#else
#define HQ_CLONES_AVX2
#define HQ_CLONES_AVX512
#define HQ_CLONES_X86_64_V3
#endif
