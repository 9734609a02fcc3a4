// weft_bv_study — which bounding volume should preselect pairs for the narrow phase?
//
//   build/bin/weft_bv_study [--out DIR]
//
// Volumes: bounding sphere, AABB, OBB (the piece's own box, turned with it), k-DOPs with
// k = 6 (the three axes: the AABB again, computed the k-DOP way), 14 (axes and the four
// cube diagonals), 18 (axes and the six face diagonals) and 26 (all thirteen). Each is
// fitted to the piece in its pose and grown by the speculative distance (10 mm), so a pair
// closer than that always overlaps: every volume is conservative, and the study checks it
// (a missed contact is a bug, reported in the table). Fitting: the sphere and the OBB come
// from the piece's body-frame sphere and box moved to the pose (no vertex touched); the AABB
// and the k-DOPs project every hull vertex onto their directions in the pose (tight; a
// sphere piece is its centre plus the radius along each direction).
//
// Two cases:
//   pile     the built-in `pile` (1000 convex bodies in a bin; weft's own RigidWorld) at
//            0.25 s (falling), 1 s (landing) and 3 s (settled): every pair of pieces of
//            different bodies, at least one dynamic;
//   cloth    a 64 x 64 grid of particles (radius 5 mm, as RigidOptions::particleThickness)
//            lying over the settled pile at 0 to 20 mm above its top: every particle
//            against every piece.
// For each volume: candidate pairs (volumes overlap), true contacts (the exact narrow phase
// within the margin; a particle: distance to the piece), false candidates, missed contacts,
// ns to fit one volume, ns per overlap test, and the preselection's cost per step =
// fits + tests of all pairs + false candidates x the mean exact narrow-phase query on them
// (what a false candidate costs downstream). Times are medians of 5 passes.
// Output: Markdown on stdout; with --out, DIR/bv_study.md and DIR/bv_study.csv.
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "weft/rigid/narrow_phase.hpp"
#include "weft/rigid/rigid_world.hpp"
#include "weft/scene/rigid_scenes.hpp"

