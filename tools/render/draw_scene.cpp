#include "draw_scene.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "weft/core/kinematic_path.hpp"

namespace weftrender {

namespace {

using Vec3f = Eigen::Vector3f;

// Linear RGB (the renderer converts to sRGB). Cloth: a deep front and a pale back.
struct ClothColours {
  Vec3f front, back;
};
const ClothColours kCloth[] = {
    {{0.62f, 0.07f, 0.05f}, {0.86f, 0.72f, 0.48f}},  // red / cream
    {{0.06f, 0.20f, 0.55f}, {0.68f, 0.80f, 0.92f}},  // blue / pale blue
    {{0.08f, 0.38f, 0.12f}, {0.74f, 0.88f, 0.66f}},  // green / pale green
    {{0.58f, 0.34f, 0.04f}, {0.92f, 0.84f, 0.62f}},  // ochre / straw
};
const Vec3f kObstacle{0.30f, 0.36f, 0.45f};
const Vec3f kStaticBody{0.42f, 0.42f, 0.42f};
const Vec3f kDynamicBody{0.80f, 0.48f, 0.10f};
const Vec3f kKinematicBody{0.10f, 0.45f, 0.45f};
const Vec3f kRope{0.22f, 0.12f, 0.05f};

Vec3f toF(const Eigen::Vector3d& v) { return v.cast<float>(); }
Vec3f toF(const weft::Vec3d& v) {
  return Vec3f(static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z));
}
weft::Vec3d toD(const Vec3f& v) { return {v.x(), v.y(), v.z()}; }

/// Two unit vectors perpendicular to the unit `axis` and to each other.
void perpendiculars(const Vec3f& axis, Vec3f& e1, Vec3f& e2) {
  const Vec3f helper = std::abs(axis.x()) < 0.9f ? Vec3f::UnitX() : Vec3f::UnitY();
  e1 = axis.cross(helper).normalized();
  e2 = axis.cross(e1);
}

/// A sphere swept along the segment a -> b (a == b: a sphere): latitude rings, the lower
/// hemisphere around a and the upper around b, joined by the cylinder between.
void appendCapsule(const Vec3f& a, const Vec3f& b, float radius, int around, int rings, std::vector<Vec3f>& vertices,
                   std::vector<Vec3f>& normals, std::vector<std::uint32_t>& indices) {
  Vec3f axis = b - a;
  axis = axis.norm() > 0 ? axis.normalized() : Vec3f::UnitY();
  Vec3f e1, e2;
  perpendiculars(axis, e1, e2);
  const auto base = static_cast<std::uint32_t>(vertices.size());
  const int ringCount = 2 * (rings + 1);
  for (int i = 0; i < ringCount; ++i) {
    const bool upper = i > rings;
    const int k = upper ? i - (rings + 1) : i;
    const float phi = static_cast<float>(std::numbers::pi) * (upper ? 0.5f * k / rings : -0.5f + 0.5f * k / rings);
    for (int j = 0; j < around; ++j) {
      const float theta = 2 * static_cast<float>(std::numbers::pi) * j / around;
      const Vec3f n = std::cos(phi) * (std::cos(theta) * e1 + std::sin(theta) * e2) + std::sin(phi) * axis;
      vertices.push_back((upper ? b : a) + radius * n);
      normals.push_back(n);
    }
  }
  for (int i = 0; i + 1 < ringCount; ++i)
    for (int j = 0; j < around; ++j) {
      const std::uint32_t p = base + static_cast<std::uint32_t>(i * around + j);
      const std::uint32_t q = base + static_cast<std::uint32_t>(i * around + (j + 1) % around);
      const std::uint32_t pu = p + static_cast<std::uint32_t>(around), qu = q + static_cast<std::uint32_t>(around);
      indices.insert(indices.end(), {p, q, qu, p, qu, pu});
    }
}

/// A box of half extents h centred at c, axis-aligned, flat normals.
void appendBox(const Vec3f& c, const Vec3f& h, std::vector<Vec3f>& vertices, std::vector<Vec3f>& normals,
               std::vector<std::uint32_t>& indices) {
  for (int axis = 0; axis < 3; ++axis)
    for (int side = -1; side <= 1; side += 2) {
      Vec3f n = Vec3f::Zero();
      n[axis] = static_cast<float>(side);
      const int u = (axis + 1) % 3, v = (axis + 2) % 3;
      const auto base = static_cast<std::uint32_t>(vertices.size());
      for (int corner = 0; corner < 4; ++corner) {
        Vec3f p = c;
        p[axis] += side * h[axis];
        p[u] += ((corner == 1 || corner == 2) ? 1.f : -1.f) * h[u];
        p[v] += (corner >= 2 ? 1.f : -1.f) * h[v];
        vertices.push_back(p);
        normals.push_back(n);
      }
      // Corners run (-,-), (+,-), (+,+), (-,+) in (u, v): counter-clockwise about +axis.
      if (side > 0)
        indices.insert(indices.end(), {base, base + 1, base + 2, base, base + 2, base + 3});
      else
        indices.insert(indices.end(), {base, base + 2, base + 1, base, base + 3, base + 2});
    }
}

/// A convex hull's faces as fans, flat normals, wound counter-clockwise from outside.
void appendHull(const weft::ConvexHull& hull, std::vector<Vec3f>& vertices, std::vector<Vec3f>& normals,
                std::vector<std::uint32_t>& indices) {
  for (int f = 0; f < hull.faceCount(); ++f) {
    const auto loop = hull.faceIndices(f);
    const Vec3f n = toF(hull.faces[static_cast<std::size_t>(f)].normal);
    const auto base = static_cast<std::uint32_t>(vertices.size());
    for (const int v : loop) {
      vertices.push_back(toF(hull.vertices[static_cast<std::size_t>(v)]));
      normals.push_back(n);
    }
    if (loop.size() < 3) continue;
    const Vec3f turn = (vertices[base + 1] - vertices[base]).cross(vertices[base + 2] - vertices[base]);
    const bool flip = turn.dot(n) < 0;
    for (std::uint32_t k = 1; k + 1 < loop.size(); ++k) {
      if (flip)
        indices.insert(indices.end(), {base, base + k + 1, base + k});
      else
        indices.insert(indices.end(), {base, base + k, base + k + 1});
    }
  }
}

/// Area-weighted vertex normals of a triangle mesh.
void smoothNormals(const std::vector<Vec3f>& vertices, const std::vector<std::uint32_t>& indices,
                   std::vector<Vec3f>& normals) {
  normals.assign(vertices.size(), Vec3f::Zero());
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3) {
    const Vec3f& a = vertices[indices[t]];
    const Vec3f n = (vertices[indices[t + 1]] - a).cross(vertices[indices[t + 2]] - a);
    for (int k = 0; k < 3; ++k) normals[indices[t + static_cast<std::size_t>(k)]] += n;
  }
  for (Vec3f& n : normals) n = n.norm() > 0 ? n.normalized() : Vec3f::UnitY();
}

