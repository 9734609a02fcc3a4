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
// its hit rate (queries answered from the cache) is reported.
//
// Concave: a torus (ring radius 0.4 m, tube radius 0.12 m, 24 x 12 vertices) against a box
// (0.12 m cube). Its solid is exactly the union of 24 convex segments (each the hull of two
// neighbouring rings), and the ground truth is the exact method on those segments (the
// deepest contact over them). Two ways to give the torus to a convex narrow phase: as one
// mesh (its convex hull: the hole filled) or as the 24 pieces (a compound, with a
// bounding-sphere test per piece). Situations: on the ring (the box lying on the tube's top
// half, tilted up to 3 degrees, gap in [-2, 2] mm), in the hole (the box anywhere in the
// hole, at least 2 cm from the tube: no contact), tumbling (random orientation, moved along
// the tube's normal from a random point of it until the separation is in [-5, 20] mm). Output: a Markdown table on
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

// ---------------------------------------------------------------------------------------
// Concave: a torus against a box.

constexpr double kRing = 0.4, kTube = 0.12, kBoxHalf = 0.06;
constexpr int kSegments = 24, kTubePoints = 12;
constexpr double kPi = 3.14159265358979323846;

Vector3d torusPoint(int segment, int around) {
  const double phi = 2 * kPi * segment / kSegments, theta = 2 * kPi * around / kTubePoints;
  return {(kRing + kTube * std::cos(theta)) * std::cos(phi), kTube * std::sin(theta),
          (kRing + kTube * std::cos(theta)) * std::sin(phi)};
}

struct Torus {
  weft::ConvexHull hull;                 // as one mesh: its convex hull
  std::vector<weft::ConvexHull> pieces;  // as a compound: the segments
  std::vector<Vector3d> centres;         // each piece's bounding sphere (torus frame)
  std::vector<double> radii;
};

Torus makeTorus() {
  Torus t;
  std::vector<Vector3d> all;
  for (int s = 0; s < kSegments; ++s)
    for (int a = 0; a < kTubePoints; ++a) all.push_back(torusPoint(s, a));
  t.hull = weft::makeConvexHull(all);
  for (int s = 0; s < kSegments; ++s) {
    std::vector<Vector3d> ring;
    for (const int k : {s, (s + 1) % kSegments})
      for (int a = 0; a < kTubePoints; ++a) ring.push_back(torusPoint(k, a));
    Vector3d c = Vector3d::Zero();
    for (const Vector3d& p : ring) c += p / static_cast<double>(ring.size());
    double r = 0;
    for (const Vector3d& p : ring) r = std::max(r, (p - c).norm());
    t.pieces.push_back(weft::makeConvexHull(ring));
    t.centres.push_back(c);
    t.radii.push_back(r);
  }
  return t;
}

/// A compound against a convex hull: each piece whose bounding sphere (grown by the margin)
/// meets B's, queried with `options`; the answer is the deepest piece's manifold.
void collideCompound(const Torus& t, const weft::Pose& a, const weft::ConvexHull& box, const weft::Pose& b,
                     const weft::NarrowPhaseOptions& options, weft::PairCache* caches, weft::ContactManifold& out) {
  const double boxRadius = std::sqrt(3.0) * kBoxHalf;
  out.pointCount = 0;
  double best = 1e9;
  weft::ContactManifold piece;
  for (std::size_t k = 0; k < t.pieces.size(); ++k) {
    const Vector3d c = a.position + a.rotation * t.centres[k];
    if ((c - b.position).norm() > t.radii[k] + boxRadius + kMargin) continue;
    weft::PairCache fresh;
    weft::collideHulls(t.pieces[k], a, box, b, kMargin, options, caches ? caches[k] : fresh, piece);
    if (piece.pointCount > 0 && deepest(piece) < best) {
      best = deepest(piece);
      out = piece;
    }
  }
}

