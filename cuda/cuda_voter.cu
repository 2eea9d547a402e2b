// CUDA hypothesis voter: the paper's GPU design (one thread per 3-point hypothesis, counter-based
// triples, closed-form rotation in registers, shared-memory histogram merged with atomics), with
// the per-thread work taken verbatim from hypothesis_math.h so that the CPU gold voter and the
// device cast the same votes up to float rounding.
#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>

#include "cuda_check.cuh"
#include "cuda_voter.h"
#include "hypothesis_math.h"

namespace visual_gyro {
namespace {

constexpr int kVoteBlock = 128;
constexpr int kArgmaxBlock = 256;
constexpr int kArgmaxCellsPerThread = 8;
constexpr int kStatusCount = 6;  // hyp::TripleStatus values; slot 0 (kTripleOk) counts the votes
// Grids up to this many cells vote into shared memory (16 bytes a cell: count + 3 sums = 32 KiB),
// which keeps the yaw histogram's hot bins off the global atomics; larger grids (the 3-D ones)
// vote straight into global memory, where their votes are spread thinly enough.
constexpr int32_t kSharedHistogramMaxCells = 2048;

// One device allocation (and one pinned mirror) holds everything a frame accumulates, so that a
// single memset clears it and a single copy brings it back:
//   [0, 8)        winner key (uint64): (votes << 32) | (0xffffffff - cell), 0 when no votes
//   [8, 32)       uint32 counts per hyp::TripleStatus (slot 0 = accepted)
//   [32, ...)     int32 histogram[cells], then float cell_sums[3 * cells]
constexpr size_t kHeaderBytes = 32;
size_t accumulatorBytes(int32_t cells) { return kHeaderBytes + 16u * static_cast<size_t>(cells); }

struct VoteParams {
  const hyp::Vec3f* prev;
  const hyp::Vec3f* cur;
  uint32_t matches;
  uint32_t hypotheses;
  uint64_t seed;
  hyp::TripleOptions triple;
  hyp::VoteGrid grid;
  int32_t cells;
  uint32_t* counts;
  int32_t* histogram;
  float* cell_sums;
  hyp::HypothesisRecord* records;  // null unless the request keeps records
};

template <bool kSharedHistogram>
__global__ void __launch_bounds__(kVoteBlock) voteKernel(VoteParams p) {
  extern __shared__ int32_t s_histogram[];  // cells counts, then 3 * cells float sums
  float* s_sums = reinterpret_cast<float*>(s_histogram + p.cells);
  __shared__ uint32_t s_counts[kStatusCount];
  if (threadIdx.x < kStatusCount) s_counts[threadIdx.x] = 0;
  if (kSharedHistogram) {
    for (int32_t i = threadIdx.x; i < 4 * p.cells; i += blockDim.x) s_histogram[i] = 0;
  }
  __syncthreads();

  // Computed in 64 bits: the last block may reach past 2^32 for huge hypothesis counts.
  const uint64_t h = static_cast<uint64_t>(blockIdx.x) * blockDim.x + threadIdx.x;
  int32_t status = -1;  // -1: no hypothesis for this thread (tail of the last block)
  if (h < p.hypotheses) {
    hyp::HypothesisRecord record;
    status = hyp::evaluateHypothesis(p.prev, p.cur, p.matches, p.seed, static_cast<uint32_t>(h), p.triple,
                                     p.grid, &record);
    if (p.records != nullptr) p.records[h] = record;
    if (status == hyp::kTripleOk) {
      const int32_t c = record.cell;
      if (kSharedHistogram) {
        atomicAdd(&s_histogram[c], 1);
        atomicAdd(&s_sums[3 * c + 0], record.value[0]);
        atomicAdd(&s_sums[3 * c + 1], record.value[1]);
        atomicAdd(&s_sums[3 * c + 2], record.value[2]);
      } else {
        atomicAdd(&p.histogram[c], 1);
        atomicAdd(&p.cell_sums[3 * c + 0], record.value[0]);
        atomicAdd(&p.cell_sums[3 * c + 1], record.value[1]);
        atomicAdd(&p.cell_sums[3 * c + 2], record.value[2]);
      }
    }
  }
  // Most threads of a warp share a status, so a ballot per status replaces 32 contended atomics
  // with one. Every lane reaches this point (no early return above), as __ballot_sync requires.
  const unsigned lane = threadIdx.x & 31u;
  for (int32_t s = 0; s < kStatusCount; ++s) {
    const unsigned ballot = __ballot_sync(0xffffffffu, status == s);
    if (lane == 0 && ballot != 0u) atomicAdd(&s_counts[s], static_cast<uint32_t>(__popc(ballot)));
  }
  __syncthreads();
  if (threadIdx.x < kStatusCount && s_counts[threadIdx.x] != 0u)
    atomicAdd(&p.counts[threadIdx.x], s_counts[threadIdx.x]);
  if (kSharedHistogram) {
    for (int32_t c = threadIdx.x; c < p.cells; c += blockDim.x) {
      const int32_t votes = s_histogram[c];
      if (votes == 0) continue;
      atomicAdd(&p.histogram[c], votes);
      atomicAdd(&p.cell_sums[3 * c + 0], s_sums[3 * c + 0]);
      atomicAdd(&p.cell_sums[3 * c + 1], s_sums[3 * c + 1]);
      atomicAdd(&p.cell_sums[3 * c + 2], s_sums[3 * c + 2]);
    }
  }
}

/// Fullest cell, lowest index on ties (as the CPU voter): every block reduces its cells to one key
/// (votes << 32) | (0xffffffff - cell), whose maximum is the winner, and merges it with atomicMax.
__global__ void __launch_bounds__(kArgmaxBlock)
    argmaxKernel(const int32_t* __restrict__ histogram, int32_t cells, unsigned long long* winner_key) {
  unsigned long long best = 0ull;
  for (int32_t c = blockIdx.x * blockDim.x + threadIdx.x; c < cells; c += gridDim.x * blockDim.x) {
    const int32_t votes = histogram[c];
    if (votes > 0) {
      const unsigned long long key = (static_cast<unsigned long long>(votes) << 32) |
                                     static_cast<unsigned long long>(0xffffffffu - static_cast<uint32_t>(c));
      best = key > best ? key : best;
    }
  }
  for (int offset = 16; offset > 0; offset >>= 1) {
    const unsigned long long other = __shfl_down_sync(0xffffffffu, best, offset);
    best = other > best ? other : best;
  }
  __shared__ unsigned long long s_best[kArgmaxBlock / 32];
  const int lane = threadIdx.x & 31, warp = threadIdx.x >> 5;
  if (lane == 0) s_best[warp] = best;
  __syncthreads();
  if (warp == 0) {
    best = lane < kArgmaxBlock / 32 ? s_best[lane] : 0ull;
    for (int offset = 16; offset > 0; offset >>= 1) {
      const unsigned long long other = __shfl_down_sync(0xffffffffu, best, offset);
      best = other > best ? other : best;
    }
    if (lane == 0 && best != 0ull) atomicMax(winner_key, best);
  }
}

/// A device buffer and its pinned host mirror of the same size, grown geometrically.
struct Buffer {
  void* device = nullptr;
  void* host = nullptr;  // pinned
  size_t bytes = 0;
};

class CudaVoter final : public HypothesisVoter {
 public:
  explicit CudaVoter(int device) : device_(device) {
    std::string why;
    if (!cudaDeviceAvailable(&why, device)) throw std::runtime_error("CUDA voter unavailable: " + why);
    try {
      VG_CUDA_CHECK(cudaSetDevice(device_));
      cudaDeviceProp properties;
      VG_CUDA_CHECK(cudaGetDeviceProperties(&properties, device_));
      stats_.device_name = properties.name;
      stats_.compute_capability = properties.major * 10 + properties.minor;
      VG_CUDA_CHECK(cudaStreamCreateWithFlags(&stream_, cudaStreamNonBlocking));
      VG_CUDA_CHECK(cudaEventCreate(&start_));
      VG_CUDA_CHECK(cudaEventCreate(&stop_));
      // Sized for a typical frame (4 096 matches, a 32^3 grid) so that the first frames of a
      // sequence already run without allocating; records are allocated on first request.
      grow(&bearings_, 2u * 4096u * sizeof(hyp::Vec3f));
      grow(&accumulator_, accumulatorBytes(32 * 32 * 32));
      stats_.reallocations = 0;  // the initial allocations do not count
    } catch (...) {
      release();
      throw;
    }
  }

