#include "patch_alignment.h"

#include <array>
#include <cmath>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

#include "cpu_features.h"

namespace visual_gyro {
namespace patch_alignment {

void buildTemplatePortable(const uint8_t* top_left, size_t step, PatchTemplate* patch) {
  PatchTemplate& p = *patch;
  const std::ptrdiff_t row_step = static_cast<std::ptrdiff_t>(step);
  p.sum_x = p.sum_y = p.sum_xx = p.sum_xy = p.sum_yy = p.sum_value = p.sum_x_value = p.sum_y_value = 0;
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* row = top_left + v * step;
    for (int u = 0; u < kStride; ++u) {
      const int i = v * kStride + u;
      const bool inside = u < kSide;
      p.grad_x[i] = static_cast<int16_t>(inside ? row[u + 1] - row[u - 1] : 0);
      p.grad_y[i] = static_cast<int16_t>(inside ? row[u + row_step] - row[u - row_step] : 0);
      const int32_t x = p.grad_x[i], y = p.grad_y[i], value = inside ? row[u] : 0;
      p.sum_x += x;
      p.sum_y += y;
      p.sum_xx += x * x;
      p.sum_xy += x * y;
      p.sum_yy += y * y;
      p.sum_value += value;
      p.sum_x_value += x * value;
      p.sum_y_value += y * value;
    }
  }
}

PatchCorrelation correlatePortable(const PatchTemplate& patch, const uint8_t* top_left, size_t step) {
  PatchCorrelation c{0, 0, 0};
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* row = top_left + v * step;
    for (int u = 0; u < kSide; ++u) {
      const int32_t intensity = row[u];
      c.x += patch.grad_x[v * kStride + u] * intensity;
      c.y += patch.grad_y[v * kStride + u] * intensity;
      c.intensity += intensity;
    }
  }
  return c;
}

PatchMoments momentsPortable(const uint8_t* previous_top_left, size_t previous_step, const uint8_t* current_top_left,
                             size_t current_step, int ax, int ay) {
  PatchMoments m{0, 0, 0, 0, 0};
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* a = previous_top_left + v * previous_step;
    const uint8_t* c0 = current_top_left + v * current_step;
    const uint8_t* c1 = c0 + current_step;
    for (int u = 0; u < kSide; ++u) {
      const int32_t h0 = (kBilinearOne - ax) * c0[u] + ax * c0[u + 1];
      const int32_t h1 = (kBilinearOne - ax) * c1[u] + ax * c1[u + 1];
      const int32_t b = ((kBilinearOne - ay) * h0 + ay * h1 + (1 << 9)) >> 10;
      const int32_t va = a[u];
      m.sum_a += va;
      m.sum_b += b;
      m.sum_aa += va * va;
      m.sum_bb += b * b;
      m.sum_ab += va * b;
    }
  }
  return m;
}

double zeroMeanCorrelation(const PatchMoments& m) {
  // n times the (co)variances, exact in 64 bits.
  constexpr int64_t n = kSide * kSide;
  const int64_t var_a = n * m.sum_aa - int64_t{m.sum_a} * m.sum_a;
  const int64_t var_b = n * m.sum_bb - int64_t{m.sum_b} * m.sum_b;
  if (var_a <= 0 || var_b <= 0) return -1.0;
  const int64_t covariance = n * m.sum_ab - int64_t{m.sum_a} * m.sum_b;
  return static_cast<double>(covariance) / std::sqrt(static_cast<double>(var_a) * static_cast<double>(var_b));
}

