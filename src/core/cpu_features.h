// The instruction-set level of the CPU running the process, and the one way every CPU kernel of
// the package is chosen from it (internal; not installed). The package is built for the baseline
// of its target (no -march flags); faster kernels are compiled with per-function target attributes,
// and each kernel family offers `kernelFor(CpuLevel)` (its own kernel of that level, or nullptr)
// from which selectKernel picks the highest level the CPU runs. Header-only, plain C++: the voter
// (src/voter) and the estimator's passes use it outside the core library too.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

namespace visual_gyro {
namespace cpu {

/// Instruction-set levels, ordered: each implies every level before it. A CPU's level is the
/// highest whose features it has all of (with the operating system saving the registers they
/// use); kernels of a level use no feature beyond it.
enum class CpuLevel : int {
  kPortable = 0,  ///< plain C++ (any CPU); on x86-64 the reference the vector kernels are tested against
  kSse2,          ///< SSE2: the x86-64 baseline, every x86-64 CPU (off x86-64 no CPU has this level)
  kPopcnt,        ///< + POPCNT (x86-64 since Nehalem and K10)
  kAvx,           ///< + AVX: 256-bit float lanes (Sandy Bridge, Bulldozer)
  kAvx2,          ///< + AVX2: 256-bit integer lanes and gathers (Haswell, Zen)
  kAvx512Bw,      ///< + AVX-512 F, VL and BW: 512-bit lanes of bytes and words (Skylake-SP)
  /// + AVX-512 VBMI (byte permutes across a register) and VPOPCNTDQ (population count of lanes):
  /// Ice Lake, Zen 4 and later, which have both (Cannon Lake, with VBMI only, counts as kAvx512Bw)
  kAvx512Vbmi,
};

/// Every level, lowest first.
constexpr CpuLevel kAllLevels[] = {CpuLevel::kPortable, CpuLevel::kSse2,     CpuLevel::kPopcnt,     CpuLevel::kAvx,
                                   CpuLevel::kAvx2,     CpuLevel::kAvx512Bw, CpuLevel::kAvx512Vbmi};

/// The environment variable that lowers the level kernels are chosen for (benchmarks, tests):
/// one of the levelName names; read once, when the first kernel is chosen.
constexpr const char* kLevelVariable = "VISUAL_GYRO_CPU_LEVEL";

/// The level's name: portable, sse2, popcnt, avx, avx2, avx512_bw, avx512_vbmi.
inline const char* levelName(CpuLevel level) {
  static const char* const kNames[] = {"portable", "sse2", "popcnt", "avx", "avx2", "avx512_bw", "avx512_vbmi"};
  return kNames[static_cast<int>(level)];
}

/// The level named `name` (levelName's names); false when there is none.
inline bool parseLevel(const std::string& name, CpuLevel* level) {
  for (CpuLevel l : kAllLevels)
    if (name == levelName(l)) {
      *level = l;
      return true;
    }
  return false;
}

/// The highest level of the CPU running the process (kPortable off x86-64), detected once.
inline CpuLevel detectedLevel() {
  static const CpuLevel level = [] {
#if defined(__x86_64__) && defined(__GNUC__)
    // __builtin_cpu_supports reports AVX and AVX-512 only where the operating system saves their
    // registers (XCR0), so a feature reported here can be used.
    __builtin_cpu_init();
    if (!__builtin_cpu_supports("popcnt")) return CpuLevel::kSse2;
    if (!__builtin_cpu_supports("avx")) return CpuLevel::kPopcnt;
    if (!__builtin_cpu_supports("avx2")) return CpuLevel::kAvx;
    if (!(__builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
          __builtin_cpu_supports("avx512bw")))
      return CpuLevel::kAvx2;
    if (!(__builtin_cpu_supports("avx512vbmi") && __builtin_cpu_supports("avx512vpopcntdq")))
      return CpuLevel::kAvx512Bw;
    return CpuLevel::kAvx512Vbmi;
#else
    return CpuLevel::kPortable;
#endif
  }();
  return level;
}

/// The level a request may force: `requested`, but never above what the CPU has.
inline CpuLevel clampLevel(CpuLevel requested, CpuLevel detected) {
  return static_cast<int>(requested) < static_cast<int>(detected) ? requested : detected;
}

/// The level kernels are chosen for: detectedLevel(), or the lower level named by the environment
/// variable kLevelVariable (clamped to what the CPU has). Decided once; an unknown name or a level
/// above the CPU's is reported on stderr once.
inline CpuLevel activeLevel() {
  static const CpuLevel level = [] {
    const CpuLevel detected = detectedLevel();
    const char* text = std::getenv(kLevelVariable);
    if (text == nullptr || *text == '\0') return detected;
    CpuLevel requested;
    if (!parseLevel(text, &requested)) {
      std::fprintf(stderr, "visual_gyro: %s=%s is no level (portable, sse2, popcnt, avx, avx2, avx512_bw, "
                   "avx512_vbmi); using the CPU's, %s\n", kLevelVariable, text, levelName(detected));
      return detected;
    }
    if (clampLevel(requested, detected) != requested)
      std::fprintf(stderr, "visual_gyro: %s=%s is above this CPU's level; using %s\n", kLevelVariable, text,
                   levelName(detected));
    return clampLevel(requested, detected);
  }();
  return level;
}

/// True when kernels of `level` may run: the CPU has it and no lower level is forced.
inline bool runs(CpuLevel level) { return static_cast<int>(level) <= static_cast<int>(activeLevel()); }

/// The one selector: the kernel of the highest level from `highest` down to `lowest` for which
/// `kernelFor` gives one (kernelFor returns nullptr for levels without a kernel of their own and
/// for levels that do not run), or nullptr when none does.
template <typename Kernel>
Kernel selectKernel(Kernel (*kernelFor)(CpuLevel), CpuLevel highest, CpuLevel lowest = CpuLevel::kPortable) {
  for (int l = static_cast<int>(highest); l >= static_cast<int>(lowest); --l)
    if (const Kernel kernel = kernelFor(static_cast<CpuLevel>(l))) return kernel;
  return nullptr;
}

}  // namespace cpu
}  // namespace visual_gyro
