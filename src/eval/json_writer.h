// The one JSON writer of the package: flat or nested objects, keys in insertion order, numbers as
// %.6g, NaN and infinity as null. Plain C++, header-only (the ROS summaries and the stand-alone
// tools use it too).
#pragma once

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

namespace visual_gyro {

/// A JSON object being written.
class JsonObject {
 public:
  JsonObject& add(const std::string& key, const std::string& value) { return raw(key, quote(value)); }
  JsonObject& add(const std::string& key, const char* value) { return add(key, std::string(value)); }
  JsonObject& add(const std::string& key, double value) { return raw(key, number(value)); }
  JsonObject& add(const std::string& key, int value) { return raw(key, std::to_string(value)); }
  JsonObject& add(const std::string& key, long long value) { return raw(key, std::to_string(value)); }
  JsonObject& add(const std::string& key, bool value) { return raw(key, value ? "true" : "false"); }
  JsonObject& add(const std::string& key, const JsonObject& value) { return raw(key, value.str()); }
  /// An array of numbers (each as number() writes it).
  JsonObject& add(const std::string& key, const std::vector<double>& values) {
    std::string list;
    for (const double v : values) list += (list.empty() ? "" : ", ") + number(v);
    return raw(key, "[" + list + "]");
  }
  /// null: a value that does not exist (e.g. not observable).
  JsonObject& addNull(const std::string& key) { return raw(key, "null"); }
  /// The object as one line of text.
  std::string str() const { return "{" + body_ + "}"; }

  /// A number as JSON writes it here: %.6g, null when not finite.
  static std::string number(double v) {
    if (!std::isfinite(v)) return "null";
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.6g", v);
    return buf;
  }
  /// A string quoted and escaped for JSON.
  static std::string quote(const std::string& s) {
    std::string out = "\"";
    for (const char c : s) {
      switch (c) {
        case '"': out += "\\\""; break;
        case '\\': out += "\\\\"; break;
        case '\n': out += "\\n"; break;
        case '\t': out += "\\t"; break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof(buf), "\\u%04x", c);
            out += buf;
          } else {
            out += c;
          }
      }
    }
    return out + "\"";
  }

 private:
  JsonObject& raw(const std::string& key, const std::string& value) {
    if (!body_.empty()) body_ += ", ";
    body_ += quote(key) + ": " + value;
    return *this;
  }
  std::string body_;
};

}  // namespace visual_gyro
