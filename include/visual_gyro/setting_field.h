// One description per setting: name, type, default (the settings struct's initialiser), accepted
// range, unit and a one-line doc, with the code that reads and writes it. Validation, the command
// line (evaluate --set), the nodelet's parameters and dynamic_reconfigure all go through these
// descriptions; a test checks cfg/VisualGyro.cfg, config/visual_gyro.yaml and the README against
// them. Plain C++ (no Eigen, no OpenCV).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace visual_gyro {

/// The value type of a setting, as dynamic_reconfigure knows them.
enum class SettingType { kBool, kInt, kDouble, kString };

/// One setting of a settings struct S.
template <class S>
struct SettingField {
  std::string name;       ///< as in the struct, the cfg, the yaml and `evaluate --set`
  SettingType type = SettingType::kDouble;
  /// Inclusive range of a number (kInt, kDouble); validation accepts exactly [min, max].
  double min = 0.0, max = 0.0;
  std::vector<std::string> choices;  ///< kString: the accepted values; empty: any text
  std::string unit;                  ///< e.g. "deg", "px", "s"; "" when none
  std::string doc;                   ///< one line
  /// The value of `settings` as text (numbers as the shortest exact decimal, bools true/false).
  std::function<std::string(const S&)> text;
  /// Parses `value` and stores it; returns "" or why the text is not a value of this type. The
  /// range is checked by checkRange, not here, so that a caller can report it separately.
  std::function<std::string(S*, const std::string&)> parse;
  /// The value as a number (kInt, kDouble, kBool as 0/1); NaN for text.
  std::function<double(const S&)> number;

  /// "" when the value in `settings` is in range (or one of the choices), else a message naming
  /// the setting, its value, the range and the unit.
  std::string checkRange(const S& settings) const {
    if (type == SettingType::kString) {
      if (choices.empty()) return "";
      const std::string v = text(settings);
      for (const auto& c : choices)
        if (c == v) return "";
      std::string list;
      for (const auto& c : choices) list += (list.empty() ? "" : ", ") + c;
      return name + " must be one of " + list + ", got '" + v + "'";
    }
    if (type == SettingType::kBool) return "";
    const double v = number(settings);
    if (std::isfinite(v) && v >= min && v <= max) return "";
    std::ostringstream out;
    out << name << " must be in [" << formatNumber(min) << ", " << formatNumber(max) << "]"
        << (unit.empty() ? "" : " " + unit) << ", got " << text(settings);
    return out.str();
  }

  /// Shortest text that reads back as the same double.
  static std::string formatNumber(double v) {
    // Whole numbers as integers (10000000, not 1e+07).
    if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e15) return std::to_string(static_cast<long long>(v));
    for (int precision = 6; precision <= 17; ++precision) {
      std::ostringstream out;
      out.precision(precision);
      out << v;
      if (std::stod(out.str()) == v) return out.str();
    }
    std::ostringstream out;
    out.precision(17);
    out << v;
    return out.str();
  }
};

namespace setting_detail {

inline std::string parseInteger(const std::string& text, long long lo, long long hi, long long* out) {
  try {
    size_t used = 0;
    const long long v = std::stoll(text, &used);
    if (used == text.size() && v >= lo && v <= hi) {
      *out = v;
      return "";
    }
  } catch (const std::exception&) {
  }
  return "'" + text + "' is not an integer";
}

inline std::string parseReal(const std::string& text, double* out) {
  try {
    size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size()) {
      *out = v;
      return "";
    }
  } catch (const std::exception&) {
  }
  return "'" + text + "' is not a number";
}

inline std::string parseBoolean(const std::string& text, bool* out) {
  if (text == "1" || text == "true" || text == "True" || text == "on" || text == "yes") {
    *out = true;
    return "";
  }
  if (text == "0" || text == "false" || text == "False" || text == "off" || text == "no") {
    *out = false;
    return "";
  }
  return "'" + text + "' is not a boolean (true/false)";
}

}  // namespace setting_detail