namespace {

using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kMargin = 0.01;           // m: RigidOptions::speculativeDistance
constexpr double kParticleRadius = 0.005;  // m: RigidOptions::particleThickness
constexpr int kMaxDirections = 13;

enum class Kind { Sphere, Aabb, Obb, Dop6, Dop14, Dop18, Dop26 };
constexpr std::array<Kind, 7> kKinds = {Kind::Sphere, Kind::Aabb,  Kind::Obb,  Kind::Dop6,
                                        Kind::Dop14,  Kind::Dop18, Kind::Dop26};

const char* kindName(Kind k) {
  switch (k) {
    case Kind::Sphere:
      return "sphere";
    case Kind::Aabb:
      return "AABB";
    case Kind::Obb:
      return "OBB";
    case Kind::Dop6:
      return "6-DOP";
    case Kind::Dop14:
      return "14-DOP";
    case Kind::Dop18:
      return "18-DOP";
    case Kind::Dop26:
      return "26-DOP";
  }
  return "?";
}

/// The k-DOP directions (unit): the axes, then the 4 cube diagonals, then the 6 face
/// diagonals. A k-DOP uses the first k/2 of the list it needs.
std::vector<Vector3d> directions(Kind k) {
  std::vector<Vector3d> d = {Vector3d::UnitX(), Vector3d::UnitY(), Vector3d::UnitZ()};
  const double s3 = 1 / std::sqrt(3.0), s2 = 1 / std::sqrt(2.0);
  const std::vector<Vector3d> corners = {{s3, s3, s3}, {s3, s3, -s3}, {s3, -s3, s3}, {-s3, s3, s3}};
  const std::vector<Vector3d> edges = {{s2, s2, 0}, {s2, -s2, 0}, {s2, 0, s2}, {s2, 0, -s2}, {0, s2, s2}, {0, s2, -s2}};
  if (k == Kind::Dop14 || k == Kind::Dop26) d.insert(d.end(), corners.begin(), corners.end());
  if (k == Kind::Dop18 || k == Kind::Dop26) d.insert(d.end(), edges.begin(), edges.end());
  return d;
}

/// One fitted volume. Sphere: centre, radius. OBB: centre, axes (columns), half extents.
/// AABB and k-DOPs: [lo, hi] along each direction.
struct Volume {
  Vector3d centre = Vector3d::Zero();
  double radius = 0;
  Matrix3d axes = Matrix3d::Identity();
  Vector3d half = Vector3d::Zero();
  std::array<double, kMaxDirections> lo{}, hi{};
};

struct Piece {
  const weft::RigidPiece* piece;
  const weft::ConvexHull* hull;  // null: a sphere
  weft::Pose pose;
  weft::Index body;
  bool dynamic;
};

Volume fit(Kind kind, const std::vector<Vector3d>& dirs, const Piece& p) {
  Volume v;
  const weft::RigidPiece& piece = *p.piece;
  switch (kind) {
    case Kind::Sphere:
      // RigidPiece::centre is in the body frame about the centre of mass; the pose is the
      // piece's, so go through the piece frame: centre_body = offset + rotation * c_piece.
      v.centre = p.pose.position + p.pose.rotation * (piece.rotation.transpose() * (piece.centre - piece.offset));
      v.radius = piece.boundingRadius + kMargin;
      return v;
    case Kind::Obb:
      v.centre = p.pose.position + p.pose.rotation * (0.5 * (piece.localMin + piece.localMax));
      v.axes = p.pose.rotation;
      v.half = 0.5 * (piece.localMax - piece.localMin) + Vector3d::Constant(kMargin);
      return v;
    default: {
      const std::size_t n = dirs.size();
      for (std::size_t k = 0; k < n; ++k) {
        v.lo[k] = std::numeric_limits<double>::infinity();
        v.hi[k] = -v.lo[k];
      }
      if (!p.hull) {
        for (std::size_t k = 0; k < n; ++k) {
          const double c = dirs[k].dot(p.pose.position);
          v.lo[k] = c - piece.radius - kMargin;
          v.hi[k] = c + piece.radius + kMargin;
        }
        return v;
      }
      for (const Vector3d& local : p.hull->vertices) {
        const Vector3d w = p.pose.position + p.pose.rotation * local;
        for (std::size_t k = 0; k < n; ++k) {
          const double s = dirs[k].dot(w);
          v.lo[k] = std::min(v.lo[k], s);
          v.hi[k] = std::max(v.hi[k], s);
        }
      }
      for (std::size_t k = 0; k < n; ++k) {
        v.lo[k] -= kMargin;
        v.hi[k] += kMargin;
      }
      return v;
    }
  }
}

/// Overlap of two volumes of the same kind (each grown by the margin: a pair within the
/// margin overlaps; the test is exact for the volumes, so no pair is lost).
bool overlap(Kind kind, std::size_t dirCount, const Volume& a, const Volume& b) {
  switch (kind) {
    case Kind::Sphere:
      return (a.centre - b.centre).squaredNorm() <= (a.radius + b.radius) * (a.radius + b.radius);
    case Kind::Obb: {
      // The separating-axis test of two boxes: 3 + 3 face axes and 9 edge-pair axes.
      const Matrix3d r = a.axes.transpose() * b.axes;
      const Matrix3d ar = r.cwiseAbs() + Matrix3d::Constant(1e-12);
      const Vector3d t = a.axes.transpose() * (b.centre - a.centre);
      for (int i = 0; i < 3; ++i)
        if (std::abs(t[i]) > a.half[i] + ar.row(i).dot(b.half)) return false;
      for (int j = 0; j < 3; ++j)
        if (std::abs(t.dot(r.col(j))) > ar.col(j).dot(a.half) + b.half[j]) return false;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) {
          const int i1 = (i + 1) % 3, i2 = (i + 2) % 3, j1 = (j + 1) % 3, j2 = (j + 2) % 3;
          const double ra = a.half[i1] * ar(i2, j) + a.half[i2] * ar(i1, j);
          const double rb = b.half[j1] * ar(i, j2) + b.half[j2] * ar(i, j1);
          if (std::abs(t[i2] * r(i1, j) - t[i1] * r(i2, j)) > ra + rb) return false;
        }
      return true;
    }
    default:
      for (std::size_t k = 0; k < dirCount; ++k)
        if (a.lo[k] > b.hi[k] || b.lo[k] > a.hi[k]) return false;
      return true;
  }
}

