// The command-line conventions of every visual_gyro command: `--name value` options and
// positional arguments, numbers checked against a range, comma-separated lists, exit status 2 with
// the usage for a bad command line and 1 for anything else that goes wrong. Plain C++.
#pragma once

#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace visual_gyro {
namespace cli {

/// A bad command line (exit status 2, the usage is printed).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Splits "a, b,c" into {"a", "b", "c"} (blanks trimmed, empty items dropped).
std::vector<std::string> splitList(const std::string& text);
/// An integer in [lo, hi]; `what` names it in the UsageError.
long long parseInt(const std::string& text, const std::string& what, long long lo, long long hi);
/// A finite number in [lo, hi]; `what` names it in the UsageError.
double parseDouble(const std::string& text, const std::string& what, double lo, double hi);

/// Walks argv: for (Arguments args(argc, argv); args.next();) { if (args.is("--x")) ... }.
class Arguments {
 public:
  Arguments(int argc, char** argv);
  /// Moves to the next argument; false when none is left.
  bool next();
  /// The current argument.
  const std::string& current() const { return args_[index_]; }
  /// True when the current argument is the option `name`.
  bool is(const std::string& name) const { return current() == name; }
  /// True when the current argument starts with '-' (an option).
  bool isOption() const { return !current().empty() && current()[0] == '-'; }
  /// The current option's value (the next argument), consumed.
  std::string value();
  /// The value as an integer in [lo, hi].
  long long intValue(long long lo, long long hi);
  /// The value as a number in [lo, hi].
  double doubleValue(double lo, double hi);
  /// The value as a non-empty comma-separated list.
  std::vector<std::string> listValue();
  /// The value as a non-empty comma-separated list of integers in [lo, hi].
  std::vector<int> intListValue(long long lo, long long hi);
  /// Takes the current argument as the next positional one; unexpected() for an option, or when
  /// `list` already holds `max` of them.
  void positional(std::vector<std::string>* list, size_t max) const;
  /// Throws the UsageError for an unknown option or a surplus positional argument.
  [[noreturn]] void unexpected() const;

 private:
  std::vector<std::string> args_;
  size_t index_ = 0;
  bool started_ = false;
};

/// Runs a command's body: UsageError -> "<program>: why", the usage, exit 2; any other exception
/// -> "<program>: why", exit 1; else the body's status.
int runCommand(const std::string& program, const std::string& usage, const std::function<int()>& body);

}  // namespace cli
}  // namespace visual_gyro
