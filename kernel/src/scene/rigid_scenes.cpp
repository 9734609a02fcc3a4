#include "weft/scene/rigid_scenes.hpp"

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "core/text.hpp"
#include "weft/scene/builtin_scenes.hpp"

namespace weft {

namespace {

using Point3 = Eigen::Vector3d;

RigidBodyDesc staticBox(const std::string& name, const Point3& centre, const Point3& half) {
  RigidBodyDesc b;
  b.name = name;
  b.motion = BodyMotion::Static;
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Kind::Box;
  s.halfExtents = half;
  b.shapes.push_back(s);
  b.position = centre;
  return b;
}

RigidBodyDesc dynamicBox(const std::string& name, const Point3& centre, const Point3& half, double density) {
  RigidBodyDesc b = staticBox(name, centre, half);
  b.motion = BodyMotion::Dynamic;
  b.density = density;
  return b;
}

RigidBodyDesc ballBody(const Point3& centre, double radius) {
  RigidBodyDesc ball;
  ball.name = "ball";
  RigidShapeDesc s;
  s.kind = RigidShapeDesc::Kind::Sphere;
  s.radius = radius;
  ball.shapes.push_back(s);
  ball.position = centre;
  return ball;
}

RigidBodyDesc floorBody() { return staticBox("floor", {0, -0.5, 0}, {5, 0.5, 5}); }

/// splitmix64: a generator whose output is fixed by its definition (unlike the standard
/// distributions), so the pile is the same scene on every machine and compiler.
struct SplitMix {
  std::uint64_t state;
  double uniform() {  // [0, 1)
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }
};

std::vector<Point3> icosahedron(double radius) {
  const double p = (1 + std::sqrt(5.0)) / 2;
  std::vector<Point3> v = {{-1, p, 0},  {1, p, 0},  {-1, -p, 0}, {1, -p, 0}, {0, -1, p},  {0, 1, p},
                           {0, -1, -p}, {0, 1, -p}, {p, 0, -1},  {p, 0, 1},  {-p, 0, -1}, {-p, 0, 1}};
  for (Point3& x : v) x *= radius / std::sqrt(std::fma(p, p, 1));  // fused: see pileScene
  return v;
}

std::vector<Point3> tetrahedron(double radius) {
  const double s = radius / std::sqrt(3.0);
  return {{s, s, s}, {s, -s, -s}, {-s, s, -s}, {-s, -s, s}};
}

}  // namespace

RigidOptions ballOnBrickScene() {
  RigidOptions o;
  o.bodies.push_back(floorBody());
  o.bodies.push_back(dynamicBox("brick", {0, 0.1, 0}, {0.2, 0.1, 0.1}, 2000));
  o.bodies.push_back(ballBody({0, 0.3, 0}, 0.1));  // 1000 kg/m^3
  return o;
}

RigidOptions stackScene(Index boxes) {
  if (boxes < 1) throw std::invalid_argument("stackScene: boxes must be >= 1, got " + std::to_string(boxes));
  RigidOptions o;
  o.bodies.push_back(floorBody());
  for (Index i = 0; i < boxes; ++i)
    o.bodies.push_back(dynamicBox("box" + std::to_string(i), {0, 0.25 + 0.5 * i, 0}, {0.25, 0.25, 0.25}, 500));
  return o;
}

RigidOptions pileScene(Index bodies) {
  if (bodies < 1) throw std::invalid_argument("pileScene: bodies must be >= 1, got " + std::to_string(bodies));
  RigidOptions o;
  o.bodies.push_back(staticBox("floor", {0, -0.5, 0}, {2.5, 0.5, 2.5}));
  o.bodies.push_back(staticBox("wall-x-", {-2.1, 0.5, 0}, {0.1, 0.5, 2.2}));
  o.bodies.push_back(staticBox("wall-x+", {2.1, 0.5, 0}, {0.1, 0.5, 2.2}));
  o.bodies.push_back(staticBox("wall-z-", {0, 0.5, -2.1}, {2.0, 0.5, 0.1}));
  o.bodies.push_back(staticBox("wall-z+", {0, 0.5, 2.1}, {2.0, 0.5, 0.1}));
  SplitMix rng{20261123};
  // A grid 10 x 10 wide over the bin, as many layers as it takes, 0.35 m apart.
  const Index side = 10;
  const double spacing = 0.35;
  for (Index i = 0; i < bodies; ++i) {
    const Index layer = i / (side * side), row = (i / side) % side, col = i % side;
    RigidBodyDesc b;
    b.name = "body" + std::to_string(i);
    // Every a * b + c is a std::fma: GCC fuses such C++ expressions itself (its default is
    // -ffp-contract=fast) when it optimises for a target with FMA, and not at -O0 or for
    // plain x86-64, so written plainly the pile differed between builds (and from
    // tools/scenes/pile.json, which holds its bits). Fused explicitly, every build makes
    // the pile that optimised -march=native builds made.
    b.density = std::fma(1000, rng.uniform(), 500);
    // One draw per statement, since the order of a call's arguments is unspecified. The
    // quaternion's and the box's were once drawn inside constructor calls, last argument
    // first as GCC does it, and keep that order.
    const double dx = 0.05 * (rng.uniform() - 0.5);
    const double dz = 0.05 * (rng.uniform() - 0.5);
    b.position = {std::fma(col - 4.5, spacing, dx), std::fma(layer, spacing, 0.4), std::fma(row - 4.5, spacing, dz)};
    const double qz = rng.uniform() - 0.5 + 1e-3;
    const double qy = rng.uniform() - 0.5;
    const double qx = rng.uniform() - 0.5;
    const double qw = rng.uniform() - 0.5;
    // Normalised in scalar code in a fixed order (w, x, y, z), not with Eigen's normalized(),
    // whose vectorised sum differs between SIMD widths (AVX2, AVX-512).
    const double norm = std::sqrt(std::fma(qz, qz, std::fma(qy, qy, std::fma(qx, qx, qw * qw))));
    b.orientation = Eigen::Quaterniond(qw / norm, qx / norm, qy / norm, qz / norm);
    const double size = std::fma(0.1, rng.uniform(), 0.1);
    RigidShapeDesc s;
    switch (i % 4) {
      case 0: {
        s.kind = RigidShapeDesc::Kind::Box;
        const double hz = std::fma(0.5, rng.uniform(), 0.5);
        const double hy = std::fma(0.5, rng.uniform(), 0.5);
        const double hx = std::fma(0.5, rng.uniform(), 0.5);
        s.halfExtents = Point3(hx, hy, hz) * (0.5 * size);
        break;
      }
      case 1:
        s.kind = RigidShapeDesc::Kind::Sphere;
        s.radius = 0.5 * size;
        break;
      case 2:
        s.kind = RigidShapeDesc::Kind::Hull;
        s.points = icosahedron(0.6 * size);
        break;
      default:
        s.kind = RigidShapeDesc::Kind::Hull;
        s.points = tetrahedron(0.7 * size);
        break;
    }
    b.shapes.push_back(s);
    o.bodies.push_back(b);
  }
  return o;
}

RigidOptions bulletScene(double speed) {
  if (!(std::isfinite(speed) && speed >= 0)) detail::rejectField("bulletScene: speed", speed, "finite and >= 0 (m/s)");
  RigidOptions o;
  o.bodies.push_back(staticBox("plate", {1.005, 0, 0}, {0.005, 1, 1}));
  RigidBodyDesc bullet = dynamicBox("bullet", {0, 0, 0}, {0.02, 0.02, 0.02}, 8000);
  bullet.velocity = {speed, 0, 0};
  o.bodies.push_back(bullet);
  return o;
}

RigidOptions slopeScene(double degrees, double mu) {
  if (!(degrees >= 0 && degrees < 90)) detail::rejectField("slopeScene: degrees", degrees, "in [0, 90)");
  if (!(std::isfinite(mu) && mu >= 0)) detail::rejectField("slopeScene: mu", mu, "finite and >= 0");
  const double a = degrees * 3.14159265358979323846 / 180;
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(a, Point3::UnitZ()));  // down the slope: -x
  const Point3 up = tilt * Point3::UnitY();
  RigidOptions o;
  RigidBodyDesc plane = staticBox("slope", -0.5 * up, {5, 0.5, 5});
  plane.orientation = tilt;
  plane.staticFriction = plane.kineticFriction = mu;
  o.bodies.push_back(plane);
  RigidBodyDesc box = dynamicBox("box", 0.1 * up, {0.1, 0.1, 0.1}, 1000);
  box.orientation = tilt;
  box.staticFriction = box.kineticFriction = mu;
  o.bodies.push_back(box);
  return o;
}