/// A particle (a sphere of kParticleRadius) as a volume of the kind (exact fits).
Volume particleVolume(Kind kind, const std::vector<Vector3d>& dirs, const Vector3d& x) {
  Volume v;
  const double r = kParticleRadius;
  v.centre = x;
  v.radius = r;
  v.half = Vector3d::Constant(r);
  for (std::size_t k = 0; k < dirs.size(); ++k) {
    v.lo[k] = dirs[k].dot(x) - r;
    v.hi[k] = dirs[k].dot(x) + r;
  }
  (void)kind;
  return v;
}

template <class Fn>
double medianNs(int passes, double perCount, Fn&& fn) {
  std::vector<double> t;
  for (int k = 0; k < passes; ++k) {
    const auto start = std::chrono::steady_clock::now();
    fn();
    t.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - start).count() / perCount);
  }
  std::sort(t.begin(), t.end());
  return t[t.size() / 2];
}

volatile std::size_t gSink = 0;  // keeps the timed loops from being optimised away

/// What a false candidate costs downstream: the median ns of the exact query over (up to
/// 2000 of, evenly spread) them; 0 when there are none.
template <class Query>
double falseCandidateNs(const std::vector<std::size_t>& falses, Query&& query) {
  const std::size_t sample = std::min<std::size_t>(falses.size(), 2000);
  if (sample == 0) return 0;
  return medianNs(3, static_cast<double>(sample), [&] {
    std::size_t c = 0;
    for (std::size_t s = 0; s < sample; ++s) c += query(falses[s * falses.size() / sample]);
    gSink = gSink + c;
  });
}

struct Row {
  std::string scene, volume;
  std::size_t pairs = 0, tested = 0, candidates = 0, contacts = 0, falseCandidates = 0, missed = 0;
  double fitNs = 0, testNs = 0, exactNs = 0, costUs = 0;
};

bool exactContact(const Piece& a, const Piece& b, weft::ContactManifold& out) {
  weft::NarrowPhaseOptions options;
  options.method = weft::NarrowPhaseMethod::Exact;
  weft::PairCache cache;
  if (!a.hull && !b.hull) {
    const double d = (a.pose.position - b.pose.position).norm() - a.piece->radius - b.piece->radius;
    return d <= kMargin;
  }
  if (!a.hull) {
    weft::collideSphereHull(a.pose.position, a.piece->radius, *b.hull, b.pose, kMargin, out);
  } else if (!b.hull) {
    weft::collideSphereHull(b.pose.position, b.piece->radius, *a.hull, a.pose, kMargin, out);
  } else {
    weft::collideHulls(*a.hull, a.pose, *b.hull, b.pose, kMargin, options, cache, out);
  }
  return out.pointCount > 0;
}

bool particleContact(const Vector3d& x, const Piece& p) {
  if (!p.hull) return (x - p.pose.position).norm() - p.piece->radius - kParticleRadius <= kMargin;
  weft::ContactManifold out;
  weft::collideSphereHull(x, kParticleRadius, *p.hull, p.pose, kMargin, out);
  return out.pointCount > 0;
}

