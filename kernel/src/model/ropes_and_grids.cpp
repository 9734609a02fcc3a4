#include "weft/model/ropes_and_grids.hpp"

#include <cmath>
#include <initializer_list>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "core/text.hpp"
#include "precision_limits.hpp"

namespace weft {

namespace {

Vec3d normalised(const Vec3d& v, const char* field) {
  const double len = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  if (!(std::isfinite(len) && len > 0))
    throw std::invalid_argument(std::string(field) + " must be a finite non-zero vector");
  return {v.x / len, v.y / len, v.z / len};
}

void requirePositive(const char* field, double value) {
  if (!(std::isfinite(value) && value > 0)) detail::rejectField(field, value, "finite and > 0");
}

/// What ModelBuilder<S>::build() will require of the values an object adds, checked before
/// anything is added (so that an object these builders accept also builds, and a refused
/// one leaves the builder as it was): each particle's mass and its inverse in S, the
/// corners of the object's bounding box within the precision's coordinate bound, and the
/// spring materials within S's range (the grid layout also holds them converted to S).
template <class S>
void checkPrecision(const std::string& spec, double mass, const Vec3d& from, const Vec3d& to, double shortest,
                    std::initializer_list<std::pair<const char*, const SpringMaterial*>> materials) {
  using Limits = detail::PrecisionLimits<S>;
  const std::string in = std::string(" in ") + Limits::kName + " precision";
  if (!(Limits::representable(mass) && Limits::invertibleMass(mass)))
    detail::rejectField(spec + " particle mass (totalMass / particles)", mass,
                        "such that it and 1/mass are finite" + in);
  double farthest = 0;
  for (const Vec3d& p : {from, to})
    for (const double c : {p.x, p.y, p.z}) {
      if (!Limits::coordinate(c))
        detail::rejectField(spec + " extent (a coordinate of a particle)", c,
                            "within +-" + detail::number(Limits::kFarthest) + " m" + in);
      farthest = std::max(farthest, std::abs(c));
    }
  // (ModelBuilder::build checks every spring; the shortest, checked here, names the object.)
  if (!Limits::springResolved(shortest, farthest))
    detail::rejectField(spec + " extent (the largest |coordinate| of a particle)", farthest,
                        Limits::springRule(shortest));
  for (const auto& entry : materials) {
    const char* name = entry.first;
    const SpringMaterial* material = entry.second;
    if (material == nullptr) continue;
    const auto check = [&](const char* field, double value, const char* unit) {
      if (!(std::isfinite(value) && value >= 0 && Limits::representable(value)))
        detail::rejectField(
            spec + "." + name + "." + field, value,
            std::string("finite and >= 0 (") + unit + ") and at most " + detail::number(Limits::kLargest) + in);
    };
    check("stiffness", material->stiffness, "N/m");
    check("damping", material->damping, "N s/m");
  }
}

/// A spacing the builder lays particles out at: one whose square is a normal number in S
/// (a grid at 1e-300 m would have springs of length 0 and directions of 0 / 0).
template <class S>
void checkSpacing(const std::string& field, double spacing) {
  using Limits = detail::PrecisionLimits<S>;
  if (!Limits::spacing(spacing)) detail::rejectField(field, spacing, Limits::spacingRule());
}

Vec3d along(const Vec3d& origin, const Vec3d& d, double t) {
  return {origin.x + t * d.x, origin.y + t * d.y, origin.z + t * d.z};
}

}  // namespace

std::array<Index, kSpringClassCount> expectedGridSpringCounts(const ClothGridSpec& spec) {
  const Index w = spec.width, h = spec.height;
  std::array<Index, kSpringClassCount> counts{};
  counts[0] = (w - 1) * h + w * (h - 1);
  counts[1] = spec.shearSprings ? 2 * (w - 1) * (h - 1) : 0;
  counts[2] = spec.bendSprings ? std::max<Index>(w - 2, 0) * h + w * std::max<Index>(h - 2, 0) : 0;
  return counts;
}

template <class S>
void addRope(ModelBuilder<S>& builder, const RopeSpec& spec) {
  if (spec.particleCount < 2)
    throw std::invalid_argument("RopeSpec.particleCount must be >= 2, got " + std::to_string(spec.particleCount));
  requirePositive("RopeSpec.length", spec.length);
  requirePositive("RopeSpec.totalMass", spec.totalMass);
  const Vec3d d = normalised(spec.direction, "RopeSpec.direction");
  const Index n = spec.particleCount;
  const Index first = builder.particleCount();
  const double step = spec.length / static_cast<double>(n - 1);
  const double m = spec.totalMass / static_cast<double>(n);
  checkSpacing<S>("RopeSpec.length / (particleCount - 1)", step);
  checkPrecision<S>("RopeSpec", m, spec.origin, along(spec.origin, d, step * static_cast<double>(n - 1)), step,
                    {{"structural", &spec.structural}, {"bend", spec.bendSprings ? &spec.bend : nullptr}});
  for (Index i = 0; i < n; ++i) {
    const double t = step * static_cast<double>(i);
    builder.addParticle({spec.origin.x + t * d.x, spec.origin.y + t * d.y, spec.origin.z + t * d.z}, m);
  }
  for (Index i = 0; i + 1 < n; ++i)
    builder.addSpring(first + i, first + i + 1, spec.structural, SpringClass::Structural, step);
  if (spec.bendSprings)
    for (Index i = 0; i + 2 < n; ++i)
      builder.addSpring(first + i, first + i + 2, spec.bend, SpringClass::Bend, 2 * step);
}

template <class S>
void addClothGrid(ModelBuilder<S>& builder, const ClothGridSpec& spec) {
  if (spec.width < 2)
    throw std::invalid_argument("ClothGridSpec.width must be >= 2, got " + std::to_string(spec.width));
  if (spec.height < 2)
    throw std::invalid_argument("ClothGridSpec.height must be >= 2, got " + std::to_string(spec.height));
  requirePositive("ClothGridSpec.spacing", spec.spacing);
  checkSpacing<S>("ClothGridSpec.spacing", spec.spacing);
  requirePositive("ClothGridSpec.totalMass", spec.totalMass);
  const Vec3d u = normalised(spec.rowAxis, "ClothGridSpec.rowAxis");
  const Vec3d w = normalised(spec.columnAxis, "ClothGridSpec.columnAxis");
  const double cx = u.y * w.z - u.z * w.y, cy = u.z * w.x - u.x * w.z, cz = u.x * w.y - u.y * w.x;
  if (!(std::sqrt(cx * cx + cy * cy + cz * cz) > 1e-6))
    throw std::invalid_argument("ClothGridSpec.rowAxis and ClothGridSpec.columnAxis must not be parallel, got " +
                                detail::number3(spec.rowAxis) + " and " + detail::number3(spec.columnAxis));
  const Index W = spec.width, H = spec.height;
  // Every particle, spring and triangle index must fit an Index (about 3.5 springs a particle).
  if (static_cast<long long>(W) * H > std::numeric_limits<Index>::max() / 8)
    throw std::invalid_argument("ClothGridSpec.width x height must be at most " +
                                std::to_string(std::numeric_limits<Index>::max() / 8) + " particles, got " +
                                std::to_string(W) + " x " + std::to_string(H));
  const Index first = builder.particleCount();  // the grid layout is recorded only when 0
  const double m = spec.totalMass / static_cast<double>(W * H);
  {
    // The grid's far corner, and the two others: the bounding box's extremes are among them.
    const double a = spec.spacing * static_cast<double>(W - 1), b = spec.spacing * static_cast<double>(H - 1);
    const Vec3d corner = along(along(spec.origin, u, a), w, b);
    checkPrecision<S>("ClothGridSpec", m, spec.origin, corner, spec.spacing,
                      {{"structural", &spec.structural},
                       {"shear", spec.shearSprings ? &spec.shear : nullptr},
                       {"bend", spec.bendSprings ? &spec.bend : nullptr}});
    checkPrecision<S>("ClothGridSpec", m, along(spec.origin, u, a), along(spec.origin, w, b), spec.spacing, {});
  }
  // Exact counts: structural (two families), shear (two), bend (two), two triangles a cell.
  const Index springs = (W - 1) * H + W * (H - 1) + (spec.shearSprings ? 2 * (W - 1) * (H - 1) : 0) +
                        (spec.bendSprings ? (W - 2) * H + W * (H - 2) : 0);
  builder.reserve(W * H, springs, 2 * (W - 1) * (H - 1));
  for (Index r = 0; r < H; ++r)
    for (Index c = 0; c < W; ++c) {
      const double a = spec.spacing * static_cast<double>(c), b = spec.spacing * static_cast<double>(r);
      builder.addParticle(
          {spec.origin.x + a * u.x + b * w.x, spec.origin.y + a * u.y + b * w.y, spec.origin.z + a * u.z + b * w.z}, m);
    }

  // A family's rest length is the length of its lattice vector dc h u + dr h w: the same
  // for every spring of the family (the stencil relies on that), and the true distance
  // at rest also when the axes are not orthogonal (a skewed grid starts unstressed).
  struct FamilySpec {
    int dr, dc;
    SpringClass kind;
    const SpringMaterial* material;
  };
  const double h = spec.spacing;
  const auto restLength = [&](int dr, int dc) {
    const double x = h * (dc * u.x + dr * w.x), y = h * (dc * u.y + dr * w.y), z = h * (dc * u.z + dr * w.z);
    return std::sqrt(x * x + y * y + z * z);
  };
  std::vector<FamilySpec> families = {{0, 1, SpringClass::Structural, &spec.structural},
                                      {1, 0, SpringClass::Structural, &spec.structural}};
  if (spec.shearSprings) {
    families.push_back({1, 1, SpringClass::Shear, &spec.shear});
    families.push_back({1, -1, SpringClass::Shear, &spec.shear});
  }
  if (spec.bendSprings) {
    families.push_back({0, 2, SpringClass::Bend, &spec.bend});
    families.push_back({2, 0, SpringClass::Bend, &spec.bend});
  }
  GridLayout<S> layout;
  layout.width = W;
  layout.height = H;
  for (const FamilySpec& f : families) {
    GridFamily<S> g;
    g.rowOffset = f.dr;
    g.columnOffset = f.dc;
    const double rest = restLength(f.dr, f.dc);
    if (!(rest > 0)) throw std::invalid_argument("ClothGridSpec.rowAxis and columnAxis must not be parallel");
    g.restLength = static_cast<S>(rest);
    g.stiffness = static_cast<S>(f.material->stiffness);
    g.damping = static_cast<S>(f.material->damping);
    g.firstSpring = builder.springCount();
    for (Index r = 0; r + f.dr < H; ++r)
      for (Index c = std::max(0, -f.dc); c < std::min(W, W - f.dc); ++c)
        builder.addSpring(first + r * W + c, first + (r + f.dr) * W + c + f.dc, *f.material, f.kind, rest);
    g.springCount = builder.springCount() - g.firstSpring;
    if (g.springCount > 0) layout.families.push_back(g);
  }
  if (first == 0) builder.setGridLayout(std::move(layout));
  // Two triangles per cell, normal along rowAxis x columnAxis.
  for (Index r = 0; r + 1 < H; ++r)
    for (Index c = 0; c + 1 < W; ++c) {
      const Index a = first + r * W + c, b = a + 1, d = a + W, e = d + 1;
      builder.addTriangle(a, b, e);
      builder.addTriangle(a, e, d);
    }
}

template void addRope(ModelBuilder<float>&, const RopeSpec&);
template void addRope(ModelBuilder<double>&, const RopeSpec&);
template void addClothGrid(ModelBuilder<float>&, const ClothGridSpec&);
template void addClothGrid(ModelBuilder<double>&, const ClothGridSpec&);

}  // namespace weft
