// Internal: a symmetric 3x3 block (a particle's diagonal block of implicit Euler's matrix,
// a spring's coupling block), in double: the block-Jacobi preconditioner and the multigrid
// preconditioner's levels share it. The functions have internal linkage, so each file
// keeps its own floating-point contraction setting (kernel/CMakeLists.txt).
#pragma once

#include <cmath>

namespace weft::detail {

struct SymmetricBlock {
  double xx = 0, yy = 0, zz = 0, xy = 0, xz = 0, yz = 0;
};

/// y = B x.
static inline void multiply(const SymmetricBlock& m, const double* x, double* y) {
  y[0] = m.xx * x[0] + m.xy * x[1] + m.xz * x[2];
  y[1] = m.xy * x[0] + m.yy * x[1] + m.yz * x[2];
  y[2] = m.xz * x[0] + m.yz * x[1] + m.zz * x[2];
}

/// to += b.
static inline void add(SymmetricBlock& to, const SymmetricBlock& b) {
  to.xx += b.xx;
  to.yy += b.yy;
  to.zz += b.zz;
  to.xy += b.xy;
  to.xz += b.xz;
  to.yz += b.yz;
}

/// The inverse of a symmetric positive definite block by cofactors; zero if the block is
/// not definite (determinant <= 0 or not finite).
static inline SymmetricBlock inverse(const SymmetricBlock& m) {
  const double cxx = m.yy * m.zz - m.yz * m.yz, cyy = m.xx * m.zz - m.xz * m.xz, czz = m.xx * m.yy - m.xy * m.xy;
  const double cxy = m.xz * m.yz - m.xy * m.zz, cxz = m.xy * m.yz - m.xz * m.yy, cyz = m.xy * m.xz - m.xx * m.yz;
  const double det = m.xx * cxx + m.xy * cxy + m.xz * cxz;
  const double f = det > 0 && std::isfinite(det) ? 1.0 / det : 0.0;
  return {f * cxx, f * cyy, f * czz, f * cxy, f * cxz, f * cyz};
}

}  // namespace weft::detail