std::vector<Row> studyPile(const std::string& name, const std::vector<Piece>& pieces) {
  const std::size_t n = pieces.size();
  std::vector<std::pair<int, int>> pairs;
  for (std::size_t i = 0; i < n; ++i)
    for (std::size_t j = i + 1; j < n; ++j)
      if (pieces[i].body != pieces[j].body && (pieces[i].dynamic || pieces[j].dynamic))
        pairs.emplace_back(static_cast<int>(i), static_cast<int>(j));
  // Ground truth on the sphere candidates (spheres are conservative by construction; the
  // check below confirms that no other volume misses one of these).
  const std::vector<Vector3d> none;
  std::vector<Volume> spheres(n);
  for (std::size_t i = 0; i < n; ++i) spheres[i] = fit(Kind::Sphere, none, pieces[i]);
  std::vector<char> truth(pairs.size(), 0);
  weft::ContactManifold scratch;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const auto [i, j] = pairs[k];
    if (overlap(Kind::Sphere, 0, spheres[i], spheres[j])) truth[k] = exactContact(pieces[i], pieces[j], scratch);
  }
  // The pairs a sort-and-sweep along x hands to the volume test (their boxes overlap in x):
  // the volumes are tested on these, as weft's broad phase does.
  std::vector<std::size_t> sweep;
  {
    const std::vector<Vector3d> axes = directions(Kind::Aabb);
    std::vector<Volume> boxes(n);
    for (std::size_t i = 0; i < n; ++i) boxes[i] = fit(Kind::Aabb, axes, pieces[i]);
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const Volume &a = boxes[pairs[k].first], &b = boxes[pairs[k].second];
      if (!(a.lo[0] > b.hi[0] || b.lo[0] > a.hi[0])) sweep.push_back(k);
    }
  }
  std::vector<Row> rows;
  for (const Kind kind : kKinds) {
    const std::vector<Vector3d> dirs = directions(kind);
    Row row;
    row.scene = name;
    row.volume = kindName(kind);
    row.pairs = pairs.size();
    std::vector<Volume> v(n);
    row.fitNs = medianNs(5, static_cast<double>(n), [&] {
      for (std::size_t i = 0; i < n; ++i) v[i] = fit(kind, dirs, pieces[i]);
    });
    std::vector<std::size_t> falses;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const bool c = overlap(kind, dirs.size(), v[pairs[k].first], v[pairs[k].second]);
      row.candidates += c;
      row.contacts += truth[k];
      if (c && !truth[k]) falses.push_back(k);
      row.missed += truth[k] && !c;
    }
    row.falseCandidates = falses.size();
    row.tested = sweep.size();
    row.testNs = medianNs(5, static_cast<double>(sweep.size()), [&] {
      std::size_t c = 0;
      for (const std::size_t k : sweep) c += overlap(kind, dirs.size(), v[pairs[k].first], v[pairs[k].second]);
      gSink = gSink + c;
    });
    row.exactNs = falseCandidateNs(falses, [&](std::size_t k) {
      const auto [i, j] = pairs[k];
      return exactContact(pieces[i], pieces[j], scratch);
    });
    row.costUs = 1e-3 * (row.fitNs * static_cast<double>(n) + row.testNs * static_cast<double>(sweep.size()) +
                         row.exactNs * static_cast<double>(row.falseCandidates));
    rows.push_back(row);
    std::fprintf(stderr, "%s %s: %zu candidates, %zu false, %zu missed\n", name.c_str(), row.volume.c_str(),
                 row.candidates, row.falseCandidates, row.missed);
  }
  return rows;
}

