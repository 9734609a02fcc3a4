// weft_narrow_study — what each narrow phase gets right and what it costs.
//
//   build/bin/weft_narrow_study [--pairs N] [--out DIR]
//
// For each shape (box: 6 faces; icosahedron: 20 faces; sphere: the hull of weft's icosphere
// with 8 divisions, 1280 faces) and situation, N random pairs of poses (fixed seeds, the
// same on every machine: splitmix64):
//   resting   B placed on a random face of A, tilted by up to 3 degrees, turned about the
//             normal at random, its gap to A uniform in [-2, 2] mm: face contacts.
//   tumbling  B in a random orientation at a random direction from A, moved along that
//             direction until the exact separation is uniform in [-5, 20] mm: every kind of
//             feature pair, vertex-face and edge-edge included.
// every method answers with a margin of 10 mm (RigidOptions::speculativeDistance), and is
// compared with the exact method (the separating-axis test, the ground truth):
//   detected        share of the exact method's contact pairs the method also reports
//   recall          share it reports correctly: normal within 5 degrees of the exact one and
//                   deepest separation within 1 mm (a contact on the wrong features is a miss)
//   false contacts  pairs the method reports that the exact method does not
//   normal error    largest angle between the method's and the exact normal (pairs both report), degrees
//   depth error     largest difference of the deepest point's separation, mm
//   ns/pair         median over 5 passes of the time per query
// The witness method is run on sequences instead of isolated pairs (its cache is for pairs
// that persist): each pair is replayed 8 times with 0.1 mm / 0.1 mrad of motion per query;
// its hit rate (queries answered from the cache) is reported. Output: a Markdown table on
// stdout, and with --out, DIR/narrow_study.csv and DIR/narrow_study.md.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "weft/collide/shapes.hpp"
#include "weft/rigid/convex_hull.hpp"
#include "weft/rigid/narrow_phase.hpp"

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kMargin = 0.01;

struct SplitMix {
  std::uint64_t state;
  double uniform() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }
  double range(double a, double b) { return a + (b - a) * uniform(); }
  Vector3d direction() {
    for (;;) {
      const Vector3d v(range(-1, 1), range(-1, 1), range(-1, 1));
      const double n = v.norm();
      if (n > 0.1 && n <= 1) return v / n;
    }
  }
  Matrix3d rotation() {
    Eigen::Quaterniond q(range(-1, 1), range(-1, 1), range(-1, 1), range(-1, 1));
    return q.normalized().toRotationMatrix();
  }
};

/// The vertices of weft's icosphere (20 d^2 triangles on the sphere), as hull input.
std::vector<Vector3d> icosphere(weft::Index divisions, double radius) {
  const weft::TriangleMesh mesh = weft::makeIcosphere({0, 0, 0}, radius, divisions);
  std::vector<Vector3d> v;
  for (const weft::Vec3d& p : mesh.vertices) v.emplace_back(p.x, p.y, p.z);
  return v;
}

struct Shape {
  std::string name;
  weft::ConvexHull hull;
};

struct Pair {
  weft::Pose a, b;
};

weft::Pose pose(const Matrix3d& r, const Vector3d& p) {
  weft::Pose q;
  q.rotation = r;
  q.position = p;
  return q;
}

/// Moves B along `dir` so the exact separation is `target` (bisection on the distance).
void placeAt(const weft::ConvexHull& h, Pair& pair, const Vector3d& dir, double target) {
  double lo = -2, hi = 4;  // offsets along dir, m
  const Vector3d base = pair.a.position;
  for (int it = 0; it < 40; ++it) {
    const double midOffset = 0.5 * (lo + hi);
    pair.b.position = base + midOffset * dir;
    if (weft::hullSeparation(h, pair.a, h, pair.b) < target)
      lo = midOffset;
    else
      hi = midOffset;
  }
  pair.b.position = base + hi * dir;
}

std::vector<Pair> makePairs(const weft::ConvexHull& h, bool resting, int count, std::uint64_t seed) {
  SplitMix rng{seed};
  std::vector<Pair> pairs;
  for (int k = 0; k < count; ++k) {
    Pair p;
    p.a = pose(rng.rotation(), Vector3d(rng.range(-1, 1), rng.range(-1, 1), rng.range(-1, 1)));
    if (resting) {
      const int f = static_cast<int>(rng.uniform() * h.faceCount()) % h.faceCount();
      const Vector3d n = p.a.rotation * h.faces[f].normal;
      // B's most opposite face against A's face: B rotated so its face normal is -n, then
      // tilted and turned.
      const int g = static_cast<int>(rng.uniform() * h.faceCount()) % h.faceCount();
      const Matrix3d align = Eigen::Quaterniond::FromTwoVectors(h.faces[g].normal, -n).toRotationMatrix();
      const Matrix3d turn = Eigen::AngleAxisd(rng.range(0, 6.283185307179586), n).toRotationMatrix();
      const Matrix3d tilt =
          Eigen::AngleAxisd(rng.range(0, 3 * 3.14159265358979 / 180), rng.direction()).toRotationMatrix();
      p.b = pose(tilt * turn * align, p.a.position);
      placeAt(h, p, n, rng.range(-0.002, 0.002));
    } else {
      p.b = pose(rng.rotation(), p.a.position);
      placeAt(h, p, rng.direction(), rng.range(-0.005, 0.020));
    }
    pairs.push_back(p);
  }
  return pairs;
}

