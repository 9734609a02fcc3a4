#include "textbook.hpp"

namespace textbook {

Cloth::Cloth(const weft::Model<double>& model, const weft::State<double>& state, const weft::Vec3d& gravity)
    : gravity_(gravity.x, gravity.y, gravity.z) {
  for (int i = 0; i < model.particleCount(); ++i) {
    Particle p;
    p.x = {state.x(i, 0), state.x(i, 1), state.x(i, 2)};
    p.v = {state.v(i, 0), state.v(i, 1), state.v(i, 2)};
    p.m = model.mass()[i];
    p.pinned = model.isPinned(i);
    particles_.push_back(p);
  }
  const auto& s = model.springs();
  for (int k = 0; k < s.count(); ++k)
    springs_.push_back({s.a[k], s.b[k], s.restLength[k], s.stiffness[k], s.damping[k]});
}

void Cloth::computeForces(std::vector<Particle>& p) const {
  for (Particle& q : p) q.f = q.pinned ? Vec3() : gravity_ * q.m;
  for (const Spring& s : springs_) {
    Vec3 dx = p[s.a].x - p[s.b].x;
    Vec3 dv = p[s.a].v - p[s.b].v;
    double len = dx.length();
    if (len == 0) continue;
    Vec3 f = dx / len * -(s.ks * (len - s.r) + s.kd * dv.dot(dx) / len);
    p[s.a].f += f;
    p[s.b].f -= f;
  }
}

std::vector<Cloth::Derivative> Cloth::evaluate(std::vector<Particle>& p) const {
  computeForces(p);
  std::vector<Derivative> d(p.size());
  for (size_t i = 0; i < p.size(); ++i) {
    d[i].dx = p[i].v;
    d[i].dv = p[i].pinned ? Vec3() : p[i].f / p[i].m;
  }
  return d;
}

void Cloth::stepRk4(double h) {
  std::vector<Particle> s0 = particles_;
  std::vector<Derivative> k1 = evaluate(s0);
  std::vector<Particle> s1 = particles_;
  for (size_t i = 0; i < s1.size(); ++i) {
    s1[i].x = particles_[i].x + k1[i].dx * (h / 2);
    s1[i].v = particles_[i].v + k1[i].dv * (h / 2);
  }
  std::vector<Derivative> k2 = evaluate(s1);
  std::vector<Particle> s2 = particles_;
  for (size_t i = 0; i < s2.size(); ++i) {
    s2[i].x = particles_[i].x + k2[i].dx * (h / 2);
    s2[i].v = particles_[i].v + k2[i].dv * (h / 2);
  }
  std::vector<Derivative> k3 = evaluate(s2);
  std::vector<Particle> s3 = particles_;
  for (size_t i = 0; i < s3.size(); ++i) {
    s3[i].x = particles_[i].x + k3[i].dx * h;
    s3[i].v = particles_[i].v + k3[i].dv * h;
  }
  std::vector<Derivative> k4 = evaluate(s3);
  for (size_t i = 0; i < particles_.size(); ++i) {
    particles_[i].x += (k1[i].dx + k2[i].dx * 2 + k3[i].dx * 2 + k4[i].dx) * (h / 6);
    particles_[i].v += (k1[i].dv + k2[i].dv * 2 + k3[i].dv * 2 + k4[i].dv) * (h / 6);
  }
}

}  // namespace textbook
