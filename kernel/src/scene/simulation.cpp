#include "weft/scene/simulation.hpp"

#include <oneapi/tbb/task_arena.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace weft {

namespace {

const SimulationOptions& validated(const SimulationOptions& o) {
  if (!(std::isfinite(o.dt) && o.dt > 0))
    throw std::invalid_argument("SimulationOptions.dt must be finite and > 0 (s), got " + std::to_string(o.dt));
  if (!o.arena && o.threads < 0)
    throw std::invalid_argument("SimulationOptions.threads must be >= 0 (0 = all cores), got " +
                                std::to_string(o.threads));
  if (!(std::isfinite(o.gravity.x) && std::isfinite(o.gravity.y) && std::isfinite(o.gravity.z)))
    throw std::invalid_argument("SimulationOptions.gravity must be finite");
  if (!(std::isfinite(o.effects.drag) && o.effects.drag >= 0))
    throw std::invalid_argument("SimulationOptions.effects.drag must be finite and >= 0 (N s/m), got " +
                                std::to_string(o.effects.drag));
  if (std::isnan(o.stability.maxStretch))
    throw std::invalid_argument("SimulationOptions.stability.maxStretch must not be NaN");
  return o;
}

template <class S>
std::shared_ptr<const Model<S>> requireModel(std::shared_ptr<const Model<S>> model) {
  if (!model) throw std::invalid_argument("Simulation: model must not be null");
  return model;
}

std::unique_ptr<Executor> makeExecutor(const SimulationOptions& o) {
  return o.arena ? std::make_unique<Executor>(*o.arena) : std::make_unique<Executor>(o.threads);
}

}  // namespace

template <class S>
Simulation<S>::Simulation(std::shared_ptr<const Model<S>> model, State<S> initial, const SimulationOptions& options)
    : model_(requireModel(std::move(model))),
      options_(validated(options)),
      executor_(makeExecutor(options_)),
      forces_(*model_, options_.forceStrategy, options_.gravity, options_.effects),
      integrator_(makeIntegrator<S>(options_.integrator, *model_, options_.integration)),
      stability_(*model_, options_.stability),
      nextX_(model_->particleCount(), 3),
      nextV_(model_->particleCount(), 3) {
  setState(initial);
}

template <class S>
Simulation<S>::Simulation(ModelAndState<S> built, const SimulationOptions& options)
    : Simulation(std::make_shared<const Model<S>>(std::move(built.model)), std::move(built.state), options) {}

template <class S>
Simulation<S>::~Simulation() = default;

template <class S>
void Simulation<S>::setState(const State<S>& state) {
  const Index n = model_->particleCount();
  if (state.x.rows() != n || state.v.rows() != n)
    throw std::invalid_argument("Simulation::setState: state has " + std::to_string(state.x.rows()) +
                                " positions and " + std::to_string(state.v.rows()) + " velocities, the model has " +
                                std::to_string(n) + " particles");
  if (!state.x.allFinite() || !state.v.allFinite())
    throw std::invalid_argument("Simulation::setState: state has non-finite positions or velocities");
  state_ = state;
  status_ = StepStatus{};
  integrator_->reset();
}

template <class S>
void Simulation<S>::setTimeStep(double dt) {
  if (!(std::isfinite(dt) && dt > 0))
    throw std::invalid_argument("Simulation::setTimeStep: dt must be finite and > 0 (s), got " + std::to_string(dt));
  options_.dt = dt;
  status_ = StepStatus{};
}

template <class S>
StepStatus Simulation<S>::step() {
  if (!status_.ok()) return status_;
  executor_->run([&] {
    lastWork_ =
        integrator_->advance(forces_, state_.x, state_.v, static_cast<S>(options_.dt), nextX_, nextV_, *executor_);
    if (lastWork_.failed) {
      status_ = StepStatus{};
      status_.code = StepCode::StepSizeUnderflow;
      status_.value = static_cast<double>(lastWork_.substeps + lastWork_.rejectedSubsteps);
    } else {
      status_ = stability_.check(nextX_, nextV_, *executor_);
    }
  });
  totalWork_ += lastWork_;
  if (!status_.ok()) {
    status_.time = state_.time;
    integrator_->reset();  // anything it carried belongs to the rejected candidate
    return status_;
  }
  state_.x.swap(nextX_);  // O(1): exchanges storage, no copy, no allocation
  state_.v.swap(nextV_);
  ++stepCount_;
  state_.time += options_.dt;
  return status_;
}

template <class S>
StepStatus Simulation<S>::run(Index steps) {
  for (Index k = 0; k < steps; ++k)
    if (!step().ok()) break;
  return status_;
}

template class Simulation<float>;
template class Simulation<double>;

}  // namespace weft