std::vector<Row> studyCloth(const std::vector<Piece>& pieces, const std::vector<Vector3d>& particles) {
  const std::size_t n = pieces.size(), m = particles.size();
  std::vector<Row> rows;
  std::vector<char> truth(n * m, 0);
  for (std::size_t q = 0; q < m; ++q)
    for (std::size_t i = 0; i < n; ++i) {
      // Spheres first (conservative) to keep the ground truth cheap.
      const Vector3d c =
          pieces[i].pose.position + pieces[i].pose.rotation * (pieces[i].piece->rotation.transpose() *
                                                               (pieces[i].piece->centre - pieces[i].piece->offset));
      if ((particles[q] - c).norm() > pieces[i].piece->boundingRadius + kParticleRadius + kMargin) continue;
      truth[q * n + i] = particleContact(particles[q], pieces[i]);
    }
  std::vector<Volume> boxes(n);
  const std::vector<Vector3d> axes = directions(Kind::Aabb);
  for (std::size_t i = 0; i < n; ++i) boxes[i] = fit(Kind::Aabb, axes, pieces[i]);
  for (const Kind kind : kKinds) {
    const std::vector<Vector3d> dirs = directions(kind);
    Row row;
    row.scene = "cloth on the pile";
    row.volume = kindName(kind);
    row.pairs = n * m;
    std::vector<Volume> v(n), pv(m);
    row.fitNs = medianNs(5, static_cast<double>(n), [&] {
      for (std::size_t i = 0; i < n; ++i) v[i] = fit(kind, dirs, pieces[i]);
    });
    for (std::size_t q = 0; q < m; ++q) pv[q] = particleVolume(kind, dirs, particles[q]);
    // A particle against a piece: the particle's volume of the same kind (for the OBB, the
    // particle's axis-aligned cube, tested by the box-box separating axes).
    std::vector<std::size_t> falses, sweep;
    for (std::size_t q = 0; q < m; ++q)
      for (std::size_t i = 0; i < n; ++i) {
        const double x = particles[q].x();
        if (x + kParticleRadius >= boxes[i].lo[0] && x - kParticleRadius <= boxes[i].hi[0]) sweep.push_back(q * n + i);
      }
    const auto test = [&](std::size_t q, std::size_t i) {
      return kind == Kind::Obb ? overlap(Kind::Obb, 0, pv[q], v[i]) : overlap(kind, dirs.size(), pv[q], v[i]);
    };
    for (std::size_t q = 0; q < m; ++q)
      for (std::size_t i = 0; i < n; ++i) {
        const bool c = test(q, i);
        const bool t = truth[q * n + i];
        row.candidates += c;
        row.contacts += t;
        if (c && !t) falses.push_back(q * n + i);
        row.missed += t && !c;
      }
    row.falseCandidates = falses.size();
    row.tested = sweep.size();
    row.testNs = medianNs(3, static_cast<double>(sweep.size()), [&] {
      std::size_t c = 0;
      for (const std::size_t f : sweep) c += test(f / n, f % n);
      gSink = gSink + c;
    });
    row.exactNs =
        falseCandidateNs(falses, [&](std::size_t f) { return particleContact(particles[f / n], pieces[f % n]); });
    row.costUs = 1e-3 * (row.fitNs * static_cast<double>(n) + row.testNs * static_cast<double>(sweep.size()) +
                         row.exactNs * static_cast<double>(row.falseCandidates));
    rows.push_back(row);
    std::fprintf(stderr, "cloth %s: %zu candidates, %zu false, %zu missed\n", row.volume.c_str(), row.candidates,
                 row.falseCandidates, row.missed);
  }
  return rows;
}

std::vector<Piece> piecesOf(const weft::RigidWorld& world) {
  const weft::RigidModel& m = world.model();
  std::vector<Piece> out;
  for (weft::Index p = 0; p < m.pieceCount(); ++p) {
    const weft::RigidPiece& piece = m.pieces[static_cast<std::size_t>(p)];
    Piece q;
    q.piece = &piece;
    q.hull = piece.kind == weft::RigidShapeDesc::Kind::Hull ? &m.hulls[static_cast<std::size_t>(piece.hull)] : nullptr;
    q.pose = world.piecePose(p, world.state());
    q.body = piece.body;
    q.dynamic = m.motion[static_cast<std::size_t>(piece.body)] == weft::BodyMotion::Dynamic;
    out.push_back(q);
  }
  return out;
}

