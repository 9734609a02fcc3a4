#include "weft/integrate/stability.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>

#include "core/text.hpp"

namespace weft {

void validateStabilityOptions(const StabilityOptions& o, const char* where) {
  if (std::isnan(o.maxStretch) || (o.maxStretch > 0 && o.maxStretch < 1))
    detail::rejectField(std::string(where) + ".maxStretch", o.maxStretch,
                        "<= 0 (no stretch check) or >= 1 (a multiple of the rest length)");
}

const char* stepCodeName(StepCode code) {
  switch (code) {
    case StepCode::Ok:
      return "ok";
    case StepCode::NonFinite:
      return "non-finite";
    case StepCode::Overstretched:
      return "overstretched";
    case StepCode::StepSizeUnderflow:
      return "step-size-underflow";
    case StepCode::CapacityExceeded:
      return "capacity-exceeded";
    case StepCode::TooManyCandidates:
      return "too-many-candidates";
  }
  return "unknown";
}

std::string StepStatus::message() const {
  std::ostringstream out;
  out.precision(6);
  switch (code) {
    case StepCode::Ok:
      out << "ok";
      break;
    case StepCode::NonFinite:
      if (body >= 0) {
        out << "non-finite state: rigid body " << body << " has position, velocity or kinetic energy " << value
            << " after the step starting at t = " << time << " s (reduce dt)";
      } else {
        out << "non-finite state: particle " << particle << " has position or velocity " << value
            << " after the step starting at t = " << time << " s (reduce dt or use a more stable integrator)";
      }
      break;
    case StepCode::CapacityExceeded:
      out << "the rigid-body pair buffer (capacity " << value << ") is full in the step starting at t = " << time
          << " s: raise RigidOptions::maxPairs";
      break;
    case StepCode::TooManyCandidates:
      out << "self-collision met more than " << value
          << " candidate pairs per triangle (SelfCollisionOptions::maxCandidatesPerTriangle; "
             "self_collision.max_candidates_per_triangle in a scene file) in the step starting at t = "
          << time
          << " s, in chunks halved as often as CollisionOptions::maxHalvings allows: the step moves the cloth so far "
             "that nearly all its swept boxes overlap (a cloth started deep inside an obstacle is pushed out at "
             "once), and the work would grow with the square of the triangles; start the cloth outside the "
             "obstacles, reduce dt, or raise the limit";
      break;
    case StepCode::Overstretched:
      out << "overstretched spring " << spring << " (particle " << particle << "): length is " << value
          << " x rest length after the step starting at t = " << time
          << " s (the integrator is likely past its stability limit: reduce dt)";
      break;
    case StepCode::StepSizeUnderflow:
      out << "adaptive step-size control gave up in the step starting at t = " << time << " s after " << value
          << " trial substeps (error still above tolerance at the minimum substep, or too many substeps: loosen "
             "the tolerances, raise maxSubsteps, or use an implicit integrator for stiff models)";
      break;
  }
  return out.str();
}

namespace {

// Detection kernels: out-of-line with restrict pointers so they vectorise (see
// effects/force_field.cpp). The flag is an integer as wide as S: GCC 12 vectorises an OR
// reduction of same-width compare results, not one into a bool.
template <class S>
using Flag = std::conditional_t<sizeof(S) == 4, std::int32_t, std::int64_t>;

// !(|value| <= max) is true for NaN and for +-inf.
template <class S>
[[gnu::noinline]] bool anyNonFinite(Index count, const S* __restrict p) {
  const S big = std::numeric_limits<S>::max();
  Flag<S> bad = 0;
  for (Index i = 0; i < count; ++i) bad |= (std::abs(p[i]) <= big) ? Flag<S>(0) : Flag<S>(1);
  return bad != 0;
}

// Any spring i -> i + offset, i in [0, count), longer than sqrt(limit2)?
template <class S>
[[gnu::noinline]] bool anyLongerStrided(Index count, Index offset, const S* __restrict x, const S* __restrict y,
                                        const S* __restrict z, S limit2) {
  Flag<S> bad = 0;
  for (Index t = 0; t < count; ++t) {
    const S dx = x[t] - x[t + offset], dy = y[t] - y[t + offset], dz = z[t] - z[t + offset];
    bad |= (dx * dx + dy * dy + dz * dz) > limit2 ? Flag<S>(1) : Flag<S>(0);
  }
  return bad != 0;
}

template <class S>
[[gnu::noinline]] bool anyLongerIndexed(Index b, Index e, const Index* __restrict A, const Index* __restrict B,
                                        const S* __restrict x, const S* __restrict y, const S* __restrict z,
                                        const S* __restrict rest, S ratio2) {
  Flag<S> bad = 0;
  for (Index s = b; s < e; ++s) {
    const Index i = A[s], j = B[s];
    const S dx = x[i] - x[j], dy = y[i] - y[j], dz = z[i] - z[j];
    bad |= (dx * dx + dy * dy + dz * dz) > ratio2 * rest[s] * rest[s] ? Flag<S>(1) : Flag<S>(0);
  }
  return bad != 0;
}

}  // namespace

template <class S>
StabilityCheck<S>::StabilityCheck(const Model<S>& model, const StabilityOptions& options)
    : model_(&model), options_(options) {
  const Index n = model.particleCount();
  Index blocks = Executor::blockCount(n, kGrain);
  if (model.grid()) {
    const Index W = model.grid()->width, familyCount = static_cast<Index>(model.grid()->families.size());
    blocks = std::max(blocks, Executor::blockCount(model.grid()->height,
                                                   std::max<Index>(1, kGrain / std::max<Index>(1, W * familyCount))));
  } else {
    blocks = std::max(blocks, Executor::blockCount(model.springCount(), kGrain));
  }
  blockBad_.assign(static_cast<size_t>(blocks), 0);
}

template <class S>
StepStatus StabilityCheck<S>::check(const Vec3Array<S>& x, const Vec3Array<S>& v, const Executor& exec) {
  if (!options_.enabled) return {};
  const Index n = model_->particleCount();
  const auto anyBad = [&] {
    bool bad = false;
    for (char b : blockBad_) bad |= b != 0;
    return bad;
  };
  std::fill(blockBad_.begin(), blockBad_.end(), 0);
  exec.parallelForBlocks(n, kGrain, [&](Index block, Index b, Index e) {
    bool bad = false;
    for (int c = 0; c < 3; ++c)
      bad |= anyNonFinite(e - b, x.data() + c * n + b) | anyNonFinite(e - b, v.data() + c * n + b);
    blockBad_[block] = bad;
  });
  if (anyBad()) return locate(x, v);
  if (options_.maxStretch <= 0) return {};

  const S ratio2 = static_cast<S>(options_.maxStretch * options_.maxStretch);
  const S* X = x.data();
  if (model_->grid()) {
    const GridLayout<S>& g = *model_->grid();
    const Index W = g.width, H = g.height, familyCount = static_cast<Index>(g.families.size());
    const Index rowsPerBlock = std::max<Index>(1, kGrain / std::max<Index>(1, W * familyCount));
    exec.parallelForBlocks(H, rowsPerBlock, [&](Index block, Index r0, Index r1) {
      bool bad = false;
      for (const GridFamily<S>& f : g.families) {
        const Index c0 = std::max<Index>(0, -f.columnOffset), c1 = std::min<Index>(W, W - f.columnOffset);
        const Index offset = f.rowOffset * W + f.columnOffset;
        const S limit2 = ratio2 * f.restLength * f.restLength;
        for (Index r = r0; r < std::min<Index>(r1, H - f.rowOffset); ++r) {
          const Index i = r * W + c0;
          bad |= anyLongerStrided(c1 - c0, offset, X + i, X + n + i, X + 2 * n + i, limit2);
        }
      }
      blockBad_[block] = bad;
    });
  } else {
    const Springs<S>& sp = model_->springs();
    exec.parallelForBlocks(sp.count(), kGrain, [&](Index block, Index b, Index e) {
      blockBad_[block] =
          anyLongerIndexed(b, e, sp.a.data(), sp.b.data(), X, X + n, X + 2 * n, sp.restLength.data(), ratio2);
    });
  }
  if (anyBad()) return locate(x, v);
  return {};
}

// The rare path: an exact serial scan for the first offender, by index.
template <class S>
StepStatus StabilityCheck<S>::locate(const Vec3Array<S>& x, const Vec3Array<S>& v) const {
  StepStatus status;
  const Index n = model_->particleCount();
  // A NaN force reaches a pinned particle as 0 x NaN; name the first free particle that
  // went non-finite (where the instability is), and a pinned one only if no free one did.
  for (int pass = 0; pass < 2; ++pass)
    for (Index i = 0; i < n; ++i) {
      if ((pass == 0) == model_->isPinned(i)) continue;
      for (int c = 0; c < 3; ++c) {
        const double values[2] = {static_cast<double>(x(i, c)), static_cast<double>(v(i, c))};
        for (double value : values)
          if (!std::isfinite(value)) {
            status.code = StepCode::NonFinite;
            status.particle = i;
            status.value = value;
            return status;
          }
      }
    }
  if (options_.maxStretch <= 0) return status;
  const Springs<S>& sp = model_->springs();
  for (Index s = 0; s < sp.count(); ++s) {
    const Index i = sp.a[s], j = sp.b[s];
    const S dx = x(i, 0) - x(j, 0), dy = x(i, 1) - x(j, 1), dz = x(i, 2) - x(j, 2);
    const S ratio2 = static_cast<S>(options_.maxStretch * options_.maxStretch);
    if ((dx * dx + dy * dy + dz * dz) > ratio2 * sp.restLength[s] * sp.restLength[s]) {
      status.code = StepCode::Overstretched;
      status.spring = s;
      // Name an endpoint that moves: a pinned one is where the spring is held, not where
      // the instability is.
      status.particle = model_->isPinned(i) != model_->isPinned(j) ? (model_->isPinned(i) ? j : i) : std::min(i, j);
      status.value = std::sqrt(double(dx) * double(dx) + double(dy) * double(dy) + double(dz) * double(dz)) /
                     double(sp.restLength[s]);
      return status;
    }
  }
  return status;
}

template class StabilityCheck<float>;
template class StabilityCheck<double>;

template <class S>
double maxAngularFrequency(const Model<S>& model) {
  const Index n = model.particleCount();
  const Springs<S>& sp = model.springs();
  std::vector<double> row(static_cast<size_t>(n), 0.0);
  for (Index s = 0; s < sp.count(); ++s) {
    const double k = static_cast<double>(sp.stiffness[s]);
    const double wa = static_cast<double>(model.inverseMass()[sp.a[s]]);
    const double wb = static_cast<double>(model.inverseMass()[sp.b[s]]);
    const double cross = std::sqrt(wa * wb);
    row[sp.a[s]] += k * (wa + cross);
    row[sp.b[s]] += k * (wb + cross);
  }
  double largest = 0;
  for (double r : row) largest = std::max(largest, r);
  return std::sqrt(largest);
}

template <class S>
double estimateStableTimeStep(const Model<S>& model, IntegratorKind kind) {
  const double omega = maxAngularFrequency(model);
  if (omega == 0) return std::numeric_limits<double>::infinity();
  return integratorStabilityLimit(kind) / omega;
}

template double maxAngularFrequency(const Model<float>&);
template double maxAngularFrequency(const Model<double>&);
template double estimateStableTimeStep(const Model<float>&, IntegratorKind);
template double estimateStableTimeStep(const Model<double>&, IntegratorKind);

}  // namespace weft
