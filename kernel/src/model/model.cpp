#include "weft/model/model.hpp"

namespace weft {

const char* springClassName(SpringClass c) {
  switch (c) {
    case SpringClass::Structural:
      return "structural";
    case SpringClass::Shear:
      return "shear";
    case SpringClass::Bend:
      return "bend";
  }
  return "unknown";
}

template <class S>
Index Model<S>::pinnedCount() const {
  Index count = 0;
  for (Index i = 0; i < particleCount(); ++i) count += isPinned(i) ? 1 : 0;
  return count;
}

template <class S>
std::array<Index, kSpringClassCount> Model<S>::springCountByClass() const {
  std::array<Index, kSpringClassCount> counts{};
  for (SpringClass c : springs_.kind) ++counts[static_cast<int>(c)];
  return counts;
}

template class Model<float>;
template class Model<double>;

}  // namespace weft
