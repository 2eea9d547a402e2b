// Sub-pixel alignment of a previous corner's patch with the current image (internal to the core
// library; not installed): the kernels of FeatureFrontEnd::refineMatches. Every sum is an exact
// integer sum, so the vector kernels (SSE2, x86-64's baseline, and AVX2 where the CPU has it) and
// the portable ones give the same result bit for bit, whatever order they add in.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cpu_features.h"
#include "visual_gyro/feature_front_end.h"

namespace visual_gyro {
namespace patch_alignment {

/// Template side: (2 kRefineHalfWindow + 1) pixels.
constexpr int kSide = 2 * kRefineHalfWindow + 1;
/// Template row length in memory: kSide pixels, then zeros up to one 16-pixel vector.
constexpr int kStride = 16;
static_assert(kSide <= kStride, "a template row fits one 16-pixel vector");
/// Largest correction per axis [px]: a larger one has left the detected corner's neighbourhood.
/// Two, not one: on blurred images FAST places a corner up to a couple of pixels from where the
/// previous patch's content lies (a fifth of euroc_mh01_shake's matches, most of a 3 px motion
/// blur's), and those matches need the alignment most; three let some converge on other structure.
constexpr int kMaxShift = 2;

/// The previous corner's patch: unscaled central differences (twice the derivative:
/// I(x+1) - I(x-1)), rows of kStride with zeros past kSide, and the sums over the patch of them and
/// of its intensities (exact: at most 121 * 255 * 255 < 2^31).
struct PatchTemplate {
  alignas(16) int16_t grad_x[kSide * kStride];
  alignas(16) int16_t grad_y[kSide * kStride];
  int32_t sum_x, sum_y;              ///< sum of grad_x, of grad_y
  int32_t sum_xx, sum_xy, sum_yy;    ///< sums of the gradient products
  int32_t sum_value;                 ///< sum of the intensities
  int32_t sum_x_value, sum_y_value;  ///< sums of grad_x * value, grad_y * value
};

/// The template against the current patch at one integer shift: sums of grad_x * I, grad_y * I and
/// of I over the template's kSide x kSide pixels.
struct PatchCorrelation {
  int32_t x, y, intensity;
};

/// Fills `patch` from the kSide x kSide pixels whose top-left is `top_left` (a row stride of
/// `step` bytes). Reads one pixel around the patch, and kStride - kSide more to the right.
using TemplateKernel = void (*)(const uint8_t* top_left, size_t step, PatchTemplate* patch);
/// Correlates `patch` with the pixels whose top-left is `top_left` (reads kSide rows of kStride).
using CorrelationKernel = PatchCorrelation (*)(const PatchTemplate& patch, const uint8_t* top_left,
                                               size_t step);

/// Plain loops: the reference every other kernel must match exactly.
void buildTemplatePortable(const uint8_t* top_left, size_t step, PatchTemplate* patch);
PatchCorrelation correlatePortable(const PatchTemplate& patch, const uint8_t* top_left, size_t step);

/// The kernels of `level`: the portable ones (kPortable), 16 pixels in two registers (kSse2, on
/// x86-64), a row in one register (kAvx2); nullptr for other levels, or when this build or this
/// CPU cannot run them. All give the portable kernels' integers exactly; the tests compare each
/// level with them.
TemplateKernel templateKernelFor(cpu::CpuLevel level);
CorrelationKernel correlationKernelFor(cpu::CpuLevel level);

/// The kernels of the highest level up to `at_most` (cpu::selectKernel).
TemplateKernel selectTemplateKernel(cpu::CpuLevel at_most);
CorrelationKernel selectCorrelationKernel(cpu::CpuLevel at_most);
/// The kernels of the highest level this build and CPU run (cpu::activeLevel(); chosen once).
TemplateKernel templateKernel();
CorrelationKernel correlationKernel();

/// Bilinear weights of the similarity check: a sub-pixel offset in 1/kBilinearOne px per axis.
constexpr int kBilinearOne = 128;

/// Integer sums of the similarity check over kSide x kSide pixels: a = the previous patch's
/// intensities, b = the current image's, interpolated and in 1/16 grey level.
struct PatchMoments {
  int32_t sum_a, sum_b, sum_aa, sum_bb, sum_ab;
};

/// The similarity check's sums: the previous patch whose top-left is `previous_top_left` against
/// the current image whose top-left is `current_top_left` moved by (ax, ay) / kBilinearOne px
/// (0 <= ax, ay <= kBilinearOne), interpolated bilinearly: b = ((kBilinearOne - ay) h(row) +
/// ay h(row + 1) + 2^9) >> 10 with h(r) = (kBilinearOne - ax) I(r, u) + ax I(r, u + 1). Reads
/// kSide rows of 16 bytes of the previous image and kSide + 1 rows of 17 bytes of the current one.
/// Exact integers (at most 121 * 4080^2 < 2^31), so every kernel gives the same sums.
using MomentsKernel = PatchMoments (*)(const uint8_t* previous_top_left, size_t previous_step,
                                       const uint8_t* current_top_left, size_t current_step, int ax, int ay);

/// Plain loops: the reference.
PatchMoments momentsPortable(const uint8_t* previous_top_left, size_t previous_step, const uint8_t* current_top_left,
                             size_t current_step, int ax, int ay);

/// The moments kernel of `level` (kPortable, kAvx2), or nullptr for other levels (SSE2 has none:
/// the portable kernel serves there) or when this build or CPU cannot run it.
MomentsKernel momentsKernelFor(cpu::CpuLevel level);

/// The moments kernel of the highest level up to `at_most` (cpu::selectKernel).
MomentsKernel selectMomentsKernel(cpu::CpuLevel at_most);
/// The moments kernel of the highest level this build and CPU run (cpu::activeLevel(); chosen once).
MomentsKernel momentsKernel();

/// Zero-mean normalised cross-correlation of the two patches `moments` summed (-1..1); -1 when
/// either patch is flat.
double zeroMeanCorrelation(const PatchMoments& moments);

/// Translational inverse-compositional Lucas-Kanade: the shift d (|d| <= kMaxShift per axis) such
/// that the current image at `current_top_left` + d looks like `patch`, with the brightness
/// offset between the two removed. `current_top_left` is the unshifted patch's top-left; the
/// pixels from kMaxShift above and left of it to kMaxShift + 1 below and right (plus the row
/// padding) must be readable. Returns false when the patch has no corner structure (an edge
/// or flat: the position along it is undetermined) or the alignment leaves the +-kMaxShift box.
/// `iterations`: Gauss-Newton steps at most; `converged_px`: a step this short ends them.
bool alignPatch(const PatchTemplate& patch, const uint8_t* current_top_left, size_t step,
                CorrelationKernel correlate, int iterations, double converged_px, double* dx,
                double* dy);

}  // namespace patch_alignment
}  // namespace visual_gyro
