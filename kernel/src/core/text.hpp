// core/text.hpp (internal) — the one place the kernel formats values for its messages and
// rejects a bad field. Every module's validation goes through it, so that every message
// reads the same way: "<where>.<field> must be <rule>, got <value>", with the value as the
// shortest decimal that reads back as the same double ("0.1", "-1", "1e-09", "nan",
// "inf"), so a message shows the value the user wrote.
#pragma once

#include <Eigen/Core>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <string_view>

#include "weft/core/types.hpp"

namespace weft::detail {

/// `bytes` quoted from a file in a message: printable ASCII as it is, every other byte as
/// \xNN, at most `max` bytes ("..." after a cut).
inline std::string escaped(std::string_view bytes, size_t max = std::string_view::npos) {
  std::string out;
  for (size_t k = 0; k < bytes.size() && k < max; ++k) {
    const unsigned char u = static_cast<unsigned char>(bytes[k]);
    if (u >= 32 && u < 127) {
      out += static_cast<char>(u);
    } else {
      char hex[8];
      std::snprintf(hex, sizeof hex, "\\x%02x", u);
      out += hex;
    }
  }
  if (bytes.size() > max) out += "...";
  return out;
}

/// Shortest round-trip text of v.
inline std::string number(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, result.ptr);
}

/// "(x, y, z)", each coordinate as number() writes it.
inline std::string number3(double x, double y, double z) {
  // Appended piece by piece (a chain of operator+ on temporaries trips GCC 12's -Wrestrict).
  std::string out = "(";
  out += number(x);
  out += ", ";
  out += number(y);
  out += ", ";
  out += number(z);
  out += ")";
  return out;
}
inline std::string number3(const Vec3d& v) { return number3(v.x, v.y, v.z); }
inline std::string number3(const Eigen::Vector3d& v) { return number3(v.x(), v.y(), v.z()); }

/// Throws std::invalid_argument("<field> must be <rule>, got <value>"); `field` carries its
/// place ("ModelBuilder::addSpring: stiffness of spring [3]", "effects.wind.gustModes").
[[noreturn]] inline void rejectField(std::string_view field, std::string_view value, std::string_view rule) {
  std::string msg(field);
  msg += " must be ";
  msg += rule;
  msg += ", got ";
  msg += value;
  throw std::invalid_argument(msg);
}
[[noreturn]] inline void rejectField(std::string_view field, double value, std::string_view rule) {
  rejectField(field, number(value), rule);
}
/// Whether a velocity is within kMaxSpeed (weft/core/types.hpp), and what that requires, as
/// messages say it.
/// (A speed within it is within the range of float too: velocities need no range check of
/// their own.)
/// (The sum of squares accepts a speed clearly within it, far from overflow and with a
/// margin far wider than its rounding; hypot, slow but exact, decides the rest.)
inline bool speedWithinLimit(double x, double y, double z) {
  constexpr double kClearly = 0.999 * kMaxSpeed;
  if (x * x + y * y + z * z <= kClearly * kClearly) return true;
  return std::hypot(x, y, z) <= kMaxSpeed;
}
static_assert(kMaxSpeed < 3.4e38, "kMaxSpeed is within float's range");
inline std::string speedRule() { return "a speed of at most " + number(kMaxSpeed) + " m/s (the speed of light)"; }
/// rejectField unless `ok`.
inline void requireField(bool ok, std::string_view field, double value, std::string_view rule) {
  if (!ok) rejectField(field, value, rule);
}

}  // namespace weft::detail