RigidOptions hammockBall() {
  RigidOptions o;
  RigidBodyDesc ball = ballBody({0, 1.0, 0}, 0.12);
  ball.mass = 1;
  o.bodies.push_back(ball);
  return o;
}

namespace {
/// A square cloth's side: at least 2, and its particles' indices within an Index (as
/// addClothGrid requires: at most 2^28 particles).
void requireSide(const char* field, Index size) {
  if (size < 2 || size > (Index(1) << 14))
    throw std::invalid_argument(std::string(field) + " must be in [2, 16384], got " + std::to_string(size));
}
}  // namespace

ClothGridSpec hammockCloth(Index size) {
  requireSide("hammockCloth: size", size);
  ClothGridSpec spec = flagSpec(size);
  spec.origin = {-0.5, 0.5, -0.5};
  return spec;
}

std::vector<Index> hammockPins(Index size) {
  requireSide("hammockPins: size", size);
  return {0, size - 1, size * (size - 1), size * size - 1};
}

namespace {
// The tablecloth trick's layout: the cloth lies one particle thickness (the default
// RigidOptions::particleThickness) above the table, the objects one more above it.
constexpr double kClothThickness = 0.005;  // m
constexpr double kClothLeft = -0.6;        // m: the cloth spans x in [kClothLeft, kClothLeft + 1]
constexpr double kPullDistance = 1.4;      // m: the edge ends 0.6 m past the table's end
}  // namespace