#if defined(__SSE2__)
namespace {

int32_t horizontalSum(__m128i x) {
  x = _mm_add_epi32(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(1, 0, 3, 2)));
  x = _mm_add_epi32(x, _mm_shuffle_epi32(x, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(x);
}

__m128i loadBytes(const uint8_t* p) { return _mm_loadu_si128(reinterpret_cast<const __m128i*>(p)); }

// A row is 16 pixels: the first 8 widened to 16 bits, then the other 8 with the columns past
// kSide zeroed. Products of 16-bit pairs are summed pairwise into 32 bits (pmaddwd).
void buildTemplateSse2(const uint8_t* top_left, size_t step, PatchTemplate* patch) {
  static_assert(kSide > 8 && kSide <= 16, "the second half of a row holds kSide - 8 pixels");
  const __m128i zero = _mm_setzero_si128(), ones = _mm_set1_epi16(1);
  const __m128i high_half = _mm_srli_si128(_mm_set1_epi32(-1), 2 * (16 - kSide));
  __m128i sx = zero, sy = zero, sxx = zero, sxy = zero, syy = zero, sv = zero, sxv = zero, syv = zero;
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* row = top_left + v * step;
    const __m128i centre = loadBytes(row), left = loadBytes(row - 1), right = loadBytes(row + 1);
    const __m128i up = loadBytes(row - step), down = loadBytes(row + step);
    for (int half = 0; half < 2; ++half) {
      const auto widen = [&](__m128i x) {
        return half == 0 ? _mm_unpacklo_epi8(x, zero) : _mm_and_si128(_mm_unpackhi_epi8(x, zero), high_half);
      };
      const __m128i value = widen(centre);
      const __m128i x = _mm_sub_epi16(widen(right), widen(left));
      const __m128i y = _mm_sub_epi16(widen(down), widen(up));
      const int i = v * kStride + 8 * half;
      _mm_store_si128(reinterpret_cast<__m128i*>(&patch->grad_x[i]), x);
      _mm_store_si128(reinterpret_cast<__m128i*>(&patch->grad_y[i]), y);
      sx = _mm_add_epi32(sx, _mm_madd_epi16(x, ones));
      sy = _mm_add_epi32(sy, _mm_madd_epi16(y, ones));
      sxx = _mm_add_epi32(sxx, _mm_madd_epi16(x, x));
      sxy = _mm_add_epi32(sxy, _mm_madd_epi16(x, y));
      syy = _mm_add_epi32(syy, _mm_madd_epi16(y, y));
      sv = _mm_add_epi32(sv, _mm_madd_epi16(value, ones));
      sxv = _mm_add_epi32(sxv, _mm_madd_epi16(x, value));
      syv = _mm_add_epi32(syv, _mm_madd_epi16(y, value));
    }
  }
  patch->sum_x = horizontalSum(sx);
  patch->sum_y = horizontalSum(sy);
  patch->sum_xx = horizontalSum(sxx);
  patch->sum_xy = horizontalSum(sxy);
  patch->sum_yy = horizontalSum(syy);
  patch->sum_value = horizontalSum(sv);
  patch->sum_x_value = horizontalSum(sxv);
  patch->sum_y_value = horizontalSum(syv);
}

PatchCorrelation correlateSse2(const PatchTemplate& patch, const uint8_t* top_left, size_t step) {
  const __m128i zero = _mm_setzero_si128();
  // The row's kSide pixels (the template's padding gradients are zero; the intensity sum needs
  // the padding masked).
  const __m128i row_bytes = _mm_srli_si128(_mm_set1_epi32(-1), 16 - kSide);
  __m128i sx = zero, sy = zero, si = zero;
  for (int v = 0; v < kSide; ++v) {
    const __m128i bytes = loadBytes(top_left + v * step);
    const __m128i low = _mm_unpacklo_epi8(bytes, zero), high = _mm_unpackhi_epi8(bytes, zero);
    const __m128i* gx = reinterpret_cast<const __m128i*>(&patch.grad_x[v * kStride]);
    const __m128i* gy = reinterpret_cast<const __m128i*>(&patch.grad_y[v * kStride]);
    sx = _mm_add_epi32(sx, _mm_add_epi32(_mm_madd_epi16(gx[0], low), _mm_madd_epi16(gx[1], high)));
    sy = _mm_add_epi32(sy, _mm_add_epi32(_mm_madd_epi16(gy[0], low), _mm_madd_epi16(gy[1], high)));
    si = _mm_add_epi64(si, _mm_sad_epu8(_mm_and_si128(bytes, row_bytes), zero));
  }
  return {horizontalSum(sx), horizontalSum(sy),
          _mm_cvtsi128_si32(si) + _mm_cvtsi128_si32(_mm_unpackhi_epi64(si, si))};
}

}  // namespace
#endif

