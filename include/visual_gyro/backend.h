// The hypothesis-voting backend that ran an estimate. Callers decide by this value; its name is
// only for what is printed (CSV files, JSON, messages, diagnostics).
#pragma once

#include <stdexcept>
#include <string>

namespace visual_gyro {

/// The backend that voted an estimate's hypotheses (what BackendChoice picked).
enum class Backend {
  kCpu,   ///< the reference CPU voter
  kCuda,  ///< the CUDA voter
};

/// "cpu" or "cuda", as every output writes it.
inline const char* backendName(Backend backend) { return backend == Backend::kCuda ? "cuda" : "cpu"; }

/// Reads a backendName(); false (and *backend untouched) for any other text.
inline bool parseBackend(const std::string& name, Backend* backend) {
  for (const Backend b : {Backend::kCpu, Backend::kCuda}) {
    if (name == backendName(b)) {
      *backend = b;
      return true;
    }
  }
  return false;
}

/// The backend a voter names (HypothesisVoter::name()); throws std::invalid_argument for a name that is no backend.
inline Backend backendNamed(const std::string& name) {
  Backend backend = Backend::kCpu;
  if (!parseBackend(name, &backend)) throw std::invalid_argument("'" + name + "' is no backend (cpu, cuda)");
  return backend;
}

}  // namespace visual_gyro