Vec3f transform(const weft::Pose& pose, const Vec3f& p) {
  return (pose.rotation * p.cast<double>() + pose.position).cast<float>();
}

}  // namespace

template <class S>
SceneDrawer::SceneDrawer(const weft::Model<S>& model, const std::vector<weft::Index>& firstParticle,
                         const weft::CollisionOptions& collision, const weft::RigidModel* rigid)
    : particleCount_(model.particleCount()) {
  // Cloth: each body's triangles (bodies are consecutive particle ranges).
  std::vector<weft::Index> starts = firstParticle;
  if (starts.empty()) starts.push_back(0);
  const weft::Triangles& tr = model.triangles();
  std::vector<char> inTriangle(static_cast<std::size_t>(particleCount_), 0);
  for (std::size_t b = 0; b < starts.size(); ++b) {
    Cloth cloth;
    cloth.first = starts[b];
    cloth.count = (b + 1 < starts.size() ? starts[b + 1] : particleCount_) - cloth.first;
    for (weft::Index t = 0; t < tr.count(); ++t) {
      if (tr.a[t] < cloth.first || tr.a[t] >= cloth.first + cloth.count) continue;
      for (const weft::Index p : {tr.a[t], tr.b[t], tr.c[t]}) {
        cloth.indices.push_back(static_cast<std::uint32_t>(p - cloth.first));
        inTriangle[static_cast<std::size_t>(p)] = 1;
      }
    }
    if (cloth.indices.empty()) continue;
    const ClothColours& c = kCloth[cloths_.size() % std::size(kCloth)];
    cloth.front = c.front;
    cloth.back = c.back;
    cloths_.push_back(std::move(cloth));
  }
  // Ropes: structural springs between particles of no triangle.
  const weft::Springs<S>& springs = model.springs();
  for (weft::Index s = 0; s < springs.count(); ++s)
    if (springs.kind[static_cast<std::size_t>(s)] == weft::SpringClass::Structural &&
        !inTriangle[static_cast<std::size_t>(springs.a[s])] && !inTriangle[static_cast<std::size_t>(springs.b[s])])
      rope_.segments.push_back({springs.a[s], springs.b[s]});

  // Analytic obstacles.
  for (const weft::Obstacle& o : collision.obstacles) {
    PlacedShape placed;
    placed.colour = kObstacle;
    Shape& s = placed.shape;
    switch (o.kind) {
      case weft::ObstacleKind::Plane: {
        const Vec3f n = toF(o.normal).normalized();
        if (n.y() > 0.999f) {
          groundPlane_ =
              std::max(groundPlane_.value_or(-std::numeric_limits<float>::infinity()), static_cast<float>(o.point.y));
        } else {
          planes_.push_back(o);
        }
        continue;
      }
      case weft::ObstacleKind::Sphere:
        appendCapsule(toF(o.point), toF(o.point), static_cast<float>(o.radius), 48, 16, s.vertices, s.normals,
                      s.indices);
        break;
      case weft::ObstacleKind::Capsule:
        appendCapsule(toF(o.point), toF(o.end), static_cast<float>(o.radius), 32, 8, s.vertices, s.normals, s.indices);
        break;
      case weft::ObstacleKind::Box:
        appendBox(toF(o.point), toF(o.halfExtents) + Vec3f::Constant(static_cast<float>(o.radius)), s.vertices,
                  s.normals, s.indices);
        break;
    }
    shapes_.push_back(std::move(placed));
  }
  // Mesh obstacles, at time 0 (a path moves them).
  for (const weft::MeshObstacle& m : collision.meshes) {
    PlacedShape placed;
    placed.colour = kObstacle;
    for (const weft::Vec3d& v : m.mesh.vertices) placed.shape.vertices.push_back(toF(v));
    for (const auto& t : m.mesh.triangles)
      for (const weft::Index k : t) placed.shape.indices.push_back(static_cast<std::uint32_t>(k));
    smoothNormals(placed.shape.vertices, placed.shape.indices, placed.shape.normals);
    if (m.path) {
      placed.path = static_cast<int>(paths_.size());
      paths_.push_back(*m.path);
    }
    shapes_.push_back(std::move(placed));
  }
  // Rigid pieces, in their own frames (RigidWorld::piecePose places them).
  if (rigid) {
    for (weft::Index p = 0; p < rigid->pieceCount(); ++p) {
      const weft::RigidPiece& piece = rigid->pieces[static_cast<std::size_t>(p)];
      PlacedShape placed;
      const weft::BodyMotion motion = rigid->motion[static_cast<std::size_t>(piece.body)];
      placed.colour = motion == weft::BodyMotion::Static      ? kStaticBody
                      : motion == weft::BodyMotion::Kinematic ? kKinematicBody
                                                              : kDynamicBody;
      // Neighbouring bodies in shades of their colour, so a stack shows its boxes.
      if (motion == weft::BodyMotion::Dynamic)
        placed.colour *= 0.72f + 0.28f * static_cast<float>(piece.body % 3) / 2.f;
      placed.staticBody = motion == weft::BodyMotion::Static;
      placed.piece = static_cast<int>(p);
      Shape& s = placed.shape;
      if (piece.kind == weft::RigidShapeDesc::Kind::Sphere)
        appendCapsule(Vec3f::Zero(), Vec3f::Zero(), static_cast<float>(piece.radius), 24, 8, s.vertices, s.normals,
                      s.indices);
      else
        appendHull(rigid->hulls[static_cast<std::size_t>(piece.hull)], s.vertices, s.normals, s.indices);
      shapes_.push_back(std::move(placed));
    }
  }
}