#if defined(__x86_64__) && defined(__GNUC__)
namespace {

__attribute__((target("avx2"))) int32_t horizontalSumAvx2(__m256i x) {
  __m128i sum = _mm_add_epi32(_mm256_castsi256_si128(x), _mm256_extracti128_si256(x, 1));
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(1, 0, 3, 2)));
  sum = _mm_add_epi32(sum, _mm_shuffle_epi32(sum, _MM_SHUFFLE(2, 3, 0, 1)));
  return _mm_cvtsi128_si32(sum);
}

// A row's 16 pixels widened to 16 bits fill one register: half the SSE2 kernel's instructions.
__attribute__((target("avx2"))) __m256i widenRow(const uint8_t* p) {
  return _mm256_cvtepu8_epi16(_mm_loadu_si128(reinterpret_cast<const __m128i*>(p)));
}

// Lanes 0 .. kSide - 1 of a widened row.
__attribute__((target("avx2"))) __m256i rowLanes() {
  return _mm256_cmpgt_epi16(_mm256_set1_epi16(kSide),
                            _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15));
}

__attribute__((target("avx2"))) void buildTemplateAvx2(const uint8_t* top_left, size_t step, PatchTemplate* patch) {
  const __m256i zero = _mm256_setzero_si256(), ones = _mm256_set1_epi16(1), lanes = rowLanes();
  __m256i sx = zero, sy = zero, sxx = zero, sxy = zero, syy = zero, sv = zero, sxv = zero, syv = zero;
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* row = top_left + v * step;
    const __m256i value = _mm256_and_si256(widenRow(row), lanes);
    const __m256i x = _mm256_and_si256(_mm256_sub_epi16(widenRow(row + 1), widenRow(row - 1)), lanes);
    const __m256i y = _mm256_and_si256(_mm256_sub_epi16(widenRow(row + step), widenRow(row - step)), lanes);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&patch->grad_x[v * kStride]), x);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(&patch->grad_y[v * kStride]), y);
    sx = _mm256_add_epi32(sx, _mm256_madd_epi16(x, ones));
    sy = _mm256_add_epi32(sy, _mm256_madd_epi16(y, ones));
    sxx = _mm256_add_epi32(sxx, _mm256_madd_epi16(x, x));
    sxy = _mm256_add_epi32(sxy, _mm256_madd_epi16(x, y));
    syy = _mm256_add_epi32(syy, _mm256_madd_epi16(y, y));
    sv = _mm256_add_epi32(sv, _mm256_madd_epi16(value, ones));
    sxv = _mm256_add_epi32(sxv, _mm256_madd_epi16(x, value));
    syv = _mm256_add_epi32(syv, _mm256_madd_epi16(y, value));
  }
  patch->sum_x = horizontalSumAvx2(sx);
  patch->sum_y = horizontalSumAvx2(sy);
  patch->sum_xx = horizontalSumAvx2(sxx);
  patch->sum_xy = horizontalSumAvx2(sxy);
  patch->sum_yy = horizontalSumAvx2(syy);
  patch->sum_value = horizontalSumAvx2(sv);
  patch->sum_x_value = horizontalSumAvx2(sxv);
  patch->sum_y_value = horizontalSumAvx2(syv);
}

__attribute__((target("avx2"))) PatchCorrelation correlateAvx2(const PatchTemplate& patch, const uint8_t* top_left,
                                                               size_t step) {
  // The template's padding gradients are zero; the intensity sum needs the padding masked.
  const __m256i zero = _mm256_setzero_si256(), lanes = rowLanes();
  __m256i sx = zero, sy = zero, si = zero;
  for (int v = 0; v < kSide; ++v) {
    const __m256i pixels = widenRow(top_left + v * step);
    const __m256i gx = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(&patch.grad_x[v * kStride]));
    const __m256i gy = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(&patch.grad_y[v * kStride]));
    sx = _mm256_add_epi32(sx, _mm256_madd_epi16(gx, pixels));
    sy = _mm256_add_epi32(sy, _mm256_madd_epi16(gy, pixels));
    si = _mm256_add_epi16(si, _mm256_and_si256(pixels, lanes));  // at most 11 * 255 per lane
  }
  return {horizontalSumAvx2(sx), horizontalSumAvx2(sy), horizontalSumAvx2(_mm256_madd_epi16(si, _mm256_set1_epi16(1)))};
}

