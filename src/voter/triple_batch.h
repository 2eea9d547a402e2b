// hyp::solveTripleRotation for several triples at once in SIMD lanes (CPU only), bit for bit the
// same statuses and rotations as the scalar function the CUDA kernels share.
// Eigen- and OpenCV-free like the rest of src/voter.
#pragma once

#include <cstdint>

#include "hypothesis_math.h"

namespace visual_gyro {
namespace hyp {

/// Triples solved by one solveTripleBatch call.
constexpr int kTripleBatch = 8;

/// True when this CPU runs solveTripleBatch (x86-64 with AVX); otherwise solve one triple at a time
/// with solveTripleRotation.
bool tripleBatchAvailable();

/// solveTripleRotation for kTripleBatch triples: prev[k] and cur[k] are triple k, status[k] and R[k]
/// its results (R[k] set only when status[k] is kTripleOk). Every lane performs exactly the scalar
/// function's floating-point operations, so the results are identical to it. Requires
/// tripleBatchAvailable().
void solveTripleBatch(const Vec3f prev[kTripleBatch][3], const Vec3f cur[kTripleBatch][3],
                      const TripleOptions& opt, int32_t status[kTripleBatch], Mat3f R[kTripleBatch]);

}  // namespace hyp
}  // namespace visual_gyro
