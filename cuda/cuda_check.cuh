// Error checking for CUDA runtime calls: failures throw, they never terminate the process, so the
// estimator factory and the nodelet can fall back to the CPU backend.
#pragma once

#include <cuda_runtime.h>

#include <stdexcept>
#include <string>

namespace visual_gyro {
namespace cuda_detail {

/// Throws std::runtime_error naming the failed call, its place and the CUDA error string.
inline void throwCudaError(cudaError_t error, const char* call, const char* file, int line) {
  throw std::runtime_error(std::string("CUDA error at ") + file + ":" + std::to_string(line) + ": " + call +
                           " failed: " + cudaGetErrorName(error) + " (" + cudaGetErrorString(error) + ")");
}

}  // namespace cuda_detail
}  // namespace visual_gyro

/// Evaluates a CUDA runtime call; throws std::runtime_error when it does not return cudaSuccess.
#define VG_CUDA_CHECK(call)                                                              \
  do {                                                                                   \
    const cudaError_t vg_cuda_error_ = (call);                                           \
    if (vg_cuda_error_ != cudaSuccess)                                                   \
      ::visual_gyro::cuda_detail::throwCudaError(vg_cuda_error_, #call, __FILE__, __LINE__); \
  } while (0)
