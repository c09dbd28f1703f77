// Output formats hold what the README says (issue 17): the OBJ's faces
// (1-based, two triangles per cell, winding) and normals on a small known
// mesh, and cloth_sim_run's --out and --trace values equal to an in-process
// Simulation's.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "cloth_sim/simulation.hpp"
#include "scene_builders.hpp"

namespace cloth_sim {
namespace {

const std::string kDemo = std::string(CLOTH_SIM_SOURCE_DIR) + "/config/demo.yaml";

std::vector<std::string> fileLines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> out;
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

std::vector<double> numbers(const std::string& line) {
  std::istringstream in(line);
  std::vector<double> out;
  for (std::string token; in >> token;) out.push_back(std::strtod(token.c_str(), nullptr));
  return out;
}

class TempDir {
 public:
  TempDir() {
    char pattern[] = "/tmp/cloth_sim_outputs_XXXXXX";
    dir_ = mkdtemp(pattern);
  }
  ~TempDir() { std::system(("rm -rf '" + dir_ + "'").c_str()); }
  std::string operator/(const std::string& name) const { return dir_ + "/" + name; }

 private:
  std::string dir_;
};

TEST(ObjExport, FacesAndNormalsOfASmallKnownMesh) {
  // 2 rows x 3 columns, horizontal at z = 1.5: nodes 0 1 2 / 3 4 5 with row 1
  // at -y. Two cells, two triangles each, counter-clockwise seen from +z.
  Scene scene = test::bareScene(2, 3);
  scene.cloth.width = 2.0;
  scene.cloth.length = 1.0;
  const Model model = buildModel(scene);
  VecX x = model.rest_positions;
  x[3 * 4 + 2] += 0.5;  // lift node 4: the normals tilt in a known way
  TempDir dir;
  ASSERT_TRUE(writeObj(dir / "mesh.obj", model, x));

  std::vector<Vec3> v, vn;
  std::vector<std::vector<int>> faces;
  for (const std::string& line : fileLines(dir / "mesh.obj")) {
    if (line.rfind("v ", 0) == 0) {
      const auto n = numbers(line.substr(2));
      ASSERT_EQ(n.size(), 3u) << line;
      v.emplace_back(n[0], n[1], n[2]);
    } else if (line.rfind("vn ", 0) == 0) {
      const auto n = numbers(line.substr(3));
      ASSERT_EQ(n.size(), 3u) << line;
      vn.emplace_back(n[0], n[1], n[2]);
    } else if (line.rfind("f ", 0) == 0) {
      // "f a//a b//b c//c": vertex and normal index the same node, 1-based.
      int a, an, b, bn, c, cn;
      ASSERT_EQ(std::sscanf(line.c_str(), "f %d//%d %d//%d %d//%d", &a, &an, &b, &bn, &c, &cn), 6)
          << line;
      EXPECT_EQ(a, an);
      EXPECT_EQ(b, bn);
      EXPECT_EQ(c, cn);
      faces.push_back({a, b, c});
    } else {
      EXPECT_EQ(line.rfind("#", 0), 0u) << "unexpected line: " << line;
    }
  }
  ASSERT_EQ(v.size(), 6u);
  ASSERT_EQ(vn.size(), 6u);
  for (int i = 0; i < 6; ++i) EXPECT_EQ(v[i], Vec3(x.segment<3>(3 * i))) << "vertex " << i;

  // Exactly these faces (1-based): cell 0 = nodes 1 2 4 5, cell 1 = 2 3 5 6.
  const std::vector<std::vector<int>> expected = {{1, 4, 2}, {2, 4, 5}, {2, 5, 3}, {3, 5, 6}};
  EXPECT_EQ(faces, expected);
  // Winding: on the flat (unlifted) mesh every face normal points to +z.
  for (const auto& f : faces) {
    const Vec3 a = model.rest_positions.segment<3>(3 * (f[0] - 1));
    const Vec3 b = model.rest_positions.segment<3>(3 * (f[1] - 1));
    const Vec3 c = model.rest_positions.segment<3>(3 * (f[2] - 1));
    EXPECT_GT((b - a).cross(c - a).z(), 0.0);
  }
  // Normals: unit length, the area-weighted mean of the adjacent faces' normals.
  std::vector<Vec3> sum(6, Vec3::Zero());
  for (const auto& f : faces) {
    const Vec3 a = v[f[0] - 1], b = v[f[1] - 1], c = v[f[2] - 1];
    const Vec3 n = (b - a).cross(c - a);
    for (int k : f) sum[k - 1] += n;
  }
  for (int i = 0; i < 6; ++i) {
    EXPECT_NEAR(vn[i].norm(), 1.0, 1e-8) << i;
    EXPECT_LT((vn[i] - sum[i].normalized()).norm(), 1e-8) << "normal " << i;
  }
  // Nodes off the lifted node's faces keep the flat normal +z; the lifted
  // node's faces tilt its neighbours' normals away from +z.
  EXPECT_LT((vn[0] - Vec3::UnitZ()).norm(), 1e-8);
  EXPECT_LT(vn[1].z(), 1.0 - 1e-3);

  // The flat mesh: every normal is +z.
  ASSERT_TRUE(writeObj(dir / "flat.obj", model, model.rest_positions));
  int flat_normals = 0;
  for (const std::string& line : fileLines(dir / "flat.obj")) {
    if (line.rfind("vn ", 0) != 0) continue;
    ++flat_normals;
    const auto n = numbers(line.substr(3));
    EXPECT_EQ(Vec3(n[0], n[1], n[2]), Vec3::UnitZ()) << line;
  }
  EXPECT_EQ(flat_normals, 6);
}

int runCli(const std::string& args) {
  const std::string cmd = std::string("'") + CLOTH_SIM_RUN_PATH + "' " + args +
                          " </dev/null >/dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CliOutputs, OutAndTraceEqualAnInProcessSimulation) {
  const int steps = 10, every = 3;
  TempDir dir;
  ASSERT_EQ(runCli("'" + kDemo + "' --steps " + std::to_string(steps) + " --out '" +
                   (dir / "out.txt") + "' --trace '" + (dir / "trace.txt") + "' --every " +
                   std::to_string(every)),
            0);

  Simulation sim(loadScene(kDemo));
  std::vector<VecX> samples = {sim.positions()};
  std::vector<double> times = {sim.time()};
  for (int k = 1; k <= steps; ++k) {
    const StepStats s = sim.step();
    ASSERT_TRUE(s.ok) << s.failure;
    if (k % every == 0) {
      samples.push_back(sim.positions());
      times.push_back(sim.time());
    }
  }
  ASSERT_GT(sim.time(), 0.0);

  // %.17g round-trips: the same code on the same input gives the same bits.
  const std::vector<std::string> trace = fileLines(dir / "trace.txt");
  ASSERT_EQ(trace.size(), samples.size());
  for (size_t s = 0; s < trace.size(); ++s) {
    const std::vector<double> values = numbers(trace[s]);
    ASSERT_EQ(values.size(), 1 + static_cast<size_t>(samples[s].size())) << "trace line " << s;
    EXPECT_EQ(values[0], times[s]) << "trace line " << s;
    for (Eigen::Index k = 0; k < samples[s].size(); ++k) {
      ASSERT_EQ(values[1 + k], samples[s][k]) << "trace line " << s << " value " << k;
    }
  }
  const std::vector<std::string> out = fileLines(dir / "out.txt");
  ASSERT_EQ(static_cast<int>(out.size()), sim.numNodes());
  for (int i = 0; i < sim.numNodes(); ++i) {
    const std::vector<double> values = numbers(out[i]);
    ASSERT_EQ(values.size(), 6u) << "node " << i;
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(values[k], sim.positions()[3 * i + k]) << "node " << i;
      ASSERT_EQ(values[3 + k], sim.velocities()[3 * i + k]) << "node " << i;
    }
  }
}

}  // namespace
}  // namespace cloth_sim
