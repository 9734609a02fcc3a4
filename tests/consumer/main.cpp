// The kernel alone: a flag for 1000 steps and a box dropped on a floor, both described by
// this program (compiled without weft's machine flags) and run by the library.
#include <cstdio>
#include <weft/weft.hpp>

int main() {
  weft::SimulationOptions options;
  options.integrator = weft::IntegratorKind::SymplecticEuler;
  options.dt = 1e-4;  // fixed step, s
  options.threads = 2;
  weft::Simulation<float> sim(weft::makeFlag<float>(32), options);
  const weft::StepStatus status = sim.run(1000);
  if (!status.ok()) {
    std::fprintf(stderr, "%s\n", status.message().c_str());
    return 1;
  }
  const weft::Energy e = weft::energy(sim.model(), sim.state(), options.gravity);
  std::printf("flag: t = %.3f s, kinetic %.4f J, spring %.4f J, gravity %.4f J\n", sim.state().time, e.kinetic,
              e.spring, e.gravity);

  weft::SimulationOptions bodies;
  bodies.dt = 1.0 / 60;
  weft::RigidBodyDesc floor;
  floor.motion = weft::BodyMotion::Static;
  floor.shapes.push_back({.kind = weft::RigidShapeDesc::Kind::Box, .halfExtents = {5, 0.5, 5}});
  floor.position = {0, -0.5, 0};
  weft::RigidBodyDesc box;
  box.shapes.push_back({.kind = weft::RigidShapeDesc::Kind::Box, .halfExtents = {0.1, 0.1, 0.1}});
  box.position = {0, 1, 0};
  box.orientation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  bodies.rigid.bodies = {floor, box};
  weft::Simulation<double> world(weft::ModelBuilder<double>().build(), bodies);
  if (!world.run(120).ok()) return 1;
  const Eigen::Vector3d& x = world.rigidWorld()->state().x[1];
  std::printf("box: rests at y = %.4f m\n", x.y());
  // The box (0.2 m) fell 1 m and rests on the floor: its centre 0.1 m up.
  return e.kinetic > 0 && x.y() > 0.09 && x.y() < 0.11 ? 0 : 1;
}
