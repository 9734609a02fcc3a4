#include "weft/model/model.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <mutex>
#include <vector>

namespace weft {

namespace detail {

/// The Model's derived data, each piece computed once under its own flag.
template <class S>
struct DerivedTopology {
  std::once_flag springIncidenceOnce, triangleIncidenceOnce, colouringOnce, gridOnce, edgesOnce, surfaceOnce;
  Incidence springIncidence;
  Incidence triangleIncidence;
  SpringColouring<S> colouring;
  bool trianglesFormGrid = false;
  std::vector<Edge> collisionEdges;
  SurfaceTopology surface;
  std::atomic<int> builds{0};
};

}  // namespace detail

namespace {

/// CSR from (item, particle) pairs given in ascending item order: each particle's list
/// comes out ascending too. `each(f)` calls f(particle, entry) for every pair.
template <class Each>
Incidence buildIncidence(Index particles, Index total, Each each) {
  Incidence inc;
  inc.offsets.setZero(particles + 1);
  each([&](Index i, Index) { ++inc.offsets[i + 1]; });
  for (Index i = 0; i < particles; ++i) inc.offsets[i + 1] += inc.offsets[i];
  inc.entries.resize(total);
  std::vector<Index> fill(inc.offsets.data(), inc.offsets.data() + particles);
  each([&](Index i, Index entry) { inc.entries[fill[i]++] = entry; });
  return inc;
}

}  // namespace

template <class S>
Model<S>::Model() : derived_(std::make_shared<detail::DerivedTopology<S>>()) {}

template <class S>
const Incidence& Model<S>::springIncidence() const {
  std::call_once(derived_->springIncidenceOnce, [&] {
    const Springs<S>& sp = springs_;
    derived_->springIncidence = buildIncidence(particleCount(), 2 * sp.count(), [&](auto&& f) {
      for (Index s = 0; s < sp.count(); ++s) {
        f(sp.a[s], 2 * s);
        f(sp.b[s], 2 * s + 1);
      }
    });
    ++derived_->builds;
  });
  return derived_->springIncidence;
}

template <class S>
const Incidence& Model<S>::triangleIncidence() const {
  std::call_once(derived_->triangleIncidenceOnce, [&] {
    const Triangles& tr = triangles_;
    derived_->triangleIncidence = buildIncidence(particleCount(), 3 * tr.count(), [&](auto&& f) {
      for (Index t = 0; t < tr.count(); ++t) {
        f(tr.a[t], t);
        f(tr.b[t], t);
        f(tr.c[t], t);
      }
    });
    ++derived_->builds;
  });
  return derived_->triangleIncidence;
}

template <class S>
const SpringColouring<S>& Model<S>::springColouring() const {
  std::call_once(derived_->colouringOnce, [&] {
    const Index n = particleCount();
    const Index m = springCount();
    const Springs<S>& sp = springs_;
    std::vector<Index> degree(n, 0);
    for (Index s = 0; s < m; ++s) {
      ++degree[sp.a[s]];
      ++degree[sp.b[s]];
    }
    const Index maxDegree = n > 0 ? *std::max_element(degree.begin(), degree.end()) : 0;
    const Index words = (2 * maxDegree) / 64 + 1;
    std::vector<std::uint64_t> used(static_cast<size_t>(n) * words, 0);
    std::vector<Index> colour(m);
    Index colours = 0;
    for (Index s = 0; s < m; ++s) {
      const std::uint64_t* ua = &used[static_cast<size_t>(sp.a[s]) * words];
      const std::uint64_t* ub = &used[static_cast<size_t>(sp.b[s]) * words];
      Index c = 0;
      for (Index w = 0; w < words; ++w) {
        const std::uint64_t free = ~(ua[w] | ub[w]);
        if (free) {
          c = w * 64 + static_cast<Index>(__builtin_ctzll(free));
          break;
        }
      }
      colour[s] = c;
      used[static_cast<size_t>(sp.a[s]) * words + c / 64] |= std::uint64_t(1) << (c % 64);
      used[static_cast<size_t>(sp.b[s]) * words + c / 64] |= std::uint64_t(1) << (c % 64);
      colours = std::max(colours, c + 1);
    }
    SpringColouring<S>& out = derived_->colouring;
    out.offsets.assign(colours + 1, 0);
    for (Index s = 0; s < m; ++s) ++out.offsets[colour[s] + 1];
    for (Index c = 0; c < colours; ++c) out.offsets[c + 1] += out.offsets[c];
    std::vector<Index> fill(out.offsets.begin(), out.offsets.end() - 1);
    out.a.resize(m);
    out.b.resize(m);
    out.restLength.resize(m);
    out.stiffness.resize(m);
    out.damping.resize(m);
    for (Index s = 0; s < m; ++s) {
      const Index t = fill[colour[s]]++;
      out.a[t] = sp.a[s];
      out.b[t] = sp.b[s];
      out.restLength[t] = sp.restLength[s];
      out.stiffness[t] = sp.stiffness[s];
      out.damping[t] = sp.damping[s];
    }
    ++derived_->builds;
  });
  return derived_->colouring;
}

template <class S>
bool Model<S>::trianglesFormGrid() const {
  std::call_once(derived_->gridOnce, [&] {
    bool regular = false;
    if (grid_ && grid_->width >= 2 && grid_->height >= 2) {
      const Triangles& tr = triangles_;
      const Index W = grid_->width, H = grid_->height;
      regular = tr.count() == 2 * (W - 1) * (H - 1);
      for (Index r = 0, t = 0; regular && r + 1 < H; ++r)
        for (Index c = 0; regular && c + 1 < W; ++c, t += 2) {
          const Index a = r * W + c;
          regular = tr.a[t] == a && tr.b[t] == a + 1 && tr.c[t] == a + W + 1 && tr.a[t + 1] == a &&
                    tr.b[t + 1] == a + W + 1 && tr.c[t + 1] == a + W;
        }
    }
    derived_->trianglesFormGrid = regular;
    ++derived_->builds;
  });
  return derived_->trianglesFormGrid;
}

template <class S>
const std::vector<Edge>& Model<S>::collisionEdges() const {
  std::call_once(derived_->edgesOnce, [&] {
    const Springs<S>& sp = springs_;
    for (Index s = 0; s < sp.count(); ++s)
      if (sp.kind[static_cast<size_t>(s)] != SpringClass::Bend) derived_->collisionEdges.push_back({sp.a[s], sp.b[s]});
    ++derived_->builds;
  });
  return derived_->collisionEdges;
}

template <class S>
const SurfaceTopology& Model<S>::surfaceTopology() const {
  std::call_once(derived_->surfaceOnce, [&] {
    const Triangles& tr = triangles_;
    const Index t = tr.count();
    // Sides as (low, high, triangle), sorted: equal sides are adjacent, their first entry
    // has the lowest triangle, which owns the edge.
    std::vector<std::array<Index, 3>> sides;
    sides.reserve(static_cast<size_t>(3 * t));
    for (Index k = 0; k < t; ++k) {
      const Index c[3] = {tr.a[k], tr.b[k], tr.c[k]};
      for (int e = 0; e < 3; ++e) {
        const Index p = c[e], q = c[(e + 1) % 3];
        if (p != q) sides.push_back({std::min(p, q), std::max(p, q), k});
      }
    }
    std::sort(sides.begin(), sides.end());
    SurfaceTopology& out = derived_->surface;
    std::vector<std::array<Index, 2>> edgeOwner;  // (owner triangle, edge)
    for (size_t i = 0; i < sides.size(); ++i) {
      if (i > 0 && sides[i][0] == sides[i - 1][0] && sides[i][1] == sides[i - 1][1]) continue;
      edgeOwner.push_back({sides[i][2], static_cast<Index>(out.edges.size())});
      out.edges.push_back({sides[i][0], sides[i][1]});
    }
    std::sort(edgeOwner.begin(), edgeOwner.end());
    out.ownedEdges = buildIncidence(t, static_cast<Index>(edgeOwner.size()), [&](auto&& f) {
      for (const auto& eo : edgeOwner) f(eo[0], eo[1]);
    });
    std::vector<Index> owner(static_cast<size_t>(particleCount()), -1);
    std::vector<std::array<Index, 2>> vertexOwner;  // (owner triangle, vertex)
    for (Index k = 0; k < t; ++k)
      for (const Index v : {tr.a[k], tr.b[k], tr.c[k]})
        if (owner[static_cast<size_t>(v)] < 0) {
          owner[static_cast<size_t>(v)] = k;
          vertexOwner.push_back({k, v});
        }
    std::sort(vertexOwner.begin(), vertexOwner.end());
    out.ownedVertices = buildIncidence(t, static_cast<Index>(vertexOwner.size()), [&](auto&& f) {
      for (const auto& vo : vertexOwner) f(vo[0], vo[1]);
    });
    ++derived_->builds;
  });
  return derived_->surface;
}

template <class S>
int Model<S>::derivedBuildCount() const {
  return derived_->builds.load();
}

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
