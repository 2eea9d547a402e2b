// One description per setting: name, type, default (the settings struct's initialiser), accepted
// values, unit, a one-line doc, tier (user, expert, paper-only) and whether it changes live, with
// the code that reads and writes it. Validation, the command line (evaluate --set), the nodelet's
// start-up parameters and dynamic_reconfigure all go through these descriptions (applyField), and
// cfg/VisualGyro.cfg, config/visual_gyro.yaml and the settings tables of the docs are generated
// from them (settings_files). Plain C++ (no Eigen, no OpenCV).
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

/// The value type of a setting: dynamic_reconfigure's four, and a list of numbers (read once at
/// start, never live: dynamic_reconfigure has no list type).
enum class SettingType { kBool, kInt, kDouble, kString, kDoubleList };

/// Who a setting is for: kUser (the few a user sets: the README's table), kExpert (tuning and
/// studies), kPaperOnly (read only by method `paper`, the faithful reproduction).
enum class SettingTier { kUser, kExpert, kPaperOnly };

/// "user", "expert", "paper-only".
inline const char* settingTierName(SettingTier tier) {
  switch (tier) {
    case SettingTier::kUser: return "user";
    case SettingTier::kExpert: return "expert";
    case SettingTier::kPaperOnly: return "paper-only";
  }
  return "?";
}

/// What a setting is, apart from the struct holding it: name, type, accepted values, unit, doc,
/// tier and whether it can change while running. Every check of a value goes through checkNumber
/// or checkChoice, so that the command line, the node's start-up parameters and
/// dynamic_reconfigure accept exactly the same values.
struct SettingSpec {
  std::string name;  ///< as in the struct, the cfg, the yaml and `evaluate --set`
  SettingType type = SettingType::kDouble;
  /// Range of a number (kInt, kDouble; each element of kDoubleList): [min, max], or (min, max]
  /// when min_exclusive. Validation accepts exactly this (and `special`); NaN and infinities never.
  double min = 0.0, max = 0.0;
  bool min_exclusive = false;
  /// A value outside the range that is accepted too, with its meaning (e.g. 0: "per frame").
  bool has_special = false;
  double special = 0.0;
  std::string special_doc;
  std::vector<std::string> choices;  ///< kString: the accepted values; empty: any text
  std::string unit;                  ///< e.g. "deg", "px", "s"; "" when none
  std::string doc;                   ///< one line
  SettingTier tier = SettingTier::kExpert;
  /// true: changes while running (dynamic_reconfigure); false: read once at start.
  bool live = true;

  /// "" when `v` (written `text`) is an accepted number, else a message naming the setting, its
  /// value and what is accepted.
  std::string checkNumber(double v, const std::string& text) const {
    if (acceptsNumber(v)) return "";
    const std::string special_text = has_special ? formatNumber(special) + " (" + special_doc + ") or " : "";
    return name + (type == SettingType::kDoubleList ? " must hold numbers " : " must be ") + special_text + "in " +
           (min_exclusive ? "(" : "[") + formatNumber(min) + ", " + formatNumber(max) + "]" +
           (unit.empty() ? "" : " " + unit) + ", got " + text;
  }

  /// true when `v` is in the range or the special value (never NaN or an infinity). Allocates
  /// nothing, so that a per-frame validation of the settings stays allocation-free.
  bool acceptsNumber(double v) const {
    return (has_special && v == special) || (std::isfinite(v) && (min_exclusive ? v > min : v >= min) && v <= max);
  }

  /// "" when `text` is one of the choices (or there are none), else a message naming the setting.
  std::string checkChoice(const std::string& text) const {
    if (choices.empty()) return "";
    for (const auto& c : choices)
      if (c == text) return "";
    return name + " must be one of " + joined(choices, ", ") + ", got '" + text + "'";
  }

  /// The accepted values for people: "1 … 254 grey levels", "over 0, up to 1000000 (rad/s)^2",
  /// "0 (per frame) or 8 … 16", "true, false", "vote, paper", "any text"; `to` joins a range's ends.
  std::string acceptedText(const std::string& to = " … ") const {
    std::string text;
    switch (type) {
      case SettingType::kBool: return "true, false";
      case SettingType::kString: return choices.empty() ? "any text" : joined(choices, ", ");
      case SettingType::kDoubleList: text = "numbers in "; break;
      default: break;
    }
    if (has_special) text += formatNumber(special) + " (" + special_doc + ") or ";
    text += min_exclusive ? "over " + formatNumber(min) + ", up to " + formatNumber(max)
                          : formatNumber(min) + to + formatNumber(max);
    return unit.empty() ? text : text + " " + unit;
  }

