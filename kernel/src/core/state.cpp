#include "weft/core/state.hpp"

#include <cstddef>
#include <cstring>

namespace weft {

namespace {
std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t bytes) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (std::size_t i = 0; i < bytes; ++i) {
    h ^= p[i];
    h *= 1099511628211ull;
  }
  return h;
}
}  // namespace

template <class S>
std::uint64_t stateHash(const State<S>& state) {
  std::uint64_t h = 14695981039346656037ull;
  const std::uint64_t n = static_cast<std::uint64_t>(state.x.rows());
  h = fnv1a(h, &n, sizeof n);
  h = fnv1a(h, state.x.data(), sizeof(S) * static_cast<std::size_t>(state.x.size()));
  h = fnv1a(h, state.v.data(), sizeof(S) * static_cast<std::size_t>(state.v.size()));
  return h;
}

template std::uint64_t stateHash(const State<float>&);
template std::uint64_t stateHash(const State<double>&);

}  // namespace weft