// A row at once: the horizontal blend in 16 bits (at most 255 * kBilinearOne), the vertical one
// as pairs (h0, h1) . (kBilinearOne - ay, ay) in 32 bits, packed back to 16 bits (at most 4080).
__attribute__((target("avx2"))) PatchMoments momentsAvx2(const uint8_t* previous_top_left, size_t previous_step,
                                                         const uint8_t* current_top_left, size_t current_step, int ax,
                                                         int ay) {
  const __m256i zero = _mm256_setzero_si256(), ones = _mm256_set1_epi16(1), lanes = rowLanes();
  const __m256i left = _mm256_set1_epi16(static_cast<int16_t>(kBilinearOne - ax));
  const __m256i right = _mm256_set1_epi16(static_cast<int16_t>(ax));
  const __m256i vertical = _mm256_set1_epi32((ay << 16) | (kBilinearOne - ay));
  const __m256i rounding = _mm256_set1_epi32(1 << 9);
  __m256i sa = zero, sb = zero, saa = zero, sbb = zero, sab = zero;
  __m256i h_above = _mm256_add_epi16(_mm256_mullo_epi16(widenRow(current_top_left), left),
                                     _mm256_mullo_epi16(widenRow(current_top_left + 1), right));
  for (int v = 0; v < kSide; ++v) {
    const uint8_t* below = current_top_left + (v + 1) * current_step;
    const __m256i h_below =
        _mm256_add_epi16(_mm256_mullo_epi16(widenRow(below), left), _mm256_mullo_epi16(widenRow(below + 1), right));
    const __m256i low = _mm256_srai_epi32(
        _mm256_add_epi32(_mm256_madd_epi16(_mm256_unpacklo_epi16(h_above, h_below), vertical), rounding), 10);
    const __m256i high = _mm256_srai_epi32(
        _mm256_add_epi32(_mm256_madd_epi16(_mm256_unpackhi_epi16(h_above, h_below), vertical), rounding), 10);
    // Both unpacks work within 128-bit halves and the pack undoes their order.
    const __m256i b = _mm256_and_si256(_mm256_packs_epi32(low, high), lanes);
    const __m256i a = _mm256_and_si256(widenRow(previous_top_left + v * previous_step), lanes);
    sa = _mm256_add_epi32(sa, _mm256_madd_epi16(a, ones));
    sb = _mm256_add_epi32(sb, _mm256_madd_epi16(b, ones));
    saa = _mm256_add_epi32(saa, _mm256_madd_epi16(a, a));
    sbb = _mm256_add_epi32(sbb, _mm256_madd_epi16(b, b));
    sab = _mm256_add_epi32(sab, _mm256_madd_epi16(a, b));
    h_above = h_below;
  }
  return {horizontalSumAvx2(sa), horizontalSumAvx2(sb), horizontalSumAvx2(saa), horizontalSumAvx2(sbb),
          horizontalSumAvx2(sab)};
}

}  // namespace
#endif

MomentsKernel momentsKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return momentsPortable;
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? momentsAvx2 : nullptr;
#endif
    default:
      return nullptr;
  }
}

TemplateKernel templateKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return buildTemplatePortable;
#if defined(__SSE2__)
    case cpu::CpuLevel::kSse2:
      return cpu::runs(level) ? buildTemplateSse2 : nullptr;
#endif
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? buildTemplateAvx2 : nullptr;
#endif
    default:
      return nullptr;
  }
}

CorrelationKernel correlationKernelFor(cpu::CpuLevel level) {
  switch (level) {
    case cpu::CpuLevel::kPortable:
      return correlatePortable;
#if defined(__SSE2__)
    case cpu::CpuLevel::kSse2:
      return cpu::runs(level) ? correlateSse2 : nullptr;
#endif
#if defined(__x86_64__) && defined(__GNUC__)
    case cpu::CpuLevel::kAvx2:
      return cpu::runs(level) ? correlateAvx2 : nullptr;
#endif
    default:
      return nullptr;
  }
}

TemplateKernel selectTemplateKernel(cpu::CpuLevel at_most) { return cpu::selectKernel(templateKernelFor, at_most); }

CorrelationKernel selectCorrelationKernel(cpu::CpuLevel at_most) {
  return cpu::selectKernel(correlationKernelFor, at_most);
}

MomentsKernel selectMomentsKernel(cpu::CpuLevel at_most) { return cpu::selectKernel(momentsKernelFor, at_most); }