template <class S>
SceneSnapshot SceneDrawer::snapshot(const weft::Simulation<S>& sim) const {
  SceneSnapshot snap;
  const weft::State<S>& state = sim.state();
  snap.time = static_cast<double>(state.time);
  snap.x.resize(static_cast<std::size_t>(3 * state.x.rows()));
  for (weft::Index i = 0; i < state.x.rows(); ++i)
    for (int k = 0; k < 3; ++k) snap.x[static_cast<std::size_t>(3 * i + k)] = static_cast<float>(state.x(i, k));
  if (const weft::RigidWorld* world = sim.rigidWorld()) {
    snap.pieces.reserve(static_cast<std::size_t>(world->model().pieceCount()));
    for (weft::Index p = 0; p < world->model().pieceCount(); ++p)
      snap.pieces.push_back(world->piecePose(p, world->state()));
  }
  return snap;
}

void SceneDrawer::findFloors(const SceneSnapshot& initial) {
  const Bounds framed = framedBounds(initial);
  for (PlacedShape& placed : shapes_) {
    if (!placed.staticBody || placed.piece < 0 || static_cast<std::size_t>(placed.piece) >= initial.pieces.size())
      continue;
    Bounds box;
    for (const Vec3f& v : placed.shape.vertices)
      box.add(transform(initial.pieces[static_cast<std::size_t>(placed.piece)], v));
    const Vec3f size = box.hi - box.lo;
    const bool flat = size.y() <= 0.2f * std::max(size.x(), size.z());
    const bool large = framed.empty() || box.radius() > 2.f * framed.radius();
    if (flat && large && (framed.empty() || box.hi.y() <= framed.lo.y() + 0.05f * framed.radius())) {
      placed.floor = true;
      groundPlane_ = std::max(groundPlane_.value_or(-std::numeric_limits<float>::infinity()), box.hi.y());
    }
  }
}

