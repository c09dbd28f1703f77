// Checks the core tests and the hard-case suites share: the exact
// self-intersection count of a cloth state, and the `# pass.KEY: value`
// bounds a hard-case scene states in its header.
#pragma once

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "cloth_sim/collision_geometry.hpp"
#include "cloth_sim/model.hpp"
#include "cloth_sim/types.hpp"

namespace cloth_sim::test {

/// Pairs of triangles sharing no node that intersect, by the exact test
/// (exact orientation predicates), with a sort-and-sweep broad phase along x
/// of its own (independent of the simulator's spatial hash).
inline int selfIntersections(const Model& m, const VecX& x) {
  const auto& T = m.triangles;
  const int n = static_cast<int>(T.size());
  std::vector<Eigen::AlignedBox3d> box(n);
  std::vector<int> order(n);
  for (int t = 0; t < n; ++t) {
    for (int k = 0; k < 3; ++k) box[t].extend(Vec3(x.segment<3>(3 * T[t][k])));
    order[t] = t;
  }
  std::sort(order.begin(), order.end(),
            [&](int a, int b) { return box[a].min().x() < box[b].min().x(); });
  auto p = [&](int i) { return Vec3(x.segment<3>(3 * i)); };
  int count = 0;
  for (int ia = 0; ia < n; ++ia) {
    const int a = order[ia];
    for (int ib = ia + 1; ib < n; ++ib) {
      const int b = order[ib];
      if (box[b].min().x() > box[a].max().x()) break;
      if (!box[a].intersects(box[b])) continue;
      bool shared = false;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) shared = shared || T[a][i] == T[b][j];
      if (shared) continue;
      count += trianglesIntersect(p(T[a][0]), p(T[a][1]), p(T[a][2]), p(T[b][0]), p(T[b][1]),
                                  p(T[b][2]));
    }
  }
  return count;
}

/// The `# pass.KEY: value` header lines of a hard-case scene (first word of
/// the value; what follows it is the measurement beside the bound).
inline std::map<std::string, std::string> passBounds(const std::string& path) {
  std::ifstream in(path);
  std::map<std::string, std::string> found;
  std::string line;
  const std::string tag = "# pass.";
  while (std::getline(in, line)) {
    if (line.rfind(tag, 0) != 0) continue;
    const size_t colon = line.find(':');
    std::istringstream value(line.substr(colon + 1));
    value >> found[line.substr(tag.size(), colon - tag.size())];
  }
  return found;
}

/// A gtest parameter name from a scene file and a stepper: "c1_fast_drop_newton".
inline std::string caseName(const std::string& file, const char* method) {
  std::string n = file.substr(0, file.find('.')) + "_" + method;
  for (char& c : n) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return n;
}

}  // namespace cloth_sim::test