  ~CudaVoter() override { release(); }

  void vote(const VoteRequest& request, VoteResult* result) override {
    validateVoteRequest(request);
    if (result == nullptr) throw std::invalid_argument("vote without a result to fill");
    try {
      voteOnDevice(request, result);
    } catch (...) {
      // Work already queued may still read or write the pinned buffers: let it drain before the
      // caller (or the next frame) touches them; the stream's own error is already being thrown.
      if (stream_ != nullptr) cudaStreamSynchronize(stream_);
      cudaGetLastError();
      throw;
    }
  }

  std::string name() const override { return "cuda"; }

  CudaVoterStats stats() const {
    CudaVoterStats s = stats_;
    s.device_bytes = bearings_.bytes + accumulator_.bytes + records_.bytes;
    s.pinned_bytes = s.device_bytes;
    return s;
  }

 private:
  void voteOnDevice(const VoteRequest& request, VoteResult* result) {
    VG_CUDA_CHECK(cudaSetDevice(device_));  // the caller's thread may have selected another device
    const uint32_t n = request.matches;
    const uint32_t hypotheses = request.hypotheses;
    const int32_t cells = hyp::cellCount(request.grid);
    const size_t bearing_bytes = static_cast<size_t>(n) * sizeof(hyp::Vec3f);
    const size_t accumulator_bytes = accumulatorBytes(cells);
    const size_t record_bytes = request.keep_records ? hypotheses * sizeof(hyp::HypothesisRecord) : 0u;
    if (2u * bearing_bytes > bearings_.bytes) grow(&bearings_, 2u * bearing_bytes);
    if (accumulator_bytes > accumulator_.bytes) grow(&accumulator_, accumulator_bytes);
    if (record_bytes > records_.bytes) grow(&records_, record_bytes);

    // Staging through pinned memory makes the upload a true async DMA (pageable memory would be
    // copied by the driver first); prev and cur go up in one transfer.
    auto* h_bearings = static_cast<hyp::Vec3f*>(bearings_.host);
    std::memcpy(h_bearings, request.prev, bearing_bytes);
    std::memcpy(h_bearings + n, request.cur, bearing_bytes);
    auto* d_bearings = static_cast<hyp::Vec3f*>(bearings_.device);
    VG_CUDA_CHECK(cudaMemcpyAsync(d_bearings, h_bearings, 2u * bearing_bytes, cudaMemcpyHostToDevice, stream_));
    VG_CUDA_CHECK(cudaMemsetAsync(accumulator_.device, 0, accumulator_bytes, stream_));

    auto* d_accumulator = static_cast<unsigned char*>(accumulator_.device);
    auto* d_winner_key = reinterpret_cast<unsigned long long*>(d_accumulator);
    VoteParams params;
    params.prev = d_bearings;
    params.cur = d_bearings + n;
    params.matches = n;
    params.hypotheses = hypotheses;
    params.seed = request.seed;
    params.triple = request.triple;
    params.grid = request.grid;
    params.cells = cells;
    params.counts = reinterpret_cast<uint32_t*>(d_accumulator + 8);
    params.histogram = reinterpret_cast<int32_t*>(d_accumulator + kHeaderBytes);
    params.cell_sums = reinterpret_cast<float*>(params.histogram + cells);
    params.records = request.keep_records ? static_cast<hyp::HypothesisRecord*>(records_.device) : nullptr;

    VG_CUDA_CHECK(cudaEventRecord(start_, stream_));
    if (hypotheses > 0) {
      const uint64_t blocks = (static_cast<uint64_t>(hypotheses) + kVoteBlock - 1) / kVoteBlock;
      if (cells <= kSharedHistogramMaxCells) {
        voteKernel<true><<<static_cast<unsigned>(blocks), kVoteBlock, 16u * static_cast<size_t>(cells), stream_>>>(
            params);
      } else {
        voteKernel<false><<<static_cast<unsigned>(blocks), kVoteBlock, 0, stream_>>>(params);
      }
      VG_CUDA_CHECK(cudaGetLastError());
      const int64_t per_block = static_cast<int64_t>(kArgmaxBlock) * kArgmaxCellsPerThread;
      const int64_t argmax_blocks = std::min<int64_t>((cells + per_block - 1) / per_block, 1024);
      argmaxKernel<<<static_cast<unsigned>(argmax_blocks), kArgmaxBlock, 0, stream_>>>(params.histogram, cells,
                                                                                       d_winner_key);
      VG_CUDA_CHECK(cudaGetLastError());
    }
    VG_CUDA_CHECK(cudaEventRecord(stop_, stream_));
    VG_CUDA_CHECK(cudaMemcpyAsync(accumulator_.host, accumulator_.device, accumulator_bytes, cudaMemcpyDeviceToHost,
                                  stream_));
    if (record_bytes > 0)
      VG_CUDA_CHECK(cudaMemcpyAsync(records_.host, records_.device, record_bytes, cudaMemcpyDeviceToHost, stream_));
    VG_CUDA_CHECK(cudaStreamSynchronize(stream_));  // the frame's only synchronisation
    float kernel_ms = 0.f;
    VG_CUDA_CHECK(cudaEventElapsedTime(&kernel_ms, start_, stop_));

    const auto* h_accumulator = static_cast<const unsigned char*>(accumulator_.host);
    unsigned long long winner_key;
    uint32_t counts[kStatusCount];
    std::memcpy(&winner_key, h_accumulator, sizeof winner_key);
    std::memcpy(counts, h_accumulator + 8, sizeof counts);
    const auto* h_histogram = reinterpret_cast<const int32_t*>(h_accumulator + kHeaderBytes);
    const auto* h_sums = reinterpret_cast<const float*>(h_histogram + cells);
    result->histogram.assign(h_histogram, h_histogram + cells);
    result->cell_sums.assign(h_sums, h_sums + 3 * static_cast<size_t>(cells));
    if (request.keep_records) {
      const auto* h_records = static_cast<const hyp::HypothesisRecord*>(records_.host);
      result->records.assign(h_records, h_records + hypotheses);
    } else {
      result->records.clear();
    }
    result->winner =
        winner_key == 0ull ? -1 : static_cast<int32_t>(0xffffffffu - static_cast<uint32_t>(winner_key & 0xffffffffull));
    result->accepted = counts[hyp::kTripleOk];
    result->rejected[hyp::kTripleOk] = 0;
    for (int s = 1; s < kStatusCount; ++s) result->rejected[s] = counts[s];
    result->device_ms = kernel_ms;
    ++stats_.frames;
  }

