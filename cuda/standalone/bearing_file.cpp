#include "standalone/bearing_file.h"

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
  if (line != kBearingFileHeader) fail(std::string("expected header \"") + kBearingFileHeader + "\"");

  std::vector<BearingFrame> frames;
  size_t remaining = 0;  // bearing lines still expected for the current frame
  while (std::getline(in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    if (remaining == 0) {
      std::string keyword;
      long long index = 0, count = -1;
      if (!(fields >> keyword >> index >> count) || keyword != "frame" || count < 0)
        fail("expected \"frame <k> <n>\", got \"" + line + "\"");
      frames.emplace_back();
      frames.back().index = index;
      frames.back().prev.reserve(static_cast<size_t>(count));
      frames.back().cur.reserve(static_cast<size_t>(count));
      remaining = static_cast<size_t>(count);
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
    std::fprintf(out, "frame %lld %zu\n", static_cast<long long>(frame.index), frame.prev.size());
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
