// What the CPU running the process offers, for the kernels chosen at run time (internal to the
// core library; not installed). The package is built for the baseline of its target (no -march
// flags); faster kernels are compiled with per-function target attributes and picked with these.
#pragma once

namespace visual_gyro {
namespace cpu_features {

/// True when the CPU has the popcnt instruction (x86-64 only; false elsewhere, where the
/// baseline's own population count serves).
inline bool hasPopcnt() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("popcnt");
#else
  return false;
#endif
}

/// True when the CPU has AVX2 (x86-64 only; false elsewhere).
inline bool hasAvx2() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx2");
#else
  return false;
#endif
}

/// True when the CPU has AVX-512 F and VL with VPOPCNTDQ (population count of 64-bit lanes), and
/// the operating system saves the 512-bit registers (x86-64 only; false elsewhere).
inline bool hasAvx512Popcnt() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
         __builtin_cpu_supports("avx512vpopcntdq");
#else
  return false;
#endif
}

/// True when the CPU has AVX-512 F and BW (512-bit integer lanes of bytes and words), and the
/// operating system saves the 512-bit registers (x86-64 only; false elsewhere).
inline bool hasAvx512Bw() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw");
#else
  return false;
#endif
}

/// True when the CPU has AVX-512 F, BW and VBMI (byte permutes across a 512-bit register), and
/// the operating system saves the 512-bit registers (x86-64 only; false elsewhere).
inline bool hasAvx512Vbmi() {
#if defined(__x86_64__) && defined(__GNUC__)
  __builtin_cpu_init();
  return __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
         __builtin_cpu_supports("avx512vbmi");
#else
  return false;
#endif
}

}  // namespace cpu_features
}  // namespace visual_gyro
