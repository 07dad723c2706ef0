/* Floating point as the C sources are written: a * b + c is a product rounded, then a sum
 * rounded, never one fused multiply-add, whatever the compiler, its language mode, -O
 * level or -march. So a native FMU rebuilt from its sources/ with an importer's flags
 * (e.g. -O3 -march=native on a CPU with FMA) gives the shipped binary's results bit for
 * bit (tests/integration/test_source_build.py). Every C file of the models, their glue,
 * the native back end and the layer (its directional derivatives' sums) includes this
 * first, before any other header.
 *
 * - clang (and zig cc): the C99 pragma STDC FP_CONTRACT OFF. It wins over clang's default
 *   (-ffp-contract=on) and over -ffp-contract=on or fast-honor-pragmas, not over an
 *   explicit -ffp-contract=fast, which "fuses across statements disregarding pragmas"
 *   (clang's manual): do not pass that flag.
 * - gcc (and mingw-w64): gcc does not implement the STDC pragma; it takes
 *   #pragma GCC optimize("fp-contract=off") for every function defined after it, also
 *   over -ffp-contract=fast on the command line.
 * - MSVC: #pragma fp_contract(off) (documented; not tested here).
 * -ffast-math changes more than contraction (reassociation, no NaN or infinity): refused.
 */
#ifndef GLIDER_FP_H
#define GLIDER_FP_H

#ifdef __FAST_MATH__
#error "glider-cosim's C sources need IEEE arithmetic: build them without -ffast-math"
#endif

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#elif defined(_MSC_VER)
#pragma fp_contract(off)
#endif

#endif
