#include "command_line.h"

#include <cmath>
#include <iostream>
#include <sstream>

namespace visual_gyro {
namespace cli {

std::vector<std::string> splitList(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item.erase(0, item.find_first_not_of(" \t"));
    item.erase(item.find_last_not_of(" \t") + 1);
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

long long parseInt(const std::string& text, const std::string& what, long long lo, long long hi) {
  long long v = 0;
  try {
    size_t used = 0;
    v = std::stoll(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw UsageError(what + ": '" + text + "' is not an integer");
  }
  if (v < lo || v > hi) {
    throw UsageError(what + " must be in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got " + text);
  }
  return v;
}

double parseDouble(const std::string& text, const std::string& what, double lo, double hi) {
  double v = 0.0;
  try {
    size_t used = 0;
    v = std::stod(text, &used);
    if (used != text.size() || !std::isfinite(v)) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw UsageError(what + ": '" + text + "' is not a number");
  }
  if (v < lo || v > hi) {
    std::ostringstream range;
    range << what << " must be in [" << lo << ", " << hi << "], got " << text;
    throw UsageError(range.str());
  }
  return v;
}

Arguments::Arguments(int argc, char** argv) : args_(argv + (argc > 0 ? 1 : 0), argv + argc) {}

bool Arguments::next() {
  if (started_) ++index_;
  started_ = true;
  return index_ < args_.size();
}

std::string Arguments::value() {
  const std::string option = current();
  if (index_ + 1 >= args_.size()) throw UsageError("option " + option + " needs a value");
  return args_[++index_];
}

long long Arguments::intValue(long long lo, long long hi) {
  const std::string option = current();
  return parseInt(value(), option, lo, hi);
}

double Arguments::doubleValue(double lo, double hi) {
  const std::string option = current();
  return parseDouble(value(), option, lo, hi);
}

std::vector<std::string> Arguments::listValue() {
  const std::string option = current();
  std::vector<std::string> list = splitList(value());
  if (list.empty()) throw UsageError(option + ": empty list");
  return list;
}

std::vector<int> Arguments::intListValue(long long lo, long long hi) {
  const std::string option = current();
  std::vector<int> out;
  for (const std::string& item : listValue()) out.push_back(static_cast<int>(parseInt(item, option, lo, hi)));
  return out;
}

void Arguments::positional(std::vector<std::string>* list, size_t max) const {
  if (isOption() || list->size() >= max) unexpected();
  list->push_back(current());
}

void Arguments::unexpected() const {
  if (isOption()) throw UsageError("unknown option " + current());
  throw UsageError("unexpected argument '" + current() + "'");
}

int runCommand(const std::string& program, const std::string& usage, const std::function<int()>& body) {
  try {
    return body();
  } catch (const UsageError& e) {
    std::cerr << program << ": " << e.what() << "\n" << usage;
    return 2;
  } catch (const std::exception& e) {
    std::cerr << program << ": " << e.what() << "\n";
    return 1;
  }
}

}  // namespace cli
}  // namespace visual_gyro
