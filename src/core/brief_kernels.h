// BRIEF's intensity tests for one keypoint (internal to the core library; not installed): the
// kernels of FeatureFrontEnd::describe. Every kernel gives the same bits; which one runs is chosen
// at run time from what the CPU offers.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "cpu_features.h"
#include "visual_gyro/feature_front_end.h"

namespace visual_gyro {
namespace brief_kernels {

/// The pattern (briefPattern()) as byte offsets from the keypoint's pixel in an image of one row
/// step: test i compares the pixels at centre + first[i] and centre + second[i].
struct TestOffsets {
  alignas(32) std::array<int32_t, 256> first;
  alignas(32) std::array<int32_t, 256> second;
};

/// briefPattern()'s offsets for an image whose rows are `step` bytes apart. The caller checks that
/// kBriefHalfPatch rows of `step` fit 32 bits.
TestOffsets testOffsets(std::ptrdiff_t step);

/// The descriptor of the keypoint whose pixel is at `centre` in an image of row step `step`
/// [bytes], `offsets` being testOffsets(step): bit i (word i / 64, bit i % 64) is set when
/// centre[offsets.first[i]] < centre[offsets.second[i]]. Reads the (2 kBriefHalfPatch + 1)^2
/// patch around `centre`; vector kernels may also read up to kBytesPastPatch bytes after any
/// pixel of it, so the caller checks those lie inside the image's memory.
using TestKernel = BriefDescriptor (*)(const uint8_t* centre, std::ptrdiff_t step, const TestOffsets& offsets);

/// Bytes past a patch pixel that a vector kernel may read (the gathers read 32-bit words).
constexpr int kBytesPastPatch = 3;

/// The kernel of `level`, or nullptr for levels without one of their own or when this build or
/// this CPU cannot run it:
///  - kPortable: the pixels read one at a time into arrays, compared 16 at a time (SSE2) or one by one;
///  - kAvx2: hardware gathers, eight tests per step;
///  - kAvx512Vbmi: the patch in 16 registers, byte permutes, 64 tests per step.
/// All give the portable kernel's bits; the tests compare each with it.
TestKernel kernelFor(cpu::CpuLevel level);

/// Whichever of two kernels describes a few hundred corners of a noise image in less time on this
/// CPU (`first` on a tie). Takes about a millisecond; allocates.
TestKernel fasterKernel(TestKernel first, TestKernel second);

/// The kernel of the highest level up to `at_most` (cpu::selectKernel), with one exception: when
/// that is the AVX2 gather kernel, whichever of it and the portable kernel fasterKernel measures
/// faster (no feature flag tells whether this CPU's gathers are fast).
TestKernel selectKernel(cpu::CpuLevel at_most);
/// selectKernel(cpu::activeLevel()), chosen once.
TestKernel selectKernel();

}  // namespace brief_kernels
}  // namespace visual_gyro