/// A 64 x 64 grid over the bin's floor (4 m x 4 m, less 0.2 m a side), each particle 0 to
/// 20 mm (a fixed pattern) above the highest piece box under it: a cloth lying on the pile.
std::vector<Vector3d> clothOver(const std::vector<Piece>& pieces) {
  std::vector<Vector3d> out;
  const int side = 64;
  for (int r = 0; r < side; ++r)
    for (int c = 0; c < side; ++c) {
      const double x = -1.8 + 3.6 * c / (side - 1), z = -1.8 + 3.6 * r / (side - 1);
      double top = 0;
      for (const Piece& p : pieces) {
        if (!p.dynamic) continue;
        const Vector3d centre = p.pose.position + p.pose.rotation * (0.5 * (p.piece->localMin + p.piece->localMax));
        const Vector3d half = p.pose.rotation.cwiseAbs() * (0.5 * (p.piece->localMax - p.piece->localMin));
        if (std::abs(x - centre.x()) <= half.x() && std::abs(z - centre.z()) <= half.z())
          top = std::max(top, centre.y() + half.y());
      }
      out.emplace_back(x, top + kParticleRadius + 0.02 * ((r * 7 + c * 3) % 11) / 10.0, z);
    }
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  std::string out;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) {
      out = argv[++i];
    } else {
      std::fprintf(stderr, "usage: weft_bv_study [--out DIR]\n");
      return 2;
    }
  }
  weft::Executor exec(2);
  weft::RigidWorld world(weft::pileScene(1000), {0, -9.81, 0});
  std::vector<Row> rows;
  int steps = 0;
  for (const auto& [label, seconds] : std::vector<std::pair<std::string, double>>{
           {"pile, falling (0.25 s)", 0.25}, {"pile, landing (1 s)", 1.0}, {"pile, settled (3 s)", 3.0}}) {
    while (steps < static_cast<int>(std::lround(seconds / weft::rigidSceneTimeStep()))) {
      world.step(weft::rigidSceneTimeStep(), exec);
      ++steps;
    }
    const std::vector<Row> r = studyPile(label, piecesOf(world));
    rows.insert(rows.end(), r.begin(), r.end());
  }
  const std::vector<Piece> settled = piecesOf(world);
  const std::vector<Row> cloth = studyCloth(settled, clothOver(settled));
  rows.insert(rows.end(), cloth.begin(), cloth.end());

  std::ostringstream md, csv;
  csv << "scene,volume,pairs,tested,candidates,true_contacts,false_candidates,missed,fit_ns,test_ns,"
         "exact_ns_per_false,cost_us\n";
  md << "| case | volume | candidates / true contacts | false candidates | missed | fit, ns / volume | test, ns / "
        "pair | exact query per false candidate, ns | preselection cost, µs / step |\n"
        "|---|---|---|---|---|---|---|---|---|\n";
  for (const Row& r : rows) {
    char line[512];
    std::snprintf(line, sizeof line, "| %s | %s | %zu / %zu (%.2fx) | %zu | %zu | %.0f | %.2f | %.0f | %.0f |\n",
                  r.scene.c_str(), r.volume.c_str(), r.candidates, r.contacts,
                  r.contacts > 0 ? static_cast<double>(r.candidates) / static_cast<double>(r.contacts) : 0.0,
                  r.falseCandidates, r.missed, r.fitNs, r.testNs, r.exactNs, r.costUs);
    md << line;
    csv << '"' << r.scene << "\"," << r.volume << ',' << r.pairs << ',' << r.tested << ',' << r.candidates << ','
        << r.contacts << ',' << r.falseCandidates << ',' << r.missed << ',' << r.fitNs << ',' << r.testNs << ','
        << r.exactNs << ',' << r.costUs << '\n';
  }
  std::fputs(md.str().c_str(), stdout);
  if (!out.empty()) {
    std::filesystem::create_directories(out);
    std::ofstream(std::filesystem::path(out) / "bv_study.md") << md.str();
    std::ofstream(std::filesystem::path(out) / "bv_study.csv") << csv.str();
  }
  bool missed = false;
  for (const Row& r : rows) missed = missed || r.missed > 0;
  return missed ? 1 : 0;  // a volume that loses a contact is a bug
}