TemplateKernel templateKernel() {
  static const TemplateKernel kernel = selectTemplateKernel(cpu::activeLevel());
  return kernel;
}

CorrelationKernel correlationKernel() {
  static const CorrelationKernel kernel = selectCorrelationKernel(cpu::activeLevel());
  return kernel;
}

MomentsKernel momentsKernel() {
  static const MomentsKernel kernel = selectMomentsKernel(cpu::activeLevel());
  return kernel;
}

bool alignPatch(const PatchTemplate& patch, const uint8_t* current_top_left, size_t step,
                CorrelationKernel correlate, int iterations, double converged_px, double* dx_out,
                double* dy_out) {
  constexpr double n = kSide * kSide;
  // The brightness offset between the frames is removed from the residual (its mean), which is
  // the same as centring the gradients: the structure tensor of the zero-mean gradients, and
  // b = sum g e - mean(g) sum e below. The integer sums keep the subtraction exact enough.
  const double mean_x = patch.sum_x / n, mean_y = patch.sum_y / n;
  const double hxx = patch.sum_xx - patch.sum_x * mean_x;
  const double hxy = patch.sum_xy - patch.sum_x * mean_y;
  const double hyy = patch.sum_yy - patch.sum_y * mean_y;
  // Corner structure: both eigenvalues of the structure tensor well above zero. An edge (one
  // small eigenvalue) leaves the position along it undetermined.
  const double det = hxx * hyy - hxy * hxy, trace = hxx + hyy;
  if (!(trace > 0.0) || !(det > 0.01 * trace * trace)) return false;
  // The gradients are twice the derivative, so H and b are 4 and 2 times the derivative's: the
  // step H'^-1 b' is 2 H^-1 b.
  const double ixx = 2.0 * hyy / det, ixy = -2.0 * hxy / det, iyy = 2.0 * hxx / det;
  const double template_x = patch.sum_x_value - mean_x * patch.sum_value;
  const double template_y = patch.sum_y_value - mean_y * patch.sum_value;

  // The residual e(u) = I(u + d) - T(u) samples I bilinearly, so b(d) = sum g e is the bilinear
  // blend of b at the four integer shifts around d: each integer shift is correlated once and
  // every later iteration in the same cell costs nothing.
  constexpr int kShifts = 2 * kMaxShift + 2;  // -kMaxShift .. kMaxShift + 1 per axis
  std::array<double, 2 * kShifts * kShifts> b_at;
  std::array<bool, kShifts * kShifts> known{};
  const auto bAt = [&](int ox, int oy) -> const double* {
    const int k = (oy + kMaxShift) * kShifts + ox + kMaxShift;
    if (!known[k]) {
      const PatchCorrelation c =
          correlate(patch, current_top_left + static_cast<std::ptrdiff_t>(oy) * static_cast<std::ptrdiff_t>(step) + ox,
                    step);
      b_at[2 * k] = c.x - mean_x * c.intensity - template_x;
      b_at[2 * k + 1] = c.y - mean_y * c.intensity - template_y;
      known[k] = true;
    }
    return &b_at[2 * k];
  };
  double dx = 0.0, dy = 0.0;
  for (int it = 0; it < iterations; ++it) {
    const int ox = static_cast<int>(std::floor(dx)), oy = static_cast<int>(std::floor(dy));
    const double fx = dx - ox, fy = dy - oy;
    const double weights[4] = {(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy};
    const int corner_x[4] = {0, 1, 0, 1}, corner_y[4] = {0, 0, 1, 1};
    double bx = 0.0, by = 0.0;
    for (int c = 0; c < 4; ++c) {
      if (weights[c] == 0.0) continue;  // an integer shift needs only the cells it touches
      const double* b = bAt(ox + corner_x[c], oy + corner_y[c]);
      bx += weights[c] * b[0];
      by += weights[c] * b[1];
    }
    const double step_x = ixx * bx + ixy * by, step_y = ixy * bx + iyy * by;
    dx -= step_x;
    dy -= step_y;
    if (!(std::abs(dx) <= kMaxShift && std::abs(dy) <= kMaxShift)) return false;
    if (step_x * step_x + step_y * step_y < converged_px * converged_px) break;
  }
  *dx_out = dx;
  *dy_out = dy;
  return true;
}

}  // namespace patch_alignment
}  // namespace visual_gyro
