// rigid_text.hpp — numbers in the rigid module's messages (private to kernel/src/rigid).
#pragma once

#include <Eigen/Core>
#include <charconv>
#include <string>

#include "../core/text.hpp"

namespace weft::rigid_detail {

/// Shortest round-trip text of v ("-1", "0.1", "nan").
inline std::string formatNumber(double v) { return detail::number(v); }

/// "(x, y, z)".
inline std::string formatVector(const Eigen::Vector3d& v) {
  // Appended piece by piece (a chain of operator+ on temporaries trips GCC 12's -Wrestrict).
  std::string out = "(";
  out += formatNumber(v.x());
  out += ", ";
  out += formatNumber(v.y());
  out += ", ";
  out += formatNumber(v.z());
  out += ")";
  return out;
}

}  // namespace weft::rigid_detail