  /// Replaces `buffer` by one of at least `bytes` (geometric growth: at least twice the old size).
  void grow(Buffer* buffer, size_t bytes) {
    const size_t new_bytes = std::max(bytes, 2 * buffer->bytes);
    // The previous frame ended with a stream synchronisation, so nothing still uses the old memory.
    freeBuffer(buffer);
    VG_CUDA_CHECK(cudaMalloc(&buffer->device, new_bytes));
    VG_CUDA_CHECK(cudaMallocHost(&buffer->host, new_bytes));
    buffer->bytes = new_bytes;
    ++stats_.reallocations;
  }

  static void freeBuffer(Buffer* buffer) {
    // Errors are ignored: this runs on teardown paths where throwing would hide the real error.
    if (buffer->device != nullptr) cudaFree(buffer->device);
    if (buffer->host != nullptr) cudaFreeHost(buffer->host);
    *buffer = Buffer();
  }

  void release() {
    if (cudaSetDevice(device_) != cudaSuccess) return;  // no usable device: nothing was allocated
    if (stream_ != nullptr) cudaStreamSynchronize(stream_);
    freeBuffer(&bearings_);
    freeBuffer(&accumulator_);
    freeBuffer(&records_);
    if (start_ != nullptr) cudaEventDestroy(start_);
    if (stop_ != nullptr) cudaEventDestroy(stop_);
    if (stream_ != nullptr) cudaStreamDestroy(stream_);
    start_ = stop_ = nullptr;
    stream_ = nullptr;
    cudaGetLastError();
  }

