// text.hpp — numbers in the kernel's messages (private to kernel/src): one format for
// every module, the shortest decimal that reads back as the same double ("0.1", "-1",
// "1e-09", "nan", "inf"), so a message shows the value the user wrote.
#pragma once

#include <charconv>
#include <string>

namespace weft::detail {

inline std::string number(double v) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof buffer, v);
  return std::string(buffer, result.ptr);
}

}  // namespace weft::detail
