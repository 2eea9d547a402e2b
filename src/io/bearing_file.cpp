#include "bearing_file.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace visual_gyro {
namespace bearings {

std::vector<BearingFrame> readBearingFile(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open bearing file " + path);
  size_t line_number = 0;
  auto fail = [&](const std::string& what) {
    throw std::runtime_error(path + ":" + std::to_string(line_number) + ": " + what);
  };
  std::string line;
  if (!std::getline(in, line)) fail("empty file");
  ++line_number;
  if (!line.empty() && line.back() == '\r') line.pop_back();
  const bool v2 = line == kBearingFileHeader;
  if (!v2 && line != kBearingFileHeaderV1)
    fail(std::string("expected header \"") + kBearingFileHeader + "\" (or \"" + kBearingFileHeaderV1 + "\")");

  std::vector<BearingFrame> frames;
  size_t remaining = 0;       // bearing lines still expected for the current frame
  bool truth_allowed = false;  // right after a v2 frame line, before its first bearing
  while (std::getline(in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    if (truth_allowed && line.compare(first, 5, "truth") == 0) {
      std::string keyword;
      fields >> keyword;
      BearingFrame& frame = frames.back();
      for (double& x : frame.truth)
        if (!(fields >> x) || !std::isfinite(x)) fail("expected \"truth\" and 9 numbers, got \"" + line + "\"");
      // A rotation: orthonormal rows (the file prints 17 digits, so far tighter than this).
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) {
          double dot = 0.0;
          for (int k = 0; k < 3; ++k) dot += frame.truth[3 * r + k] * frame.truth[3 * c + k];
          if (std::fabs(dot - (r == c ? 1.0 : 0.0)) > 1e-6) fail("truth is not a rotation matrix");
        }
      frame.has_truth = true;
      truth_allowed = false;
      continue;
    }
    truth_allowed = false;
    if (remaining == 0) {
      std::string keyword;
      long long index = 0, count = -1;
      double dt = 0.0;
      if (!(fields >> keyword >> index >> count) || keyword != "frame" || count < 0)
        fail(std::string("expected \"frame <k> <n>") + (v2 ? " <dt>" : "") + "\", got \"" + line + "\"");
      if (v2 && (!(fields >> dt) || !std::isfinite(dt) || dt <= 0.0))
        fail("expected a positive dt [s] after \"frame <k> <n>\", got \"" + line + "\"");
      frames.emplace_back();
      frames.back().index = index;
      frames.back().dt = dt;
      frames.back().prev.reserve(static_cast<size_t>(count));
      frames.back().cur.reserve(static_cast<size_t>(count));
      remaining = static_cast<size_t>(count);
      truth_allowed = v2;
      continue;
    }
    double v[6];
    for (double& x : v)
      if (!(fields >> x)) fail("expected 6 numbers (px py pz cx cy cz), got \"" + line + "\"");
    for (int b = 0; b < 2; ++b) {
      const double* u = v + 3 * b;
      const double len = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
      if (!std::isfinite(len) || std::fabs(len - 1.0) > 1e-3) fail("bearing is not a unit vector");
    }
    frames.back().prev.push_back(hyp::make3(static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])));
    frames.back().cur.push_back(hyp::make3(static_cast<float>(v[3]), static_cast<float>(v[4]), static_cast<float>(v[5])));
    --remaining;
  }
  if (remaining != 0) fail("file ends " + std::to_string(remaining) + " bearing lines before the frame does");
  return frames;
}

void writeBearingFile(const std::string& path, const std::vector<BearingFrame>& frames) {
  FILE* out = std::fopen(path.c_str(), "w");
  if (out == nullptr) throw std::runtime_error("cannot write bearing file " + path);
  std::fprintf(out, "%s\n", kBearingFileHeader);
  for (const BearingFrame& frame : frames) {
    if (!(frame.dt > 0.0) || !std::isfinite(frame.dt)) {
      std::fclose(out);
      throw std::runtime_error("bearing file " + path + ": frame " + std::to_string(frame.index) +
                               " has no positive dt");
    }
    std::fprintf(out, "frame %lld %zu %.9g\n", static_cast<long long>(frame.index), frame.prev.size(), frame.dt);
    if (frame.has_truth) {
      std::fprintf(out, "truth");
      for (double x : frame.truth) std::fprintf(out, " %.17g", x);
      std::fprintf(out, "\n");
    }
    for (size_t i = 0; i < frame.prev.size(); ++i) {
      const hyp::Vec3f& p = frame.prev[i];
      const hyp::Vec3f& c = frame.cur[i];
      std::fprintf(out, "%.9g %.9g %.9g %.9g %.9g %.9g\n", p.x, p.y, p.z, c.x, c.y, c.z);
    }
  }
  if (std::fclose(out) != 0) throw std::runtime_error("error writing bearing file " + path);
}

}  // namespace bearings
}  // namespace visual_gyro
