/// \file
/// The learned-dynamics interface of the controller and the observer (thesis Sec. 2.3.1): a regressor of
/// n(q, q̇) = C(q, q̇) q̇ + G(q) + F_f with inputs [q; q̇] and one output per joint. Control owns this interface; any
/// regressor with `inputDim()`, `outputDim()` and a real-time safe `predict(x, y)` returning a status enum with a
/// `Success` value plugs in (learning::LocallyWeightedRegression does), so control does not depend on learning.
#pragma once

#include <Eigen/Core>

namespace bimanual_skills::control {

/// A non-owning, copyable handle on a regressor (type-erased without allocation). Default-constructed: none.
class LearnedDynamics {
 public:
  LearnedDynamics() = default;

  /// Refers to `model`, which must outlive every use of this handle.
  template <class Regressor>
  explicit LearnedDynamics(Regressor& model) noexcept
      : object_(&model), input_dim_(model.inputDim()), output_dim_(model.outputDim()), predict_(&call<Regressor>) {}

  /// True when a regressor is attached and its dimensions are those of an n-joint chain (2n inputs, n outputs).
  bool fits(int joints) const noexcept {
    return object_ != nullptr && input_dim_ == 2 * joints && output_dim_ == joints;
  }

  /// n̂ at x = [q; q̇] into y. False when no regressor is attached or it has no prediction there.
  /// Real-time safe when the regressor's predict() is.
  bool predict(const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) const noexcept {
    return object_ != nullptr && predict_(object_, x, y);
  }

 private:
  template <class Regressor>
  static bool call(void* object, const Eigen::Ref<const Eigen::VectorXd>& x, Eigen::Ref<Eigen::VectorXd> y) noexcept {
    auto& model = *static_cast<Regressor*>(object);
    return model.predict(x, y) == decltype(model.predict(x, y))::Success;
  }

  void* object_ = nullptr;
  int input_dim_ = 0;
  int output_dim_ = 0;
  bool (*predict_)(void*, const Eigen::Ref<const Eigen::VectorXd>&, Eigen::Ref<Eigen::VectorXd>) noexcept = nullptr;
};

}  // namespace bimanual_skills::control
