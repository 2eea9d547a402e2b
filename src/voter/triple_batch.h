// hyp::solveTripleRotation for many triples at once, in SIMD lanes (CPU only), bit for bit the
// same statuses and rotations as the scalar function the CUDA kernels share.
// Eigen- and OpenCV-free like the rest of src/voter.
#pragma once

#include <cstdint>

#include "hypothesis_math.h"

namespace visual_gyro {
namespace hyp {

/// Triples the batched solver works on at once (SIMD lanes).
constexpr int kTripleBatch = 8;

/// True when this CPU solves triples in SIMD lanes (x86-64 at CPU level kAvx or above, see
/// src/core/cpu_features.h); without them solveTriples solves one triple at a time.
bool tripleBatchAvailable();

/// drawTriple for hypotheses first .. first + count - 1 (idx[k]: hypothesis first + k), eight at a
/// time in SIMD lanes where the CPU can (level kAvx2); the same indices as drawTriple.
void drawTriples(uint64_t seed, uint32_t first, int count, uint32_t n, uint32_t (*idx)[3]);

/// solveTripleRotation for `count` triples, in SIMD lanes where the CPU can: triple k is made of
/// the bearings prev[idx[k][i]] and cur[idx[k][i]], i = 0..2; status[k] and R[k] are its results
/// (R[k] set only when status[k] is kTripleOk). Every triple goes through exactly the scalar
/// function's floating-point operations, so the results are identical to it.
void solveTriples(const Vec3f* prev, const Vec3f* cur, const uint32_t (*idx)[3], int count, const TripleOptions& opt,
                  int32_t* status, Mat3f* R);

}  // namespace hyp
}  // namespace visual_gyro
