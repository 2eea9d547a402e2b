// The CUDA hypothesis voter: one GPU thread per 3-point hypothesis, votes in shared-memory (yaw)
// or global (rotation-vector) histograms, winner found on the device.
//
// Plain C++ (no CUDA headers), so that the core library and the tests include it with any C++
// compiler: `#include "cuda_voter.h"` from src/core, or `#include "cuda_voter.h"` with
// the include directories of target visual_gyro_cuda. Available only in builds where
// VISUAL_GYRO_WITH_CUDA is defined (the library is then linked into visual_gyro_core).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "hypothesis_voter.h"

namespace visual_gyro {

/// True when CUDA device `device` works for this build (driver present, compute capability >= 7.5,
/// context creatable, kernels loadable); otherwise false with the reason (no driver, no device,
/// device too old, ...) in *why (may be null). Creates the device's CUDA context when it succeeds.
bool cudaDeviceAvailable(std::string* why = nullptr, int device = 0);

/// Creates the CUDA voter on device `device`: its stream, events and buffers are made once here and
/// grown only when a frame needs more. Same results as createCpuVoter() for the same request, up to
/// float rounding at bin edges (see cuda/README.md). Throws std::runtime_error with a clear message
/// when no device or driver works.
std::unique_ptr<HypothesisVoter> createCudaVoter(int device = 0);

/// Counters of a CUDA voter, for tests and benchmarks.
struct CudaVoterStats {
  uint64_t frames = 0;         ///< vote() calls that completed
  uint64_t reallocations = 0;  ///< buffer (re)allocations after construction; 0 once warmed
  uint64_t device_bytes = 0;   ///< device memory held by the voter's buffers [bytes]
  uint64_t pinned_bytes = 0;   ///< pinned host memory held [bytes]
  std::string device_name;     ///< e.g. "NVIDIA H100 80GB HBM3"
  int compute_capability = 0;  ///< major * 10 + minor, e.g. 90
};

/// Counters of a voter made by createCudaVoter(); throws std::invalid_argument for another voter.
CudaVoterStats cudaVoterStats(const HypothesisVoter& voter);

}  // namespace visual_gyro
