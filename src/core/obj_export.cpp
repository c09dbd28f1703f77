#include <cstdio>

#include "cloth_sim/simulation.hpp"

namespace cloth_sim {

std::vector<Vec3> vertexNormals(const Model& model, const VecX& x) {
  std::vector<Vec3> normals(model.numNodes(), Vec3::Zero());
  for (const auto& t : model.triangles) {
    const Vec3 a = x.segment<3>(3 * t[0]), b = x.segment<3>(3 * t[1]), c = x.segment<3>(3 * t[2]);
    const Vec3 n = (b - a).cross(c - a);  // length = twice the area: area weighting
    for (int k = 0; k < 3; ++k) normals[t[k]] += n;
  }
  for (auto& n : normals) {
    const double len = n.norm();
    n = len > 0.0 ? Vec3(n / len) : Vec3::UnitZ();
  }
  return normals;
}

bool writeObj(const std::string& path, const Model& model, const VecX& x) {
  FILE* out = std::fopen(path.c_str(), "w");
  if (!out) return false;
  std::fprintf(out, "# cloth_sim: %d x %d nodes\n", model.rows, model.cols);
  for (int i = 0; i < model.numNodes(); ++i) {
    std::fprintf(out, "v %.17g %.17g %.17g\n", x[3 * i], x[3 * i + 1], x[3 * i + 2]);
  }
  for (const Vec3& n : vertexNormals(model, x)) {
    std::fprintf(out, "vn %.9g %.9g %.9g\n", n.x(), n.y(), n.z());
  }
  for (const auto& t : model.triangles) {  // OBJ indices are 1-based
    std::fprintf(out, "f %d//%d %d//%d %d//%d\n", t[0] + 1, t[0] + 1, t[1] + 1, t[1] + 1,
                 t[2] + 1, t[2] + 1);
  }
  const bool ok = std::ferror(out) == 0;
  return std::fclose(out) == 0 && ok;
}

}  // namespace cloth_sim
