// json_reader.hpp — the strict JSON walker of weft::io's scene files (private to weft::io).
//
// Reader knows the path of every value it reads and rejects unknown keys, wrong types,
// non-finite numbers and out-of-range values with the source, the field path and the
// value in the message; where a range is the kernel's, Reader::kernelRules runs the
// kernel's validator and reports what it refuses the same way, so that the rule lives
// once. JsonPathTracker follows nlohmann's parser to name the field of a syntax error and
// rejects duplicate keys and deep nesting.
#pragma once

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <initializer_list>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "io_text.hpp"
#include "weft/io/scene.hpp"

namespace weft::io_detail {

using Json = nlohmann::json;

constexpr std::size_t kMaxJsonDepth = 32;  // a scene nests 7 levels deep

/// A value for a message: compact JSON, ASCII only (so cutting it never splits a
/// character), at most 60 characters. Integers appear as written in the file, other
/// numbers as nlohmann prints them (-3.0, 1e-05).
inline std::string shortDump(const Json& j) {
  std::string s = j.dump(-1, ' ', /*ensure_ascii=*/true);
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

/// A key as it appears in a field path: as is when it is a plain name, else quoted and
/// escaped (a key may hold anything, newlines included).
inline std::string displayKey(const std::string& key) {
  const bool plain = !key.empty() && key.size() <= 40 && std::all_of(key.begin(), key.end(), [](unsigned char c) {
    return std::isalnum(c) || c == '_' || c == '-';
  });
  return plain ? key : shortDump(Json(key));
}

inline const char* typeName(const Json& j) { return j.type_name(); }

/// A number of a JSON text that is not zero as written but may read as 0 in a double (below
/// about 2.5e-324 in magnitude), found by its decimal order: `ordinal` counts the text's
/// numbers from 0.
struct TinyNumber {
  std::size_t ordinal;
  std::string text;
};

/// The numbers of `text` (outside strings) whose first non-zero digit is below 1e-300:
/// the only ones that can underflow to 0. nlohmann reads those as 0 without a word, and a
/// rule would then report "got 0" for a value the file does not hold.
inline std::vector<TinyNumber> tinyNumbers(std::string_view text) {
  std::vector<TinyNumber> out;
  std::size_t ordinal = 0;
  const auto digit = [](char c) { return c >= '0' && c <= '9'; };
  for (std::size_t i = 0; i < text.size();) {
    if (text[i] == '"') {  // a string (a key or a value): its digits are no number
      for (++i; i < text.size() && text[i] != '"'; ++i)
        if (text[i] == '\\') ++i;
      ++i;
      continue;
    }
    if (text[i] != '-' && !digit(text[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < text.size() &&
           (digit(text[j]) || text[j] == '-' || text[j] == '+' || text[j] == '.' || text[j] == 'e' || text[j] == 'E'))
      ++j;
    const std::string_view token = text.substr(i, j - i);
    i = j;
    // The decimal order of the first non-zero digit: its place in the mantissa, plus the exponent.
    const std::size_t e = std::min(token.find('e'), token.find('E'));
    const std::string_view mantissa = token.substr(0, e);
    const std::size_t point = std::min(mantissa.find('.'), mantissa.size());
    long long first = 0;
    bool nonZero = false;
    for (std::size_t k = 0; k < mantissa.size() && !nonZero; ++k) {
      if (!digit(mantissa[k])) continue;
      if (mantissa[k] != '0') {
        nonZero = true;
        first = (k < point ? static_cast<long long>(point - k) - 1 : -static_cast<long long>(k - point));
      }
    }
    long long exponent = 0;
    if (e != std::string_view::npos) {
      std::size_t k = e + 1;
      const bool negative = k < token.size() && token[k] == '-';
      if (k < token.size() && (token[k] == '-' || token[k] == '+')) ++k;
      for (; k < token.size() && digit(token[k]); ++k)
        exponent = std::min(exponent * 10 + (token[k] - '0'), 1000000000000000LL);
      if (negative) exponent = -exponent;
    }
    if (nonZero && first + exponent < -300)
      out.push_back({ordinal, token.size() <= 60 ? std::string(token) : std::string(token.substr(0, 57)) + "..."});
    ++ordinal;
  }
  return out;
}

/// Follows nlohmann's parser (as its parse callback) so that a syntax error can name the
/// field it happened in (the parser itself gives only a line and column, or for a number
/// that overflows, like 1e999, nothing). Also rejects what the DOM would hide or what
/// later code should not have to survive: a key given twice in one object (nlohmann keeps
/// the last silently), nesting deeper than kMaxJsonDepth, and a number that is not zero as
/// written but reads as 0 (1e-400; nlohmann gives 0 without a word).
class JsonPathTracker {
 public:
  JsonPathTracker(const std::string& source, std::string_view text) : source_(source), tiny_(tinyNumbers(text)) {}

  bool operator()(int /*depth*/, Json::parse_event_t event, Json& parsed) {
    switch (event) {
      case Json::parse_event_t::object_start:
      case Json::parse_event_t::array_start:
        if (stack_.size() >= kMaxJsonDepth)
          throw SceneError(source_ + ": " + where() + ": nesting deeper than " + std::to_string(kMaxJsonDepth) +
                           " levels: not a scene");
        stack_.push_back({event == Json::parse_event_t::array_start, 0, {}, false, {}});
        break;
      case Json::parse_event_t::key: {
        Frame& f = stack_.back();
        f.key = parsed.get<std::string>();
        f.keyed = true;
        if (!f.keys.insert(f.key).second)
          throw SceneError(source_ + ": " + where() + ": duplicate key: each key may appear once in an object");
        break;
      }
      case Json::parse_event_t::value:
        if (parsed.is_number()) {
          if (nextTiny_ < tiny_.size() && tiny_[nextTiny_].ordinal == numbers_) {
            if (parsed.is_number_float() && parsed.get<double>() == 0)
              throw SceneError(source_ + ": " + where() + ": the number " + tiny_[nextTiny_].text +
                               " is too small for a double and would be read as 0 (the smallest is about 4.9e-324): "
                               "write 0 if 0 is meant");
            ++nextTiny_;
          }
          ++numbers_;
        }
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
        break;
      case Json::parse_event_t::object_end:
      case Json::parse_event_t::array_end:
        stack_.pop_back();
        if (!stack_.empty() && stack_.back().array) ++stack_.back().index;
        break;
    }
    return true;
  }

  /// Path of the value being read (or just read): "bodies[0].materials.bend".
  std::string path() const {
    std::string p;
    for (const Frame& f : stack_) {
      // Appended piece by piece (operator+ on temporaries trips GCC 12's -Wrestrict).
      if (f.array) {
        p += '[';
        p += std::to_string(f.index);
        p += ']';
      } else if (f.keyed) {
        if (!p.empty()) p += '.';
        p += displayKey(f.key);
      } else {
        break;
      }
    }
    return p;
  }

 private:
  struct Frame {
    bool array;
    std::size_t index;  // arrays: the element being read
    std::string key;    // objects: the member being read
    bool keyed;
    std::set<std::string> keys;
  };
  std::string where() const {
    const std::string p = path();
    return p.empty() ? "(top level)" : p;
  }
  const std::string& source_;
  std::vector<Frame> stack_;
  std::vector<TinyNumber> tiny_;
  std::size_t nextTiny_ = 0;  // the first of tiny_ not yet reached
  std::size_t numbers_ = 0;   // numbers parsed so far
};

/// v / |v| exactly as weft's builders compute it (addRope, addClothGrid); false when |v|
/// is 0 or not finite.
inline bool normalised(const Vec3d& v, Vec3d& out) {
  const double len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  if (!(std::isfinite(len) && len > 0)) return false;
  out = {v.x / len, v.y / len, v.z / len};
  return true;
}

inline bool finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

class Reader {
 public:
  explicit Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void fail(const std::string& field, const std::string& what) const {
    throw SceneError(source_ + ": " + (field.empty() ? std::string("(top level)") : field) + ": " + what);
  }

  /// Checks that `j` is an object whose keys are all in `allowed`.
  void object(const Json& j, const std::string& field, std::initializer_list<const char*> allowed) const {
    if (!j.is_object()) fail(field, std::string("must be an object, got ") + typeName(j) + " " + shortDump(j));
    std::set<std::string> known(allowed.begin(), allowed.end());
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (known.count(it.key())) continue;
      std::string list;
      for (const char* k : allowed) list += (list.empty() ? "" : ", ") + std::string(k);
      fail(join(field, displayKey(it.key())), "unknown key; allowed keys here: " + list);
    }
  }

  static std::string join(const std::string& field, const std::string& key) {
    return field.empty() ? key : field + "." + key;
  }

  double number(const Json& j, const std::string& field) const {
    if (!j.is_number()) fail(field, std::string("must be a number, got ") + typeName(j) + " " + shortDump(j));
    const double v = j.get<double>();
    if (!std::isfinite(v)) fail(field, "must be finite, got " + shortDump(j));
    return v;
  }
  double number(const Json& parent, const std::string& field, const char* key, double fallback, double low,
                bool lowInclusive, const char* unit) const {
    if (!parent.contains(key)) return fallback;
    const std::string f = join(field, key);
    const double v = number(parent[key], f);
    if (lowInclusive ? !(v >= low) : !(v > low))
      fail(f, std::string("must be ") + (lowInclusive ? ">= " : "> ") + fmt(low) + unit + ", got " +
                  shortDump(parent[key]));
    return v;
  }
  double anyNumber(const Json& parent, const std::string& field, const char* key, double fallback) const {
    return parent.contains(key) ? number(parent[key], join(field, key)) : fallback;
  }
  std::int64_t integer(const Json& parent, const std::string& field, const char* key, std::int64_t fallback,
                       std::int64_t low, std::int64_t high) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    const std::string f = join(field, key);
    if (!j.is_number_integer()) fail(f, std::string("must be an integer, got ") + typeName(j) + " " + shortDump(j));
    const std::string range = "must be in [" + std::to_string(low) + ", " + std::to_string(high) + "], got ";
    if (j.is_number_unsigned() && j.get<std::uint64_t>() > static_cast<std::uint64_t>(high))
      fail(f, range + shortDump(j));
    const std::int64_t v = j.get<std::int64_t>();
    if (v < low || v > high) fail(f, range + shortDump(j));
    return v;
  }
  /// An integer in int's range whose rule the kernel checks (kernelRules).
  int anyInt(const Json& parent, const std::string& field, const char* key, int fallback) const {
    return static_cast<int>(
        integer(parent, field, key, fallback, std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
  }
  bool boolean(const Json& parent, const std::string& field, const char* key, bool fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    if (!j.is_boolean())
      fail(join(field, key), std::string("must be true or false, got ") + typeName(j) + " " + shortDump(j));
    return j.get<bool>();
  }
  std::string string(const Json& parent, const std::string& field, const char* key, const std::string& fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    if (!j.is_string())
      fail(join(field, key), std::string("must be a string, got ") + typeName(j) + " " + shortDump(j));
    return j.get<std::string>();
  }
  /// A file or directory name: a non-empty string without NUL characters.
  std::string pathString(const Json& parent, const std::string& field, const char* key) const {
    const std::string v = string(parent, field, key, "");
    if (v.empty()) fail(join(field, key), "must not be empty");
    if (v.find('\0') != std::string::npos)
      fail(join(field, key), "must not contain a NUL character, got " + shortDump(parent[key]));
    return v;
  }
  std::string choice(const Json& parent, const std::string& field, const char* key, const std::string& fallback,
                     std::initializer_list<const char*> allowed) const {
    const std::string v = string(parent, field, key, fallback);
    for (const char* a : allowed)
      if (v == a) return v;
    std::string list;
    for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
    fail(join(field, key), "must be one of " + list + "; got " + shortDump(Json(v)));
  }
  Vec3d vector(const Json& parent, const std::string& field, const char* key, const Vec3d& fallback) const {
    if (!parent.contains(key)) return fallback;
    const Json& j = parent[key];
    const std::string f = join(field, key);
    if (!j.is_array() || j.size() != 3)
      fail(f, std::string("must be an array of 3 numbers [x, y, z], got ") + typeName(j) + " " + shortDump(j));
    return {number(j[0], f + "[0]"), number(j[1], f + "[1]"), number(j[2], f + "[2]")};
  }
  /// A direction: a vector of finite, non-zero length (normalised on use).
  Vec3d direction(const Json& parent, const std::string& field, const char* key, const Vec3d& fallback) const {
    const Vec3d v = vector(parent, field, key, fallback);
    Vec3d unit;
    if (parent.contains(key) && !normalised(v, unit))
      fail(join(field, key), "must be a direction (a vector of finite non-zero length), got " + shortDump(parent[key]));
    return v;
  }
  SpringMaterial material(const Json& parent, const std::string& field, const char* key,
                          const SpringMaterial& fallback) const {
    if (!parent.contains(key)) return fallback;
    const std::string f = join(field, key);
    const Json& j = parent[key];
    object(j, f, {"stiffness", "damping"});
    SpringMaterial m = fallback;
    m.stiffness = number(j, f, "stiffness", m.stiffness, 0, true, " N/m");
    m.damping = number(j, f, "damping", m.damping, 0, true, " N s/m");
    return m;
  }

  /// Runs `validate`, one of the kernel's validators or parsers (validateEffects,
  /// parseIntegrator, ...) on what this section of the file gave, so that a rule lives
  /// once, in the kernel: what it refuses (std::invalid_argument) becomes an error of the
  /// file (kernelFail).
  template <class Validate>
  void kernelRules(const Json& section, const std::string& field, const std::string& kernelPrefix, Validate&& validate,
                   std::initializer_list<std::pair<const char*, const char*>> renames = {}) const {
    try {
      validate();
    } catch (const std::invalid_argument& e) {
      kernelFail(section, field, kernelPrefix, e.what(), renames);
    }
  }

  /// A kernel's message "<member> must be <rule>, got <value>" as an error of the file. The
  /// member is a C++ path below `kernelPrefix` ("effects.wind.gustModes" below "effects.");
  /// in the file it is the same path below `field`, spelt as the file spells it: a name
  /// in `renames` as given there (a whole path: {"relativeTolerance", "rtol"}), any other
  /// in snake_case, ".x", ".y", ".z" as "[0]", "[1]", "[2]". The value is the file's as
  /// written where the file gave that member and the kernel's value is the same one, else
  /// the kernel's number in this file's spelling (fmt). A message of another shape is
  /// reported at `field` as it is, less `kernelPrefix`.
  [[noreturn]] void kernelFail(const Json& section, const std::string& field, const std::string& kernelPrefix,
                               const std::string& message,
                               std::initializer_list<std::pair<const char*, const char*>> renames = {}) const {
    const bool prefixed = message.compare(0, kernelPrefix.size(), kernelPrefix) == 0;
    const std::string rest = prefixed ? message.substr(kernelPrefix.size()) : message;
    const std::size_t must = rest.find(" must be ");
    std::string member = rest.substr(0, must);
    for (const auto& [kernel, file] : renames)
      if (member == kernel) member = file;
    const bool isPath =
        must != std::string::npos && !member.empty() && std::all_of(member.begin(), member.end(), [](unsigned char c) {
          return std::isalnum(c) || c == '_' || c == '.' || c == '[' || c == ']';
        });
    if (!prefixed || !isPath) fail(field, rest);
    // The member's path in the file's spelling, and its value in the file (if it gave it).
    std::string path = field;
    const Json* value = &section;
    const auto element = [&](std::size_t k) {
      path += '[';  // (appended piece by piece: operator+ on temporaries trips GCC 12's -Wrestrict)
      path += std::to_string(k);
      path += ']';
      value = value && value->is_array() && k < value->size() ? &(*value)[k] : nullptr;
    };
    for (std::size_t at = 0; at < member.size();) {
      if (member[at] == '.') {
        ++at;
        continue;
      }
      if (member[at] == '[') {
        element(std::strtoul(member.c_str() + at + 1, nullptr, 10));
        at = std::min(member.find(']', at), member.size() - 1) + 1;
        continue;
      }
      const std::size_t end = std::min(member.find_first_of(".[", at), member.size());
      const std::string name = member.substr(at, end - at);
      at = end;
      if (name == "x" || name == "y" || name == "z") {
        element(static_cast<std::size_t>(name[0] - 'x'));
        continue;
      }
      std::string key;
      for (const char c : name) {
        if (std::isupper(static_cast<unsigned char>(c))) {
          key += '_';
          key += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
        } else {
          key += c;
        }
      }
      path = join(path, key);
      value = value && value->is_object() && value->contains(key) ? &(*value)[key] : nullptr;
    }
    std::string what = rest.substr(must + 1);  // "must be <rule>, got <value>"
    const std::size_t got = what.rfind(" got ");
    if (got != std::string::npos) {
      const std::string kernelValue = what.substr(got + 5);
      std::string written;
      char* end = nullptr;
      const double number = std::strtod(kernelValue.c_str(), &end);
      const auto quoted = [&](const std::string& text) {  // 'text', as the kernel quotes names
        return kernelValue.size() == text.size() + 2 && kernelValue.front() == '\'' && kernelValue.back() == '\'' &&
               kernelValue.compare(1, text.size(), text) == 0;
      };
      if (value && value->is_string() && quoted(value->get<std::string>()))
        written = shortDump(*value);
      else if (!kernelValue.empty() && end == kernelValue.c_str() + kernelValue.size())
        written = value && value->is_number() && value->get<double>() == number ? shortDump(*value) : fmt(number);
      if (!written.empty()) {
        what.resize(got + 5);
        what += written;
      }
    }
    fail(path, what);
  }

 private:
  std::string source_;
};

}  // namespace weft::io_detail