  int device_;
  cudaStream_t stream_ = nullptr;
  cudaEvent_t start_ = nullptr;
  cudaEvent_t stop_ = nullptr;
  Buffer bearings_;     // prev then cur, 2 * matches Vec3f
  Buffer accumulator_;  // header, histogram, cell sums (see accumulatorBytes)
  Buffer records_;      // one HypothesisRecord per hypothesis, when requested
  CudaVoterStats stats_;
};

}  // namespace

bool cudaDeviceAvailable(std::string* why, int device) {
  auto fail = [why](const std::string& reason) {
    if (why != nullptr) *why = reason;
    cudaGetLastError();  // clear a non-sticky error so that later calls start clean
    return false;
  };
  int count = 0;
  cudaError_t error = cudaGetDeviceCount(&count);
  if (error != cudaSuccess) return fail(std::string("no usable CUDA device: ") + cudaGetErrorString(error));
  if (count == 0) return fail("no CUDA device found");
  if (device < 0 || device >= count)
    return fail("CUDA device " + std::to_string(device) + " requested but only " + std::to_string(count) +
                " present");
  int major = 0, minor = 0;
  error = cudaDeviceGetAttribute(&major, cudaDevAttrComputeCapabilityMajor, device);
  if (error == cudaSuccess) error = cudaDeviceGetAttribute(&minor, cudaDevAttrComputeCapabilityMinor, device);
  if (error != cudaSuccess) return fail(std::string("cannot query the CUDA device: ") + cudaGetErrorString(error));
  if (major * 10 + minor < 75)
    return fail("CUDA device " + std::to_string(device) + " has compute capability " + std::to_string(major) + "." +
                std::to_string(minor) + "; this build needs 7.5 or newer");
  error = cudaSetDevice(device);
  if (error == cudaSuccess) error = cudaFree(nullptr);  // creates the context: fails on busy/prohibited devices
  if (error != cudaSuccess) return fail(std::string("cannot use the CUDA device: ") + cudaGetErrorString(error));
  // Catches a binary built without code for this device (or a driver too old for its PTX).
  cudaFuncAttributes attributes;
  error = cudaFuncGetAttributes(&attributes, voteKernel<false>);
  if (error != cudaSuccess)
    return fail(std::string("the CUDA kernels cannot run on this device: ") + cudaGetErrorString(error));
  if (why != nullptr) why->clear();
  return true;
}

std::unique_ptr<HypothesisVoter> createCudaVoter(int device) { return std::make_unique<CudaVoter>(device); }

CudaVoterStats cudaVoterStats(const HypothesisVoter& voter) {
  const auto* cuda_voter = dynamic_cast<const CudaVoter*>(&voter);
  if (cuda_voter == nullptr) throw std::invalid_argument("cudaVoterStats: voter \"" + voter.name() + "\" is not a CUDA voter");
  return cuda_voter->stats();
}

}  // namespace visual_gyro