/// A double member, valid in [min, max].
template <class S>
SettingField<S> doubleField(std::string name, double S::*member, double min, double max, std::string unit,
                            std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kDouble;
  f.min = min;
  f.max = max;
  f.unit = std::move(unit);
  f.doc = std::move(doc);
  f.text = [member](const S& s) { return SettingField<S>::formatNumber(s.*member); };
  f.number = [member](const S& s) { return s.*member; };
  f.parse = [member](S* s, const std::string& v) {
    double x = 0.0;
    const std::string why = setting_detail::parseReal(v, &x);
    if (why.empty()) s->*member = x;
    return why;
  };
  return f;
}

/// An integer member (int or uint64_t), valid in [min, max].
template <class S, class Int>
SettingField<S> intField(std::string name, Int S::*member, long long min, long long max, std::string unit,
                         std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kInt;
  f.min = static_cast<double>(min);
  f.max = static_cast<double>(max);
  f.unit = std::move(unit);
  f.doc = std::move(doc);
  f.text = [member](const S& s) { return std::to_string(s.*member); };
  f.number = [member](const S& s) { return static_cast<double>(s.*member); };
  f.parse = [member](S* s, const std::string& v) {
    long long x = 0;
    // Parsed within the member type's range; the setting's range is checked separately.
    const long long lo = std::is_signed<Int>::value ? static_cast<long long>(std::numeric_limits<Int>::min()) : 0;
    const long long hi = static_cast<long long>(
        std::min<unsigned long long>(std::numeric_limits<Int>::max(), std::numeric_limits<long long>::max()));
    const std::string why = setting_detail::parseInteger(v, lo, hi, &x);
    if (why.empty()) s->*member = static_cast<Int>(x);
    return why;
  };
  return f;
}

/// A bool member.
template <class S>
SettingField<S> boolField(std::string name, bool S::*member, std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kBool;
  f.min = 0;
  f.max = 1;
  f.doc = std::move(doc);
  f.text = [member](const S& s) { return std::string(s.*member ? "true" : "false"); };
  f.number = [member](const S& s) { return s.*member ? 1.0 : 0.0; };
  f.parse = [member](S* s, const std::string& v) {
    bool x = false;
    const std::string why = setting_detail::parseBoolean(v, &x);
    if (why.empty()) s->*member = x;
    return why;
  };
  return f;
}

/// An enum member shown as text: names[i].first is the text of value names[i].second.
template <class S, class E>
SettingField<S> enumField(std::string name, E S::*member, std::vector<std::pair<std::string, E>> names,
                          std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kString;
  for (const auto& n : names) f.choices.push_back(n.first);
  f.doc = std::move(doc);
  f.text = [member, names](const S& s) {
    for (const auto& n : names)
      if (n.second == s.*member) return n.first;
    return std::string("?");
  };
  f.number = [](const S&) { return std::numeric_limits<double>::quiet_NaN(); };
  const std::string setting = f.name;
  f.parse = [member, names, setting](S* s, const std::string& v) {
    for (const auto& n : names) {
      if (n.first == v) {
        s->*member = n.second;
        return std::string();
      }
    }
    std::string list;
    for (const auto& n : names) list += (list.empty() ? "" : ", ") + n.first;
    return setting + " must be one of " + list + ", got '" + v + "'";
  };
  return f;
}

/// The same field seen from an outer struct O through its member `part` (e.g. the estimator's
/// settings inside the pipeline's).
template <class O, class S>
SettingField<O> nestedField(const SettingField<S>& inner, S O::*part) {
  SettingField<O> f;
  f.name = inner.name;
  f.type = inner.type;
  f.min = inner.min;
  f.max = inner.max;
  f.choices = inner.choices;
  f.unit = inner.unit;
  f.doc = inner.doc;
  const auto text = inner.text;
  const auto number = inner.number;
  const auto parse = inner.parse;
  f.text = [text, part](const O& o) { return text(o.*part); };
  f.number = [number, part](const O& o) { return number(o.*part); };
  f.parse = [parse, part](O* o, const std::string& v) { return parse(&(o->*part), v); };
  return f;
}

/// The first range violation among `fields` in `settings`, or "".
template <class S>
std::string checkRanges(const S& settings, const std::vector<SettingField<S>>& fields) {
  for (const auto& f : fields) {
    const std::string why = f.checkRange(settings);
    if (!why.empty()) return why;
  }
  return "";
}

}  // namespace visual_gyro
