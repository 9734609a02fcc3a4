// io_text.hpp — numbers and vectors in weft::io's messages (private to weft::io): one
// spelling for every file of the library, the shortest decimal that reads back as the
// value, so that a message shows 0.1 where the file or the caller gave 0.1.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <string>

#include "../core/text.hpp"
#include "weft/core/types.hpp"

namespace weft::io_detail {

/// The shortest decimal that reads back as v: "0.1", "1e-09", "200".
inline std::string fmt(double v) { return detail::number(v); }

inline std::string fmt(const Vec3d& v) {
  std::string s = "[";  // (appended, not "[" + ...: GCC 12 warns about that falsely, -Wrestrict)
  s += fmt(v.x);
  s += ", ";
  s += fmt(v.y);
  s += ", ";
  s += fmt(v.z);
  s += "]";
  return s;
}

}  // namespace weft::io_detail
