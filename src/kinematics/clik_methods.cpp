// Names of the CLIK methods (the thesis' abbreviations) and of the solver's statuses.
#include "bimanual_skills/kinematics/clik.hpp"

namespace bimanual_skills::kinematics {

const char* methodName(InverseOperator op, LimitScheme scheme) noexcept {
  if (scheme == LimitScheme::ContinuousTaskPriority) {
    switch (op) {
      case InverseOperator::Pseudoinverse:
        return "CTP";
      case InverseOperator::SingularValueFilter:
        return "CTP+SVF";
      case InverseOperator::SelectiveDamping:
        return "CTP+SD";
      case InverseOperator::SvfSelectiveDamping:
        return "CTP+SD+SVF";
      default:
        return "CTP+other";
    }
  }
  switch (scheme) {
    case LimitScheme::JointWeighting:
      return "JW";
    case LimitScheme::GradientProjection:
      return "GP";
    case LimitScheme::JointClamping:
      return "JC";
    case LimitScheme::TaskAugmentation:
      return "TA";
    case LimitScheme::TaskPriority:
      return "TP";
    default:
      break;
  }
  switch (op) {
    case InverseOperator::Pseudoinverse:
      return "JP";
    case InverseOperator::Transpose:
      return "JT";
    case InverseOperator::SelectiveDamping:
      return "SD";
    case InverseOperator::Damping:
      return "JD";
    case InverseOperator::Filtering:
      return "JF";
    case InverseOperator::ErrorDamping:
      return "ED";
    case InverseOperator::ImprovedErrorDamping:
      return "IED";
    case InverseOperator::SingularValueFilter:
      return "SVF";
    case InverseOperator::SvfErrorDamping:
      return "SVF+ED";
    case InverseOperator::SvfSelectiveDamping:
      return "SVF+SD";
  }
  return "unknown";
}

bool parseMethodName(const std::string& name, InverseOperator& op, LimitScheme& scheme) noexcept {
  // JW, GP, JC, TA and TP are named after their scheme alone: they pair with the pseudoinverse.
  for (LimitScheme s : kLimitSchemes) {
    for (InverseOperator o : kInverseOperators) {
      const bool named_by_scheme = s != LimitScheme::None && s != LimitScheme::ContinuousTaskPriority;
      if (named_by_scheme && o != InverseOperator::Pseudoinverse) continue;
      if (name == methodName(o, s)) {
        op = o;
        scheme = s;
        return true;
      }
    }
  }
  return false;
}

const std::vector<std::string>& methodNames() {
  static const std::vector<std::string> names = {"JP",  "JT",     "SD",      "JD",     "JF",        "ED", "IED",
                                                 "SVF", "SVF+ED", "SVF+SD",  "JW",     "GP",        "JC", "TA",
                                                 "TP",  "CTP",    "CTP+SVF", "CTP+SD", "CTP+SD+SVF"};
  return names;
}

const char* toString(IkStatus status) noexcept {
  switch (status) {
    case IkStatus::Converged:
      return "converged";
    case IkStatus::StepComputed:
      return "step computed";
    case IkStatus::MaxIterations:
      return "iteration limit reached";
    case IkStatus::Timeout:
      return "time budget exhausted";
    case IkStatus::InvalidInput:
      return "invalid input (wrong size or non-finite configuration or target)";
    case IkStatus::NumericalFailure:
      return "numerical failure (non-finite step)";
  }
  return "unknown status";
}

}  // namespace bimanual_skills::kinematics