float SceneDrawer::tubeRadius(const Bounds& bounds) const { return std::max(0.004f * bounds.radius(), 1e-4f); }

void SceneDrawer::build(const SceneSnapshot& snap, float tubeRadius, DrawFrame& out) const {
  std::size_t used = 0;
  const auto next = [&]() -> DrawMesh& {
    if (used == out.meshes.size()) out.meshes.emplace_back();
    DrawMesh& m = out.meshes[used++];
    m.positions.clear();
    m.normals.clear();
    m.indices.clear();
    m.castsShadow = true;
    return m;
  };
  const auto particle = [&](weft::Index i) {
    const float* p = &snap.x[static_cast<std::size_t>(3 * i)];
    return Vec3f(p[0], p[1], p[2]);
  };

  std::vector<Vec3f> scratch, scratchNormals;
  for (const Cloth& cloth : cloths_) {
    DrawMesh& m = next();
    m.front = cloth.front;
    m.back = cloth.back;
    scratch.resize(static_cast<std::size_t>(cloth.count));
    for (weft::Index i = 0; i < cloth.count; ++i) scratch[static_cast<std::size_t>(i)] = particle(cloth.first + i);
    smoothNormals(scratch, cloth.indices, scratchNormals);
    for (std::size_t i = 0; i < scratch.size(); ++i) {
      m.positions.insert(m.positions.end(), scratch[i].data(), scratch[i].data() + 3);
      m.normals.insert(m.normals.end(), scratchNormals[i].data(), scratchNormals[i].data() + 3);
    }
    m.indices = cloth.indices;
  }

  if (!rope_.segments.empty()) {
    DrawMesh& m = next();
    m.front = m.back = kRope;
    scratch.clear();
    scratchNormals.clear();
    for (const auto& [a, b] : rope_.segments)
      appendCapsule(particle(a), particle(b), tubeRadius, 8, 2, scratch, scratchNormals, m.indices);
    for (std::size_t i = 0; i < scratch.size(); ++i) {
      m.positions.insert(m.positions.end(), scratch[i].data(), scratch[i].data() + 3);
      m.normals.insert(m.normals.end(), scratchNormals[i].data(), scratchNormals[i].data() + 3);
    }
  }

  for (const PlacedShape& placed : shapes_) {
    if (placed.floor) continue;
    DrawMesh& m = next();
    m.front = m.back = placed.colour;
    // A large static body (a floor slab) casts its shadow on nothing worth seeing.
    m.castsShadow = !placed.staticBody;
    const std::size_t n = placed.shape.vertices.size();
    m.positions.resize(3 * n);
    m.normals.resize(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
      Vec3f p = placed.shape.vertices[i], normal = placed.shape.normals[i];
      if (placed.piece >= 0 && static_cast<std::size_t>(placed.piece) < snap.pieces.size()) {
        const weft::Pose& pose = snap.pieces[static_cast<std::size_t>(placed.piece)];
        p = transform(pose, p);
        normal = (pose.rotation * normal.cast<double>()).cast<float>();
      } else if (placed.path >= 0) {
        const weft::KinematicPath& path = paths_[static_cast<std::size_t>(placed.path)];
        p = toF(weft::kinematicPosition(path, toD(p), snap.time));
        normal = toF(weft::kinematicRotate(path, toD(normal), snap.time));
      }
      for (int k = 0; k < 3; ++k) {
        m.positions[3 * i + static_cast<std::size_t>(k)] = p[k];
        m.normals[3 * i + static_cast<std::size_t>(k)] = normal[k];
      }
    }
    m.indices = placed.shape.indices;
  }

  // Planes that do not face up: a square around the framed region's nearest point.
  out.framed = framedBounds(snap);
  for (const weft::Obstacle& plane : planes_) {
    if (out.framed.empty()) break;
    DrawMesh& m = next();
    m.front = m.back = kObstacle;
    m.castsShadow = false;
    const Vec3f n = toF(plane.normal).normalized();
    const Vec3f c = out.framed.centre();
    const Vec3f centre = c - n * n.dot(c - toF(plane.point));
    Vec3f e1, e2;
    perpendiculars(n, e1, e2);
    const float h = 1.5f * out.framed.radius();
    const Vec3f corners[4] = {centre - h * e1 - h * e2, centre + h * e1 - h * e2, centre + h * e1 + h * e2,
                              centre - h * e1 + h * e2};
    for (const Vec3f& corner : corners) {
      m.positions.insert(m.positions.end(), corner.data(), corner.data() + 3);
      m.normals.insert(m.normals.end(), n.data(), n.data() + 3);
    }
    // e1 x e2 = n: (0, 1, 2) runs counter-clockwise about n.
    m.indices = {0, 1, 2, 0, 2, 3};
  }
  out.meshes.resize(used);
  out.groundHeight = groundPlane_;
}

