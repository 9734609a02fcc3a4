// Writes tools/scenes/pile.json: the built-in `pile` (builtinSceneSpec("pile"), its
// thousand bodies from pileScene's fixed-seed generator) as a scene file that steps bit for
// bit like it (tests/test_scene.cpp checks that). Run it again whenever pileScene changes:
//
//   cmake --build build --target weft_make_pile_json
//   build/bin/weft_make_pile_json tools/scenes/pile.json
//
// Every number is written as the shortest decimal that reads back as the same double (at
// most 17 significant digits), orientations as quaternions (the reader uses those exactly
// as written), and a body's fields only where they differ from the reader's defaults
// (which are RigidBodyDesc's), one body per line like stack.json. pileScene leaves the
// solver settings at their defaults, so the file lists none of them.
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <fstream>
#include <initializer_list>
#include <iostream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "weft/io/scene.hpp"
#include "weft/rigid/rigid_world.hpp"

namespace {

std::string number(double v) {
  if (!std::isfinite(v)) throw std::runtime_error("a number is not finite: " + std::to_string(v));
  if (v == 0) return std::signbit(v) ? "-0.0" : "0";  // "-0" would read back as the integer 0
  char buffer[32];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buffer, sizeof buffer, "%.*g", precision, v);
    if (std::strtod(buffer, nullptr) == v) break;
  }
  return buffer;
}

// (Appended piece by piece: operator+ on temporaries trips GCC 12's -Wrestrict falsely.)
std::string list(std::initializer_list<double> values) {
  std::string s = "[";
  for (const double v : values) {
    if (s.size() > 1) s += ", ";
    s += number(v);
  }
  s += "]";
  return s;
}

std::string vector(const Eigen::Vector3d& v) { return list({v.x(), v.y(), v.z()}); }

std::string quaternion(const Eigen::Quaterniond& q) {
  std::string s = R"({"quaternion": )";
  s += list({q.w(), q.x(), q.y(), q.z()});
  s += "}";
  return s;
}

bool identity(const Eigen::Quaterniond& q) { return q.coeffs() == Eigen::Quaterniond::Identity().coeffs(); }

std::string shape(const weft::RigidShapeDesc& s) {
  using Kind = weft::RigidShapeDesc::Kind;
  std::string j;
  if (s.kind == Kind::Box) {
    j = R"({"type": "box", "half_extents": )" + vector(s.halfExtents);
  } else if (s.kind == Kind::Sphere) {
    j = R"({"type": "sphere", "radius": )" + number(s.radius);
  } else {
    j = R"({"type": "hull", "points": [)";
    for (std::size_t k = 0; k < s.points.size(); ++k) j += (k ? ", " : "") + vector(s.points[k]);
    j += "]";
  }
  if (!s.offset.isZero(0)) j += R"(, "offset": )" + vector(s.offset);
  if (!identity(s.rotation)) j += R"(, "rotation": )" + quaternion(s.rotation);
  return j + "}";
}

std::string body(const weft::RigidBodyDesc& b) {
  const weft::RigidBodyDesc defaults;
  std::string j = R"({"name": )" + nlohmann::json(b.name).dump();
  if (b.motion == weft::BodyMotion::Static) j += R"(, "motion": "static")";
  if (b.motion == weft::BodyMotion::Kinematic)
    throw std::runtime_error(b.name + " is kinematic: this writer does not write paths");
  j += R"(, "shapes": [)";
  for (std::size_t k = 0; k < b.shapes.size(); ++k) j += (k ? ", " : "") + shape(b.shapes[k]);
  j += "]";
  if (b.density != defaults.density) j += R"(, "density": )" + number(b.density);
  if (b.mass != defaults.mass) j += R"(, "mass": )" + number(b.mass);
  if (!b.position.isZero(0)) j += R"(, "position": )" + vector(b.position);
  if (!identity(b.orientation)) j += R"(, "orientation": )" + quaternion(b.orientation);
  if (!b.velocity.isZero(0)) j += R"(, "velocity": )" + vector(b.velocity);
  if (!b.angularVelocity.isZero(0)) j += R"(, "angular_velocity": )" + vector(b.angularVelocity);
  if (b.staticFriction != defaults.staticFriction || b.kineticFriction != defaults.kineticFriction)
    j +=
        R"(, "static_friction": )" + number(b.staticFriction) + R"(, "kinetic_friction": )" + number(b.kineticFriction);
  if (b.restitution != defaults.restitution) j += R"(, "restitution": )" + number(b.restitution);
  return j + "}";
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: weft_make_pile_json OUTPUT.json   (tools/scenes/pile.json)\n";
    return 2;
  }
  try {
    const weft::SceneSpec spec = weft::builtinSceneSpec("pile");
    std::string text = "{\n";
    text += "  \"name\": " + nlohmann::json(spec.name).dump() + ",\n";
    text += "  \"dt\": " + number(spec.simulation.dt) + ",\n";
    text += "  \"steps\": " + std::to_string(spec.steps) + ",\n";
    text += "  \"rigid_bodies\": {\n    \"bodies\": [\n";
    const auto& bodies = spec.simulation.rigid.bodies;
    for (std::size_t k = 0; k < bodies.size(); ++k)
      text += "      " + body(bodies[k]) + (k + 1 < bodies.size() ? ",\n" : "\n");
    text += "    ]\n  }\n}\n";
    std::ofstream out(argv[1], std::ios::binary);
    out << text;
    out.close();
    if (!out) throw std::runtime_error(std::string("cannot write ") + argv[1] + ": " + std::strerror(errno));
  } catch (const std::exception& e) {
    std::cerr << "weft_make_pile_json: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
