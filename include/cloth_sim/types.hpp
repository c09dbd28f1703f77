// Basic types shared by the whole core library. Eigen only, double precision.
#pragma once

#include <Eigen/Dense>
#include <array>
#include <string>

namespace cloth_sim {

using Vec3 = Eigen::Vector3d;
using Mat3 = Eigen::Matrix3d;
using VecX = Eigen::VectorXd;

/// Whether every entry of x is finite: Eigen's allFinite, vectorised (the
/// steppers check every step's state).
bool allFinite(const VecX& x);

/// The three optional spring groups of a grid cloth.
enum class SpringType { Stretch = 0, Shear = 1, Bend = 2 };
constexpr int kNumSpringTypes = 3;
const char* toString(SpringType type);
/// Parses "stretch" | "shear" | "bend"; returns false on anything else.
bool parseSpringType(const std::string& name, SpringType* type);

/// How a spring damps: along its axis c (dv.d^) d^ (default) or the whole
/// relative velocity c dv (the original project's model).
enum class DampingModel { AlongSpring, RelativeVelocity };

enum class Plane { Horizontal, Vertical };

enum class Method { ImplicitEuler, Newton, Bdf2, SymplecticEuler };
const char* toString(Method method);
bool parseMethod(const std::string& name, Method* method);

/// none: plain CG (the original project); block_jacobi: inverse 3x3 node
/// blocks; cholesky: a sparse LDL^T factorization of the whole matrix (its
/// pattern analysed once), so CG converges in a step or two at any stiffness;
/// multigrid: one symmetric geometric V-cycle on the cloth grid, so the
/// iteration count barely grows with the resolution.
/// Auto: chosen per step by AutoPreconditioner (linear_solver.hpp).
enum class Preconditioner { None, BlockJacobi, Cholesky, Multigrid, Auto };

/// Result of a runtime request: ok, or a message naming the bad field.
struct Status {
  bool ok = true;
  std::string message;
  static Status success(std::string msg = "") { return {true, std::move(msg)}; }
  static Status error(std::string msg) { return {false, std::move(msg)}; }
  explicit operator bool() const { return ok; }
};

}  // namespace cloth_sim