double deepest(const weft::ContactManifold& m) {
  double d = 1e9;
  for (int i = 0; i < m.pointCount; ++i) d = std::min(d, m.points[i].separation);
  return d;
}

struct Row {
  std::string shape, situation, method;
  int k = 0;
  int pairs = 0, exactContacts = 0, found = 0, correct = 0, falseContacts = 0;
  double normalError = 0, depthError = 0, nsPerPair = 0, hitRate = 0;
};

template <class Query>
double timePerQuery(const std::vector<Pair>& pairs, Query&& query) {
  std::vector<double> passes;
  for (int pass = 0; pass < 5; ++pass) {
    const auto start = std::chrono::steady_clock::now();
    for (const Pair& p : pairs) query(p);
    passes.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() /
                     static_cast<double>(pairs.size()));
  }
  std::sort(passes.begin(), passes.end());
  return passes[2];
}

}  // namespace

int main(int argc, char** argv) {
  int count = 2000;
  std::string out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--pairs" && i + 1 < argc) {
      count = std::atoi(argv[++i]);
    } else if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: weft_narrow_study [--pairs N (>= 1)] [--out DIR]\n");
      return 2;
    }
  }
  if (count < 1) {
    std::fprintf(stderr, "weft_narrow_study: --pairs must be >= 1\n");
    return 2;
  }
  std::vector<Shape> shapes;
  shapes.push_back({"box", weft::makeBoxHull(Vector3d(0.5, 0.5, 0.5))});
  shapes.push_back({"icosahedron", weft::makeConvexHull(icosphere(1, 0.6))});
  shapes.push_back({"sphere-1280", weft::makeConvexHull(icosphere(8, 0.5))});
  std::vector<Row> rows;
  std::uint64_t seed = 1;
  for (const Shape& s : shapes) {
    for (const bool resting : {true, false}) {
      // The fine sphere's exact query is thousands of times dearer (1920^2 edge pairs): fewer pairs.
      const int n = s.hull.faceCount() > 100 ? std::max(10, count / 25) : count;
      const std::vector<Pair> pairs = makePairs(s.hull, resting, n, seed++);
      // The ground truth.
      std::vector<weft::ContactManifold> exact(pairs.size());
      weft::NarrowPhaseOptions exactOptions;
      exactOptions.method = weft::NarrowPhaseMethod::Exact;
      for (std::size_t i = 0; i < pairs.size(); ++i) {
        weft::PairCache cache;
        weft::collideHulls(s.hull, pairs[i].a, s.hull, pairs[i].b, kMargin, exactOptions, cache, exact[i]);
      }
      struct Method {
        weft::NarrowPhaseMethod method;
        int k;
      };
      std::vector<Method> methods = {{weft::NarrowPhaseMethod::Exact, 0}};
      for (const int k : {2, 4, 6, 8, 12, 16}) methods.push_back({weft::NarrowPhaseMethod::Ofg, k});
      methods.push_back({weft::NarrowPhaseMethod::Witness, 0});
      for (const Method& m : methods) {
        Row row;
        row.shape = s.name;
        row.situation = resting ? "resting" : "tumbling";
        row.method = weft::narrowPhaseMethodName(m.method);
        row.k = m.k;
        row.pairs = static_cast<int>(pairs.size());
        weft::NarrowPhaseOptions options;
        options.method = m.method;
        options.ofgFaces = std::max(1, m.k);
        std::vector<weft::ContactManifold> got(pairs.size());
        std::int64_t queries = 0, hits = 0;
        if (m.method == weft::NarrowPhaseMethod::Witness) {
          // Each pair replayed as a short sequence of small motions; the last answer is compared.
          SplitMix rng{seed * 977};
          std::vector<std::vector<Pair>> sequences(pairs.size());
          for (std::size_t i = 0; i < pairs.size(); ++i) {
            for (int step = 7; step >= 0; --step) {
              Pair p = pairs[i];
              p.b.position += 1e-4 * step * rng.direction();
              p.b.rotation = Eigen::AngleAxisd(1e-4 * step, rng.direction()).toRotationMatrix() * p.b.rotation;
              sequences[i].push_back(p);
            }
          }
          std::vector<weft::PairCache> caches(pairs.size());
          for (std::size_t i = 0; i < pairs.size(); ++i)
            for (const Pair& p : sequences[i]) {
              const weft::NarrowPhaseOutcome o =
                  weft::collideHulls(s.hull, p.a, s.hull, p.b, kMargin, options, caches[i], got[i]);
              ++queries;
              hits += o != weft::NarrowPhaseOutcome::FullQuery;
            }
          // Time: the steady state, each pair's last pose again with its cache warm.
          std::size_t index = 0;
          std::vector<Pair> last(pairs.size());
          for (std::size_t i = 0; i < pairs.size(); ++i) last[i] = sequences[i].back();
          weft::ContactManifold scratch;
          row.nsPerPair = timePerQuery(last, [&](const Pair& p) {
            weft::collideHulls(s.hull, p.a, s.hull, p.b, kMargin, options, caches[index++ % caches.size()], scratch);
          });
          row.hitRate = queries > 0 ? static_cast<double>(hits) / static_cast<double>(queries) : 0;
        } else {
          for (std::size_t i = 0; i < pairs.size(); ++i) {
            weft::PairCache cache;
            weft::collideHulls(s.hull, pairs[i].a, s.hull, pairs[i].b, kMargin, options, cache, got[i]);
          }
          weft::ContactManifold scratch;
          row.nsPerPair = timePerQuery(pairs, [&](const Pair& p) {
            weft::PairCache cache;
            weft::collideHulls(s.hull, p.a, s.hull, p.b, kMargin, options, cache, scratch);
          });
        }
        for (std::size_t i = 0; i < pairs.size(); ++i) {
          const bool e = exact[i].pointCount > 0, g = got[i].pointCount > 0;
          row.exactContacts += e;
          row.found += e && g;
          row.falseContacts += g && !e;
          if (e && g) {
            const double c = std::clamp(exact[i].normal.dot(got[i].normal), -1.0, 1.0);
            const double angle = std::acos(c) * 180 / 3.14159265358979;
            const double depth = 1000 * std::abs(deepest(exact[i]) - deepest(got[i]));
            row.normalError = std::max(row.normalError, angle);
            row.depthError = std::max(row.depthError, depth);
            row.correct += angle <= 5 && depth <= 1;
          }
        }
        rows.push_back(row);
        std::fprintf(stderr, "%s %s %s k=%d: %.0f ns/pair\n", row.shape.c_str(), row.situation.c_str(),
                     row.method.c_str(), row.k, row.nsPerPair);
      }
    }
  }
  std::ostringstream md, csv;
  csv << "shape,situation,method,k,pairs,exact_contacts,detected,recall,false_contacts,max_normal_error_deg,"
         "max_depth_error_mm,ns_per_pair,witness_hit_rate\n";
  md << "| shape | situation | method | pairs in contact | detected | recall | false contacts | normal error (deg, "
        "max) | "
        "depth error (mm, max) | ns / pair | faster than exact | witness hits |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  double exactNs = 1;
  for (const Row& r : rows) {
    if (r.method == "exact") exactNs = r.nsPerPair;
    const double detected = r.exactContacts > 0 ? static_cast<double>(r.found) / r.exactContacts : 1.0;
    const double recall = r.exactContacts > 0 ? static_cast<double>(r.correct) / r.exactContacts : 1.0;
    const std::string method = r.method == "ofg" ? "ofg k=" + std::to_string(r.k) : r.method;
    char line[512];
    std::snprintf(
        line, sizeof line, "| %s | %s | %s | %d / %d | %.1f %% | %.1f %% | %d | %.2f | %.3f | %.0f | %.2fx | %s |\n",
        r.shape.c_str(), r.situation.c_str(), method.c_str(), r.exactContacts, r.pairs, 100 * detected, 100 * recall,
        r.falseContacts, r.normalError, r.depthError, r.nsPerPair, exactNs / r.nsPerPair,
        r.method == "witness" ? (std::to_string(static_cast<int>(std::lround(100 * r.hitRate))) + " %").c_str() : "");
    md << line;
    csv << r.shape << ',' << r.situation << ',' << r.method << ',' << r.k << ',' << r.pairs << ',' << r.exactContacts
        << ',' << detected << ',' << recall << ',' << r.falseContacts << ',' << r.normalError << ',' << r.depthError
        << ',' << r.nsPerPair << ',' << r.hitRate << '\n';
  }
  std::fputs(md.str().c_str(), stdout);
  if (!out.empty()) {
    std::filesystem::create_directories(out);
    std::ofstream(std::filesystem::path(out) / "narrow_study.csv") << csv.str();
    std::ofstream(std::filesystem::path(out) / "narrow_study.md") << md.str();
  }
  return 0;
}