double compoundSeparation(const Torus& t, const weft::Pose& a, const weft::ConvexHull& box, const weft::Pose& b) {
  double s = 1e9;
  for (const weft::ConvexHull& p : t.pieces) s = std::min(s, weft::hullSeparation(p, a, box, b));
  return s;
}

/// The box along `dir` from `base` so that its separation from the torus is `target`.
void placeBox(const Torus& t, const weft::ConvexHull& box, Pair& pair, const Vector3d& base, const Vector3d& dir,
              double target) {
  double lo = -0.1, hi = 0.3;
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    pair.b.position = base + mid * dir;
    if (compoundSeparation(t, pair.a, box, pair.b) < target)
      lo = mid;
    else
      hi = mid;
  }
  pair.b.position = base + hi * dir;
}

std::vector<Pair> torusPairs(const Torus& t, const weft::ConvexHull& box, int situation, int count,
                             std::uint64_t seed) {
  SplitMix rng{seed};
  std::vector<Pair> pairs;
  for (int k = 0; k < count; ++k) {
    Pair p;
    p.a = pose(Matrix3d::Identity(), Vector3d::Zero());
    const double phi = rng.range(0, 2 * kPi);
    const Vector3d axis(std::cos(phi), 0, std::sin(phi));
    if (situation == 1) {  // in the hole, clear of the tube by 2 cm or more
      const double reach = kRing - kTube - std::sqrt(3.0) * kBoxHalf - 0.02;
      const double rho = reach * std::sqrt(rng.uniform());
      p.b = pose(rng.rotation(), rho * axis + Vector3d(0, rng.range(-0.05, 0.05), 0));
    } else {
      const double theta = situation == 0 ? rng.range(kPi / 6, 5 * kPi / 6) : rng.range(0, 2 * kPi);
      const Vector3d n = std::cos(theta) * axis + std::sin(theta) * Vector3d::UnitY();
      const Vector3d surface = kRing * axis + kTube * n;
      Matrix3d r = rng.rotation();
      if (situation == 0) {  // a face of the box against the tube's normal, tilted, turned
        const Matrix3d align = Eigen::Quaterniond::FromTwoVectors(-Vector3d::UnitY(), -n).toRotationMatrix();
        const Matrix3d turn = Eigen::AngleAxisd(rng.range(0, 2 * kPi), n).toRotationMatrix();
        const Matrix3d tilt = Eigen::AngleAxisd(rng.range(0, 3 * kPi / 180), rng.direction()).toRotationMatrix();
        r = tilt * turn * align;
      }
      p.b = pose(r, surface);
      placeBox(t, box, p, surface, n, situation == 0 ? rng.range(-0.002, 0.002) : rng.range(-0.005, 0.020));
    }
    pairs.push_back(p);
  }
  return pairs;
}

void compare(const std::vector<weft::ContactManifold>& truth, const std::vector<weft::ContactManifold>& got, Row& row) {
  for (std::size_t i = 0; i < truth.size(); ++i) {
    const bool e = truth[i].pointCount > 0, g = got[i].pointCount > 0;
    row.exactContacts += e;
    row.found += e && g;
    row.falseContacts += g && !e;
    if (e && g) {
      const double c = std::clamp(truth[i].normal.dot(got[i].normal), -1.0, 1.0);
      const double angle = std::acos(c) * 180 / kPi;
      const double depth = 1000 * std::abs(deepest(truth[i]) - deepest(got[i]));
      row.normalError = std::max(row.normalError, angle);
      row.depthError = std::max(row.depthError, depth);
      row.correct += angle <= 5 && depth <= 1;
    }
  }
}

