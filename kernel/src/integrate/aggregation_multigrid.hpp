// Internal: an aggregation multigrid cycle, implicit Euler's CG preconditioner
// Preconditioner::Multigrid.
//
// The system matrix of a linearised implicit Euler step is a block spring network:
//
//     A = sum_i (m_i + h c) I e_i e_i^T + sum_s (e_a - e_b)(e_a - e_b)^T (x) B_s,
//     B_s = alpha_s I + (beta_s + gamma_s) d_s d_s^T          (SpringJacobian)
//
// with every B_s symmetric positive semi-definite. Aggregating particles into groups and
// taking A_c = P^T A P with P piecewise constant (each particle moves with its group) gives
// a matrix of the same form on the groups: a group's mass is its members' mass, a spring
// inside a group drops out, and the springs between two groups add up to one coarse block.
// So every coarse operator is exact (Galerkin) and costs one addition per fine spring to
// build, every step, with no sparse matrix product. Springs to pinned particles (which the
// CG's filter keeps at dv = 0) become a "ground" block on their free end's group.
//
// Groups: on a grid model (Model::grid()) 2 x 2 blocks of the grid on every level; on any
// other model two rounds of pairwise matching by spring stiffness (Notay's pairwise
// aggregation) per level, about four particles a group. Levels are added until at most
// kCoarsestNodes groups remain, or a level fails to halve its nodes; the coarsest is solved
// exactly by a dense Cholesky factorisation (per step) when it has at most kDenseNodes
// nodes, else by five block-Jacobi sweeps. The pattern is built once, at construction;
// prepare() and apply() allocate nothing.
//
// The cycle: one damped block-Jacobi sweep (weight kSmoothing; the inverse of each node's
// 3x3 diagonal block) before and after the coarse correction on every level, the coarse
// correction scaled by kOverCorrection (piecewise-constant interpolation underestimates
// the coarse error's energy; scaling it is the usual remedy for plain aggregation, Vanek
// et al.), and, below the first coarse level, each level visited twice for every visit of
// the level above (a W-cycle: plain aggregation's V-cycle
// loses accuracy with every level, 19, 25, 36, 51 CG iterations from 32^2 to 256^2; the
// W-cycle 16.3, 19.2, 23.5, 27.9). Pre- and post-smoothing are the same symmetric
// sweep and each level's second pass is a stationary step with a symmetric operator, so
// the cycle is a symmetric positive definite operator, as CG needs. On the fine level a
// sweep costs one product with A (SpringJacobian::systemProduct; the first sweep starts
// from zero and needs none), so a cycle costs two fine products plus the coarse levels.
// On the coarse levels each sweep is fused into the pass that computes its residual (the
// new iterate goes to a second vector, swapped in), the first sweep from zero into the
// restriction that writes the level's right-hand side, and the W-cycle's second
// right-hand side into the residual pass before it: fewer passes over memory and fewer
// parallel loops to wait for.
//
// Products on a coarse level: on a grid model, every level's nodes sit in a padded
// rectangle (a ring of empty slots around the grid, and empty slots where all members are
// pinned), and since the fine springs reach at most two particles, every coarse edge joins
// a slot to one of its stencil neighbours east, south-west, south or south-east. The
// product then runs through that 9-point stencil, over contiguous arrays (axis-major
// vectors, one array per block entry and direction), as the fine grid's does: 1.5x less
// time than the general path on the 128^2 flag (perf, one thread). Any other level takes the general
// path: one block product per edge, then a gather over each node's edges.
//
// Every pass is a parallel pass over blocks of nodes that gathers in a fixed order (a
// node's members, an edge's springs, a node's edges, the stencil's directions), and levels
// below kParallelNodes run on the calling thread: the result is bitwise the same for any
// thread count. Coarse levels are kept in double for both precisions (the first sums the
// Jacobian's per-spring blocks, which are in the model's precision).
#pragma once

#include <vector>

#include "symmetric_block.hpp"
#include "weft/effects/spring_jacobian.hpp"

namespace weft::detail {

template <class S>
class AggregationMultigrid {
 public:
  /// Builds the hierarchy's pattern (allocates). `model` must outlive the preconditioner.
  /// `stencil` = false runs grid levels through the general edge product too (for tests).
  explicit AggregationMultigrid(const Model<S>& model, bool stencil = true);

  /// After jacobian.linearize(): every coarse operator, the smoothers' block inverses and
  /// the coarsest factor. Allocates nothing.
  void prepare(const SpringJacobian<S>& jacobian, const Executor& exec);

  /// z = one cycle applied to r (r zero on pinned particles; z is zero there too), and
  /// partials[k] = r . z over block k of `block` particles (block = ForceField::kSinkBlock).
  /// r and z must be distinct buffers (the passes read r while they write z).
  void apply(SpringJacobian<S>& jacobian, const Vec3Array<S>& r, Vec3Array<S>& z, std::vector<double>& partials,
             Index block, const Executor& exec);

  /// Levels including the fine one (1: no particle is free).
  int levelCount() const { return static_cast<int>(levels_.size()) + 1; }
  /// Nodes on each coarse level, finest first.
  std::vector<Index> coarseSizes() const;
  /// Coarse levels whose product runs through the grid stencil.
  int stencilLevelCount() const {
    int count = 0;
    for (const Level& l : levels_) count += l.stencil ? 1 : 0;
    return count;
  }