  /// Shortest text that reads back as the same double.
  static std::string formatNumber(double v) {
    // Whole numbers as integers (10000000, not 1e+07).
    if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e15) return std::to_string(static_cast<long long>(v));
    if (!std::isfinite(v)) return std::isnan(v) ? "nan" : (v > 0 ? "inf" : "-inf");
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

  /// `parts` joined with `separator`.
  static std::string joined(const std::vector<std::string>& parts, const std::string& separator) {
    std::string text;
    for (const auto& p : parts) text += (text.empty() ? "" : separator) + p;
    return text;
  }
};

/// The numbers of a setting's value, without a copy: one for kInt, kDouble, kBool (0/1), the
/// elements of a kDoubleList (pointing into the settings, so valid while they are), none for text.
/// A view rather than a std::vector so that reading them allocates nothing: the front end and the
/// estimator validate their settings on every call.
struct SettingNumbers {
  double single = 0.0;
  bool has_single = false;
  const std::vector<double>* list = nullptr;  ///< kDoubleList: the member itself

  static SettingNumbers none() { return {}; }
  static SettingNumbers one(double v) { return {v, true, nullptr}; }
  static SettingNumbers of(const std::vector<double>& values) { return {0.0, false, &values}; }
  const double* begin() const { return list != nullptr ? list->data() : &single; }
  const double* end() const { return list != nullptr ? list->data() + list->size() : &single + (has_single ? 1 : 0); }
};

/// One setting of a settings struct S: its spec and the code that reads and writes it.
template <class S>
struct SettingField : SettingSpec {
  /// The value of `settings` as text (numbers as the shortest exact decimal, bools true/false,
  /// lists as [a, b]).
  std::function<std::string(const S&)> text;
  /// Parses `value` and stores it; returns "" or why the text is not a value of this type. The
  /// range is checked by checkRange, not here, so that a caller can report it separately.
  std::function<std::string(S*, const std::string&)> parse;
  /// The value as numbers (SettingNumbers: one for kInt, kDouble, kBool, the elements of
  /// kDoubleList, none for text).
  std::function<SettingNumbers(const S&)> numbers;