RigidOptions tableclothBodies() {
  const double top = tableclothTableTop();
  const double standing = top + 2 * kClothThickness;  // the objects' underside
  RigidOptions o;
  RigidBodyDesc table = staticBox("table", {0, 0.5 * top, 0}, {0.8, 0.5 * top, 0.6});
  table.staticFriction = 0.3;  // the cloth slides on it (the particles take the table's coefficients)
  table.kineticFriction = 0.25;
  o.bodies.push_back(table);
  const double half = 0.08;
  for (const double z : {-0.2, 0.2}) {
    RigidBodyDesc box = dynamicBox(z < 0 ? "box-1" : "box-2", {-0.25, standing + half, z}, {half, half, half}, 400);
    box.staticFriction = 0.5;
    box.kineticFriction = 0.4;
    o.bodies.push_back(box);
  }
  const double radius = 0.07;
  RigidBodyDesc ball = ballBody({0.05, standing + radius, 0}, radius);
  ball.density = 700;
  ball.staticFriction = 0.5;
  ball.kineticFriction = 0.4;
  o.bodies.push_back(ball);
  return o;
}

ClothGridSpec tableclothCloth(Index size) {
  requireSide("tableclothCloth: size", size);
  ClothGridSpec spec = flagSpec(size);  // rows along +x, columns along +z
  spec.origin = {kClothLeft, tableclothTableTop() + kClothThickness, -0.5};
  return spec;
}

std::vector<Index> tableclothGrip(Index size) {
  // Particle (row r, column c) is r * size + c at origin + c spacing x + r spacing z: the
  // +x edge is the last column.
  requireSide("tableclothGrip: size", size);
  std::vector<Index> grip;
  for (Index r = 0; r < size; ++r) grip.push_back(r * size + size - 1);
  return grip;
}

KinematicPath tableclothPull(double speed) {
  if (!(std::isfinite(speed) && speed > 0)) detail::rejectField("tableclothPull: speed", speed, "finite and > 0 (m/s)");
  KinematicPath path;
  path.velocity = {speed, 0, 0};
  path.startTime = 0;
  path.endTime = kPullDistance / speed;
  return path;
}

}  // namespace weft
