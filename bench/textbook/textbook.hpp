// The textbook mass-spring cloth: what a newcomer writes from the Witkin/Baraff notes and
// the original design's slides (a CVector3D class with overloaded operators, a particle
// struct, a spring struct, RK4 by copying the particle vector per stage). It exists only
// as the honest baseline for bench/ (same scene, same parameters; a test checks that it
// agrees with weft's RK4) and deliberately uses none of weft's techniques.
#pragma once

#include <cmath>
#include <vector>

#include "weft/model/model_builder.hpp"

namespace textbook {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  Vec3() = default;
  Vec3(double x_, double y_, double z_) : x(x_), y(y_), z(z_) {}
  Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
  Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
  Vec3& operator+=(const Vec3& o) {
    x += o.x;
    y += o.y;
    z += o.z;
    return *this;
  }
  Vec3& operator-=(const Vec3& o) {
    x -= o.x;
    y -= o.y;
    z -= o.z;
    return *this;
  }
  double dot(const Vec3& o) const { return x * o.x + y * o.y + z * o.z; }
  double length() const { return std::sqrt(dot(*this)); }
};

struct Particle {
  Vec3 x, v, f;
  double m = 1;
  bool pinned = false;
};

struct Spring {
  int a = 0, b = 0;
  double r = 0;  // rest length
  double ks = 0, kd = 0;
};

class Cloth {
 public:
  /// Copies particles and springs (same order) from a weft model and state.
  Cloth(const weft::Model<double>& model, const weft::State<double>& state, const weft::Vec3d& gravity);

  void stepRk4(double h);
  const std::vector<Particle>& particles() const { return particles_; }

 private:
  struct Derivative {
    Vec3 dx, dv;
  };
  void computeForces(std::vector<Particle>& p) const;
  std::vector<Derivative> evaluate(std::vector<Particle>& p) const;

  std::vector<Particle> particles_;
  std::vector<Spring> springs_;
  Vec3 gravity_;
};

}  // namespace textbook