  /// "" when the value in `settings` is accepted (checkNumber, checkChoice), else a message naming
  /// the setting, its value, what is accepted and the unit. An accepted value allocates nothing
  /// (the message and the value's text are built only for a refused one).
  std::string checkRange(const S& settings) const {
    if (type == SettingType::kString) return choices.empty() ? std::string() : checkChoice(text(settings));
    if (type == SettingType::kBool) return "";
    for (const double v : numbers(settings)) {
      if (acceptsNumber(v)) continue;
      return checkNumber(v, type == SettingType::kDoubleList ? text(settings) : formatNumber(v));
    }
    return "";
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

inline std::string parseRealList(const std::string& text, std::vector<double>* out) {
  // "[a, b, c]", "a, b, c" or "a b c"; "[]" and "" are the empty list.
  std::string body = text;
  const size_t first = body.find_first_not_of(" \t");
  const size_t last = body.find_last_not_of(" \t");
  body = first == std::string::npos ? "" : body.substr(first, last - first + 1);
  if (!body.empty() && body.front() == '[') {
    if (body.back() != ']') return "'" + text + "' is not a list of numbers";
    body = body.substr(1, body.size() - 2);
  }
  std::replace(body.begin(), body.end(), ',', ' ');
  std::istringstream in(body);
  std::vector<double> values;
  std::string item;
  while (in >> item) {
    double v = 0.0;
    if (!parseReal(item, &v).empty()) return "'" + text + "' is not a list of numbers";
    values.push_back(v);
  }
  *out = values;
  return "";
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
  f.numbers = [member](const S& s) { return SettingNumbers::one(s.*member); };
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
  f.numbers = [member](const S& s) { return SettingNumbers::one(static_cast<double>(s.*member)); };
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
  f.numbers = [member](const S& s) { return SettingNumbers::one(s.*member ? 1.0 : 0.0); };
  f.parse = [member](S* s, const std::string& v) {
    bool x = false;
    const std::string why = setting_detail::parseBoolean(v, &x);
    if (why.empty()) s->*member = x;
    return why;
  };
  return f;
}

/// A text member: one of `choices`, or any text when `choices` is empty.
template <class S>
SettingField<S> stringField(std::string name, std::string S::*member, std::vector<std::string> choices,
                            std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kString;
  f.choices = std::move(choices);
  f.doc = std::move(doc);
  f.text = [member](const S& s) { return s.*member; };
  f.numbers = [](const S&) { return SettingNumbers::none(); };
  f.parse = [member](S* s, const std::string& v) {
    s->*member = v;
    return std::string();
  };
  return f;
}

/// A list of doubles, each valid in [min, max] (any length).
template <class S>
SettingField<S> doubleListField(std::string name, std::vector<double> S::*member, double min, double max,
                                std::string unit, std::string doc) {
  SettingField<S> f;
  f.name = std::move(name);
  f.type = SettingType::kDoubleList;
  f.min = min;
  f.max = max;
  f.unit = std::move(unit);
  f.doc = std::move(doc);
  f.live = false;
  f.text = [member](const S& s) {
    std::vector<std::string> items;
    for (const double v : s.*member) items.push_back(SettingField<S>::formatNumber(v));
    return "[" + SettingSpec::joined(items, ", ") + "]";
  };
  f.numbers = [member](const S& s) { return SettingNumbers::of(s.*member); };
  f.parse = [member](S* s, const std::string& v) {
    std::vector<double> x;
    const std::string why = setting_detail::parseRealList(v, &x);
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
  f.numbers = [](const S&) { return SettingNumbers::none(); };
  const SettingSpec spec = f;
  f.parse = [member, names, spec](S* s, const std::string& v) {
    for (const auto& n : names) {
      if (n.first == v) {
        s->*member = n.second;
        return std::string();
      }
    }
    return spec.checkChoice(v);
  };
  return f;
}

/// The same field seen from an outer struct O through its member `part` (e.g. the estimator's
/// settings inside the pipeline's).
template <class O, class S>
SettingField<O> nestedField(const SettingField<S>& inner, S O::*part) {
  SettingField<O> f;
  static_cast<SettingSpec&>(f) = inner;
  const auto text = inner.text;
  const auto numbers = inner.numbers;
  const auto parse = inner.parse;
  f.text = [text, part](const O& o) { return text(o.*part); };
  f.numbers = [numbers, part](const O& o) { return numbers(o.*part); };
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

/// Sets the setting `name` of `settings` from text through the gate every setting goes through:
/// "" when `value` parses and is accepted (checkRange), else why, naming the setting (and
/// *settings is unchanged).
template <class S>
std::string applyField(S* settings, const std::vector<SettingField<S>>& fields, const std::string& name,
                       const std::string& value) {
  for (const auto& f : fields) {
    if (f.name != name) continue;
    S changed = *settings;
    std::string why = f.parse(&changed, value);
    if (!why.empty()) return why.find(name) == std::string::npos ? name + ": " + why : why;
    why = f.checkRange(changed);
    if (!why.empty()) return why;
    *settings = changed;
    return "";
  }
  return "unknown setting '" + name + "'";
}

/// One row of a settings table for people: a setting and its default as text.
struct SettingRow {
  const SettingSpec* spec = nullptr;
  std::string default_text;
};

/// The rows of `fields` with their values in `defaults`, in table order.
template <class S>
std::vector<SettingRow> settingRows(const std::vector<SettingField<S>>& fields, const S& defaults) {
  std::vector<SettingRow> rows;
  for (const auto& f : fields) rows.push_back({&f, f.text(defaults)});
  return rows;
}

/// A Markdown table of `rows`: setting, default, accepted values, (with `with_live`: "live" or
/// "at start"), meaning. Every name in backquotes.
inline std::string settingsMarkdown(const std::vector<SettingRow>& rows, bool with_live) {
  std::ostringstream out;
  out << "| setting | default | accepted |" << (with_live ? " changes |" : "") << " meaning |\n"
      << "| --- | --- | --- |" << (with_live ? " --- |" : "") << " --- |\n";
  for (const SettingRow& r : rows) {
    const std::string value = r.default_text.empty() ? "\"\"" : r.default_text;
    out << "| `" << r.spec->name << "` | " << value << " | " << r.spec->acceptedText() << " |"
        << (with_live ? (r.spec->live ? " live |" : " at start |") : "") << " " << r.spec->doc << " |\n";
  }
  return out.str();
}

/// `rows` as one Markdown table per tier (user, expert, paper-only; a tier without rows left out),
/// each under a bold label ("**user settings**"), with the live column.
inline std::string tieredSettingsMarkdown(const std::vector<SettingRow>& rows) {
  std::string text;
  for (const SettingTier tier : {SettingTier::kUser, SettingTier::kExpert, SettingTier::kPaperOnly}) {
    std::vector<SettingRow> part;
    for (const SettingRow& r : rows)
      if (r.spec->tier == tier) part.push_back(r);
    if (part.empty()) continue;
    if (!text.empty()) text += "\n";
    text += std::string("**") + settingTierName(tier) + " settings**\n\n" + settingsMarkdown(part, true);
  }
  return text;
}

}  // namespace visual_gyro