  // Measured on the 128^2 flag at 1/60 s (docs/integrators.md): weights 0.67 ... 1.0 and
  // over-corrections 1.0 ... 1.5 are within 10 % of each other in CG iterations; a W-cycle
  // takes a third fewer than a V-cycle (25 against 36) and is cheaper per step; more coarse
  // sweeps save iterations but not time.
  static constexpr double kSmoothing = 0.8;       // block-Jacobi weight (A's D^-1 A has spectrum in (0, 2])
  static constexpr double kOverCorrection = 1.3;  // scale of the coarse correction
  static constexpr int kCycles = 2;               // passes on each coarser level: 2 = W-cycle
  static constexpr int kCoarseSweeps = 1;         // smoothing sweeps before and after, coarse levels
  // (A third pass would need the level's original right-hand side kept apart; no sweep after
  // the coarse correction would break the symmetry.)
  static_assert(kCycles == 1 || kCycles == 2, "the coarse passes keep only one right-hand side");
  static_assert(kCoarseSweeps >= 1, "pre- and post-smoothing must match");
  static constexpr Index kCoarsestNodes = 32;   // stop coarsening at or below this many nodes
  static constexpr Index kDenseNodes = 64;      // largest coarsest level solved by dense Cholesky
  static constexpr Index kParallelNodes = 512;  // smaller levels run on the calling thread

 private:
  struct Level {
    Index n = 0;                                   // node slots (a grid level: its padded rectangle, see below)
    Index active = 0;                              // nodes with members (the others are padding and stay 0)
    std::vector<Index> memberOffset, members;      // the finer level's nodes in each node
    std::vector<Index> edgeU, edgeV;               // edges, u < v
    std::vector<Index> linkOffset, links;          // per edge: the finer level's links summed into it
    std::vector<Index> groundOffset, groundLinks;  // per node: finer links grounding it (first level only)
    std::vector<Index> incidenceOffset, incident;  // per node: its edges in edge order (e on its u side, ~e on v)
    std::vector<Index> aggregateOf;                // finer level node -> node here (-1: pinned)
    // A grid level: node (r, c) of a gridWidth-wide grid is slot (r + 1) * stride + c + 1,
    // stride = gridWidth + 2, with a ring of empty slots around it; row and column per slot
    // (-1 on the ring). Its edges then all join a slot to the next one in one of the four
    // directions of `offset`, and the product runs through the 9-point stencil.
    Index gridWidth = 0, stride = 0;
    std::vector<Index> row, column;
    bool stencil = false;
    Index offset[4] = {0, 0, 0, 0};     // slot offsets of the stencil's directions
    std::vector<Index> stencilSlot;     // per edge: direction * n + u
    std::vector<double> stencilBlocks;  // (4 directions x 6 entries x n) edge blocks, 0 where none
    std::vector<double> groundBlocks;   // (6 entries x n) ground blocks, for the stencil product
    std::vector<SymmetricBlock> ground, edge, diagonal;
    std::vector<double> inverse;  // (6 entries x n) the smoother's inverse blocks, xx yy zz xy xz yz arrays
    std::vector<double> g;        // (3 edges) B_e (x_u - x_v), the general product's
    // (3 n each, axis-major: c n + a) right-hand side, solution, residual, the W-cycle's kept
    // solution, and the next solution of a fused sweep (swapped with x).
    std::vector<double> b, x, t, saved, next;
  };
  struct Link {  // a finer level's coupling, for building a coarser level
    Index u, v;
    double strength;
  };

  Level buildLevel(Index n, const std::vector<char>& free, const std::vector<Link>& links, Index gridWidth,
                   const std::vector<Index>& row, const std::vector<Index>& column, bool stencil) const;
  void assemble(Level& level, const Level* finer, const SpringJacobian<S>* jacobian, const Executor& exec);
  /// coarse.b = the restriction of the finer level's residual, value(i, c) (node i, axis c).
  /// With `smooth`, also the coarse cycle's first sweep from zero: x = w D^-1 b.
  template <class Value>
  void restrictTo(Level& coarse, Value&& value, bool smooth, const Executor& exec);
  /// Whether cycle(k) starts with a sweep from zero (every level but a densely solved one).
  bool startsWithSweep(std::size_t k) const { return !(k + 1 == levels_.size() && denseCoarsest_); }
  void cycle(std::size_t k, const Executor& exec);
  /// Items per block of a pass over `count` nodes or edges: `grain`, or all of them on the
  /// calling thread below kParallelNodes (each pass is too short to share).
  static Index grainOf(Index count, Index grain) { return count > kParallelNodes ? grain : std::max<Index>(count, 1); }
  /// t = b - A x on a level (t may be b), and with `smoothed` the sweep x + w D^-1 t (or
  /// w D^-1 t, fromZero) into *smoothed, in the same pass.
  void residual(Level& level, const std::vector<double>& x, const std::vector<double>& b, std::vector<double>& t,
                std::vector<double>* smoothed, bool fromZero, const Executor& exec);
  void factorCoarsest();
  void solveCoarsest();

  const Model<S>* model_;
  Index n_ = 0;
  std::vector<char> free_;
  std::vector<Level> levels_;        // coarse levels, finest first
  std::vector<double> fineInverse_;  // (6 n) fine 3x3 block inverses, xx yy zz xy xz yz arrays (0: pinned)
  Vec3Array<S> x_, t_;               // fine smoothing iterate and residual
  std::vector<double> dense_;        // coarsest: (3 active)^2 Cholesky factor, then 1 / its diagonal
  std::vector<Index> denseNode_;     // coarsest: the slot of each of its active nodes
  std::vector<double> denseRhs_;     // coarsest: (3 active) right-hand side, then solution
  bool denseCoarsest_ = false;
};

extern template class AggregationMultigrid<float>;
extern template class AggregationMultigrid<double>;

}  // namespace weft::detail