void concaveRows(int count, std::uint64_t seed, std::vector<Row>& rows) {
  const Torus torus = makeTorus();
  const weft::ConvexHull box = weft::makeBoxHull(Vector3d::Constant(kBoxHalf));
  const char* situations[] = {"on the ring", "in the hole", "tumbling"};
  for (int situation = 0; situation < 3; ++situation) {
    const std::vector<Pair> pairs = torusPairs(torus, box, situation, count, seed++);
    weft::NarrowPhaseOptions exactOptions;
    exactOptions.method = weft::NarrowPhaseMethod::Exact;
    std::vector<weft::ContactManifold> truth(pairs.size());
    for (std::size_t i = 0; i < pairs.size(); ++i)
      collideCompound(torus, pairs[i].a, box, pairs[i].b, exactOptions, nullptr, truth[i]);
    struct Method {
      weft::NarrowPhaseMethod method;
      int k;
      bool compound;
    };
    std::vector<Method> methods;
    for (const bool compound : {false, true}) {
      methods.push_back({weft::NarrowPhaseMethod::Exact, 0, compound});
      for (const int k : {2, 6, 16}) methods.push_back({weft::NarrowPhaseMethod::Ofg, k, compound});
      methods.push_back({weft::NarrowPhaseMethod::Witness, 0, compound});
    }
    for (const Method& m : methods) {
      Row row;
      row.shape = m.compound ? "torus as 24 pieces"
                             : "torus as one mesh (hull, " + std::to_string(torus.hull.faceCount()) + " faces)";
      row.situation = situations[situation];
      row.method = weft::narrowPhaseMethodName(m.method);
      row.k = m.k;
      row.pairs = static_cast<int>(pairs.size());
      row.hitRate = -1;  // not measured here (one pose per pair)
      weft::NarrowPhaseOptions options;
      options.method = m.method;
      options.ofgFaces = std::max(1, m.k);
      // The witness keeps a cache per pair (and piece); it is warmed by one query first and
      // timed on the same pose, as a pair that rests.
      std::vector<weft::PairCache> caches(pairs.size() * kSegments);
      const auto query = [&](std::size_t i, weft::ContactManifold& out) {
        weft::PairCache* c = &caches[i * kSegments];
        if (m.compound) {
          collideCompound(torus, pairs[i].a, box, pairs[i].b, options, c, out);
        } else {
          weft::PairCache fresh;
          weft::collideHulls(torus.hull, pairs[i].a, box, pairs[i].b, kMargin, options,
                             m.method == weft::NarrowPhaseMethod::Witness ? *c : fresh, out);
        }
      };
      std::vector<weft::ContactManifold> got(pairs.size());
      for (std::size_t i = 0; i < pairs.size(); ++i) query(i, got[i]);
      compare(truth, got, row);
      std::size_t index = 0;
      weft::ContactManifold scratch;
      row.nsPerPair = timePerQuery(pairs, [&](const Pair&) { query(index++ % pairs.size(), scratch); });
      rows.push_back(row);
      std::fprintf(stderr, "%s %s %s k=%d: %.0f ns/pair\n", row.shape.c_str(), row.situation.c_str(),
                   row.method.c_str(), row.k, row.nsPerPair);
    }
  }
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
        compare(exact, got, row);
        rows.push_back(row);
        std::fprintf(stderr, "%s %s %s k=%d: %.0f ns/pair\n", row.shape.c_str(), row.situation.c_str(),
                     row.method.c_str(), row.k, row.nsPerPair);
      }
    }
  }
  concaveRows(std::max(10, count / 4), seed, rows);
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
    std::snprintf(line, sizeof line,
                  "| %s | %s | %s | %d / %d | %.1f %% | %.1f %% | %d | %.2f | %.3f | %.0f | %.2fx | %s |\n",
                  r.shape.c_str(), r.situation.c_str(), method.c_str(), r.exactContacts, r.pairs, 100 * detected,
                  100 * recall, r.falseContacts, r.normalError, r.depthError, r.nsPerPair, exactNs / r.nsPerPair,
                  r.method == "witness" && r.hitRate >= 0
                      ? (std::to_string(static_cast<int>(std::lround(100 * r.hitRate))) + " %").c_str()
                      : "");
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