Bounds SceneDrawer::framedBounds(const SceneSnapshot& snap) const {
  Bounds subject;
  for (std::size_t i = 0; i + 2 < snap.x.size(); i += 3) {
    const Vec3f p(snap.x[i], snap.x[i + 1], snap.x[i + 2]);
    if (p.allFinite()) subject.add(p);
  }
  std::vector<Bounds> staticBoxes;
  for (const PlacedShape& placed : shapes_) {
    if (placed.floor) continue;
    Bounds box;
    for (const Vec3f& v : placed.shape.vertices) {
      Vec3f p = v;
      if (placed.piece >= 0 && static_cast<std::size_t>(placed.piece) < snap.pieces.size())
        p = transform(snap.pieces[static_cast<std::size_t>(placed.piece)], v);
      else if (placed.path >= 0)
        p = toF(weft::kinematicPosition(paths_[static_cast<std::size_t>(placed.path)], toD(v), snap.time));
      if (p.allFinite()) box.add(p);
    }
    if (placed.staticBody)
      staticBoxes.push_back(box);
    else
      subject.add(box);
  }
  // Static bodies: framed unless one dwarfs what moves (a floor under a stack).
  const float r = subject.radius();
  for (const Bounds& box : staticBoxes)
    if (subject.empty() || box.radius() <= 2.f * r) subject.add(box);
  if (subject.empty())
    for (const Bounds& box : staticBoxes) subject.add(box);
  return subject;
}

template SceneDrawer::SceneDrawer(const weft::Model<float>&, const std::vector<weft::Index>&,
                                  const weft::CollisionOptions&, const weft::RigidModel*);
template SceneDrawer::SceneDrawer(const weft::Model<double>&, const std::vector<weft::Index>&,
                                  const weft::CollisionOptions&, const weft::RigidModel*);
template SceneSnapshot SceneDrawer::snapshot(const weft::Simulation<float>&) const;
template SceneSnapshot SceneDrawer::snapshot(const weft::Simulation<double>&) const;

}  // namespace weftrender
