// weft/effects/spring_jacobian.hpp — matrix-free products with the springs' Jacobians,
// for implicit integration.
//
// Design note
// -----------
// Backward Euler linearised once per step (Baraff & Witkin, "Large steps in cloth
// simulation", SIGGRAPH 1998) solves
//
//     A dv = b,   A = M - h df/dv - h^2 df/dx,   b = h f0 + h^2 (df/dx) v0
//
// (a viscous drag -c v on the particles, ParticleEffects::drag, adds h c I to A).
//
// A is never formed. For a spring s = (a, b) with unit direction d = (x_a - x_b) / L,
//
//     -df_a/dx_a = ks [ d d^T + c (I - d d^T) ],  c = max(0, 1 - r / L)
//     -df_a/dv_a = kd d d^T
//
// (the damping force's dependence on x is dropped, as Baraff & Witkin do; c is clamped
// at 0 so that a compressed spring contributes no negative stiffness and A stays
// symmetric positive definite: the usual definiteness fix, after Choi & Ko 2002). With
// u = p_a - p_b, the spring adds g = alpha u + (beta + gamma) d (d . u) to (A p)_a and
// -g to (A p)_b, where alpha = h^2 ks c, beta = h^2 ks (1 - c), gamma = h kd. linearize()
// caches d, alpha, beta per spring once per step, the spring's block alpha I + (beta + gamma)
// d d^T (for A's diagonal blocks and a multigrid's coarse operators: six contiguous numbers
// a spring, read through the incidence lists), and v = sqrt(beta + gamma) d: the
// system product takes g = alpha u + v (v . u), four numbers a spring to stream instead of
// six (17 % less time per product on the 128^2 flag, one thread; the products are bound by
// memory, not arithmetic). Each product is then one pass
// over the springs (g into a per-spring buffer) and one pass over the particles summing
// +-g over a fixed CSR incidence list, exactly like the Gather force strategy: the same
// order for any thread count, so products are bitwise reproducible. The result is handed
// to a sink block by block (blocks of ForceField::kSinkBlock particles), so the caller can
// fuse its own per-particle work (and per-block reductions) into the same pass.
//
// On a model built as a regular grid (Model::grid()) the products run through the grid
// stencil instead, like the GridStencil force strategy: per chunk of particles, per family
// and row, the springs' products are computed from contiguous loads into the thread's
// window, indexed by the spring's first particle (zero where no spring starts), and
// particle i then sums +g_k[i] - g_k[i - offset_k] over the families in their fixed order:
// no index lists, the same order for any thread count, and a window that stays in the
// core's cache (the springs of the rows above a chunk that its gather reaches are computed by
// both chunks). A sink runs while other chunks still read p: it must not write p.
//
// Everything else is sized at construction; the windows, one per thread, by reserve() (or
// by the first product). linearize() and the products then never allocate.
#pragma once

#include <vector>

#include "weft/effects/force_field.hpp"

namespace weft {

template <class S>
class SpringJacobian {
 public:
  /// `model` must outlive the SpringJacobian.
  explicit SpringJacobian(const Model<S>& model);

  /// Caches the springs' linearisation at positions x for a step h (s), and the diagonal
  /// blocks of A (for a Jacobi or block-Jacobi preconditioner). `drag` (N s/m) is a viscous drag -c v on every
  /// particle: it adds h c I to A (ParticleEffects::drag; 0 = none).
  void linearize(const Vec3Array<S>& x, S h, const Executor& exec, S drag = 0);

  /// Hands (A p) to `sink` block by block: A = M - h df/dv - h^2 df/dx at the
  /// linearisation. p is (n x 3); rows of pinned particles are not special-cased here.
  /// The sink must not write p (blocks may run while others still read it).
  void systemProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec);
  /// Hands (-h^2 df/dx) p to `sink` block by block (no mass, no damping term).
  void stiffnessProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec);

  /// Diagonal of A at the linearisation, (n x 3), kg.
  const Vec3Array<S>& diagonal() const { return diagonal_; }
  /// Off-diagonal entries (xy, xz, yz) of each particle's 3x3 diagonal block of A, (n x 3),
  /// kg: with diagonal(), the blocks a block-Jacobi preconditioner inverts.
  const Vec3Array<S>& offDiagonal() const { return offDiagonal_; }
  const Model<S>& model() const { return *model_; }

  /// Makes the grid stencil's windows, one per thread of `exec` (a product makes them
  /// itself if this was not called, or for more threads); nothing on other models.
  void reserve(const Executor& exec);

  /// The linearisation per spring (indexed like Model::springs()): spring s couples its
  /// ends through the symmetric positive semi-definite 3x3 block
  /// B_s = alpha I + (beta + gamma) d d^T (kg; d its unit direction, alpha = h^2 ks c,
  /// beta = h^2 ks (1 - c), gamma = h kd), stored as six numbers a spring, xx yy zz xy xz yz,
  /// at blocks() + 6 s. A's diagonal block of a particle is its mass (plus the drag term)
  /// times I plus the blocks of its springs; a multigrid preconditioner sums the blocks into
  /// its coarse operators.
  const S* blocks() const { return blocks_.data(); }
  /// The springs' unit directions d, (m x 3) (0 for a spring of length 0).
  const Vec3Array<S>& directions() const { return direction_; }
  /// h c, kg: the drag's share of each particle's diagonal.
  S dragTerm() const { return dragTerm_; }

 private:
  template <bool kSystem>
  void product(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec);

  template <bool kSystem>
  void gridProduct(const Vec3Array<S>& p, const AccelerationSink<S>& sink, const Executor& exec);

  const Model<S>* model_;
  const Incidence* incidence_ = nullptr;  // the Model's particle -> spring lists (entry 2 s + side)
  Vec3Array<S> direction_;                // (m x 3) unit direction d of each spring (0 if length 0)
  Vec3Array<S> scaled_;                   // (m x 3) sqrt(beta + gamma) d, for the system product
  ScalarArray<S> alpha_;                  // (m) h^2 ks c, kg
  ScalarArray<S> beta_;                   // (m) h^2 ks (1 - c), kg
  std::vector<S> blocks_;                 // (6 m) B_s per spring: xx yy zz xy xz yz, kg
  Vec3Array<S> g_;                        // (m x 3) per-spring product, on endpoint a (0 rows on grid models)
  Vec3Array<S> diagonal_;                 // (n x 3) diag(A)
  Vec3Array<S> offDiagonal_;              // (n x 3) xy, xz, yz of A's diagonal blocks
  S dragTerm_ = 0;                        // h c, kg (the drag's share of A's diagonal)
  size_t windowCount(const Executor& exec) const;
  // Grid models: per thread, a window per family and axis of gridWindow_ slots: the
  // product of the spring starting at each particle of a chunk's rows (and the rows above
  // it that its gather reaches), after gridPad_ leading zeros (gridProduct).
  std::vector<S> gridWindows_;
  std::vector<Index> gridOffset_;  // per family: rowOffset W + columnOffset
  Index gridPad_ = 0;              // the largest offset
  Index gridChunk_ = 0;            // particles per task, whole sink blocks
  Index gridWindow_ = 0;           // slots per family and axis
};

extern template class SpringJacobian<float>;
extern template class SpringJacobian<double>;

}  // namespace weft
