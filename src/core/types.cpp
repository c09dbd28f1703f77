// Names of the core enums as they appear in scene files, the CLI and
// services, and the vectorised finiteness check.
#include "cloth_sim/types.hpp"

#include "cloth_sim/cg_kernels.hpp"

namespace cloth_sim {

bool allFinite(const VecX& x) { return cg_kernels::allFinite(static_cast<int>(x.size()), x.data()); }

const char* toString(SpringType type) {
  switch (type) {
    case SpringType::Stretch: return "stretch";
    case SpringType::Shear: return "shear";
    case SpringType::Bend: return "bend";
  }
  return "unknown";
}

bool parseSpringType(const std::string& name, SpringType* type) {
  for (int t = 0; t < kNumSpringTypes; ++t) {
    const auto candidate = static_cast<SpringType>(t);
    if (name == toString(candidate)) {
      *type = candidate;
      return true;
    }
  }
  return false;
}

const char* toString(Method method) {
  switch (method) {
    case Method::ImplicitEuler: return "implicit_euler";
    case Method::Newton: return "newton";
    case Method::Bdf2: return "bdf2";
    case Method::SymplecticEuler: return "symplectic_euler";
  }
  return "unknown";
}

bool parseMethod(const std::string& name, Method* method) {
  for (Method candidate : {Method::ImplicitEuler, Method::Newton, Method::Bdf2,
                           Method::SymplecticEuler}) {
    if (name == toString(candidate)) {
      *method = candidate;
      return true;
    }
  }
  return false;
}

}  // namespace cloth_sim
