// The CLI as a user runs it: a real process, its exit code, its files.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "cloth_sim/scene.hpp"

namespace {

const std::string kDemo = std::string(CLOTH_SIM_SOURCE_DIR) + "/config/demo.yaml";

struct RunResult {
  int exit_code = -1;
  std::string out;  ///< stdout
  std::string err;  ///< stderr
};

std::string readFile(const std::string& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool fileExists(const std::string& path) { return std::ifstream(path).good(); }

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> result;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) result.push_back(line);
  return result;
}

/// Parses every whitespace-separated token as a double; false on any junk.
bool parseNumbers(const std::string& line, std::vector<double>* values) {
  values->clear();
  std::istringstream in(line);
  for (std::string token; in >> token;) {
    char* end = nullptr;
    const double v = std::strtod(token.c_str(), &end);
    if (end != token.c_str() + token.size()) return false;
    values->push_back(v);
  }
  return true;
}

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

class CliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    char pattern[] = "/tmp/cloth_sim_cli_XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override { std::system(("rm -rf '" + dir_ + "'").c_str()); }

  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  /// Runs cloth_sim_run with `args` (already shell-quoted where needed).
  RunResult run(const std::string& args) const {
    const std::string out = path("stdout.txt"), err = path("stderr.txt");
    const std::string cmd = std::string("'") + CLOTH_SIM_RUN_PATH + "' " + args + " </dev/null >'" +
                            out + "' 2>'" + err + "'";
    const int status = std::system(cmd.c_str());
    RunResult r;
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = readFile(out);
    r.err = readFile(err);
    return r;
  }

  std::string dir_;
};

TEST_F(CliTest, BadOverrideExitsTwoNamingTheField) {
  const RunResult r = run("'" + kDemo + "' --steps 1 --set springs.stretch.stiffness=-3");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("springs.stretch.stiffness"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("usage:"), std::string::npos) << r.err;
}

TEST_F(CliTest, MissingSceneFileExitsTwo) {
  const RunResult r = run("'" + path("no_such_scene.yaml") + "' --steps 1");
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_NE(r.err.find("no_such_scene.yaml"), std::string::npos) << r.err;
}

TEST_F(CliTest, BadArgumentsExitTwoNamingTheFlag) {
  struct Case {
    std::string args, flag;
  };
  const std::vector<Case> cases = {
      {"'" + kDemo + "' --bogus", "--bogus"},
      {"'" + kDemo + "' --steps -4", "--steps"},
      {"'" + kDemo + "' --steps many", "--steps"},
      {"'" + kDemo + "' --duration nan", "--duration"},
      {"'" + kDemo + "' --duration 1 --steps 3", "--steps"},
      {"'" + kDemo + "' --every 2", "--every"},
      {"'" + kDemo + "' --trace '" + path("t.txt") + "' --every 0", "--every"},
      {"'" + kDemo + "' --set nokeyvalue", "--set"},
      {"'" + kDemo + "' --out", "--out"},
      {"", "SCENE.yaml"},
  };
  for (const Case& c : cases) {
    const RunResult r = run(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find(c.flag), std::string::npos) << c.args << "\n" << r.err;
    EXPECT_NE(r.err.find("usage:"), std::string::npos) << c.args << "\n" << r.err;
  }
}

TEST_F(CliTest, HelpPrintsUsageAndExitsZero) {
  const RunResult r = run("--help");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("usage: cloth_sim_run SCENE.yaml"), std::string::npos) << r.out;
}

TEST_F(CliTest, WritesStateStatsAndTrace) {
  const cloth_sim::Scene scene = cloth_sim::loadScene(kDemo);
  const int nodes = scene.numNodes();
  const int steps = 10, every = 3;
  const RunResult r =
      run("'" + kDemo + "' --steps " + std::to_string(steps) + " --out '" + path("out.txt") +
          "' --stats '" + path("stats.json") + "' --trace '" + path("trace.txt") + "' --every " +
          std::to_string(every) + " --obj '" + path("mesh.obj") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("10 steps"), std::string::npos) << r.out;

  const std::vector<std::string> state = lines(readFile(path("out.txt")));
  ASSERT_EQ(static_cast<int>(state.size()), nodes);
  for (const std::string& line : state) {
    std::vector<double> v;
    ASSERT_TRUE(parseNumbers(line, &v)) << line;
    ASSERT_EQ(v.size(), 6u) << line;
    for (double x : v) EXPECT_TRUE(std::isfinite(x)) << line;
  }

  const std::string stats = readFile(path("stats.json"));
  ASSERT_FALSE(stats.empty());
  EXPECT_EQ(stats.front(), '{');
  for (const char* key :
       {"steps", "sim_time", "wall_time_s", "ms_per_step", "cg_iterations_mean",
        "cg_iterations_max", "newton_iterations_mean", "max_residual", "energy_initial",
        "energy_final", "max_strain", "finite", "rejected_steps", "refined_steps",
        "order_reduced_steps", "max_halvings", "failure"}) {
    EXPECT_NE(stats.find("\"" + std::string(key) + "\":"), std::string::npos) << key << "\n" << stats;
  }
  EXPECT_NE(stats.find("\"steps\": 10,"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"finite\": true"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"failure\": null"), std::string::npos) << stats;

  // t = 0 plus one line every `every` steps.
  const std::vector<std::string> trace = lines(readFile(path("trace.txt")));
  ASSERT_EQ(static_cast<int>(trace.size()), 1 + steps / every);
  std::vector<double> first, last;
  ASSERT_TRUE(parseNumbers(trace.front(), &first));
  ASSERT_TRUE(parseNumbers(trace.back(), &last));
  ASSERT_EQ(static_cast<int>(first.size()), 1 + 3 * nodes);
  ASSERT_EQ(static_cast<int>(last.size()), 1 + 3 * nodes);
  EXPECT_EQ(first[0], 0.0);
  EXPECT_NEAR(last[0], (steps / every) * every * scene.solver.dt, 1e-12);

  // The OBJ has one vertex and one normal per node.
  int vertices = 0, normals = 0;
  for (const std::string& line : lines(readFile(path("mesh.obj")))) {
    if (line.rfind("v ", 0) == 0) ++vertices;
    if (line.rfind("vn ", 0) == 0) ++normals;
  }
  EXPECT_EQ(vertices, nodes);
  EXPECT_EQ(normals, nodes);
}

TEST_F(CliTest, ObjSequenceWritesOneFramePerSample) {
  const cloth_sim::Scene scene = cloth_sim::loadScene(kDemo);
  ASSERT_EQ(std::system(("mkdir '" + path("frames") + "'").c_str()), 0);
  const RunResult r = run("'" + kDemo + "' --steps 7 --every 3 --obj-sequence '" +
                          path("frames") + "' --out '" + path("out.txt") + "'");
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // t = 0 and after steps 3 and 6: three frames, the last one the state after step 6.
  for (const char* name : {"frame_00000.obj", "frame_00001.obj", "frame_00002.obj"}) {
    int vertices = 0;
    for (const std::string& line : lines(readFile(path("frames/") + name))) {
      if (line.rfind("v ", 0) == 0) ++vertices;
    }
    EXPECT_EQ(vertices, scene.numNodes()) << name;
  }
  EXPECT_EQ(readFile(path("frames/frame_00003.obj")), "");
  EXPECT_NE(readFile(path("frames/frame_00000.obj")), readFile(path("frames/frame_00002.obj")));
  // A directory that does not exist: refused before any step, naming the flag.
  const RunResult bad = run("'" + kDemo + "' --steps 2 --obj-sequence '" + path("missing") + "'");
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.err.find("--obj-sequence: cannot write"), std::string::npos) << bad.err;
}

TEST_F(CliTest, DurationRoundsUpToWholeSteps) {
  // 0.01 s at dt 0.004 is 2.5 steps -> 3; 0.012 s is 3 steps despite round-off.
  for (const char* duration : {"0.01", "0.012"}) {
    const RunResult r = run("'" + kDemo + "' --set solver.dt=0.004 --duration " +
                            std::string(duration) + " --stats '" + path("stats.json") + "'");
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_NE(readFile(path("stats.json")).find("\"steps\": 3,"), std::string::npos) << duration;
  }
}

TEST_F(CliTest, ExplicitBlowUpExitsThreeWithoutNaNOutput) {
  const RunResult r =
      run("'" + kDemo +
          "' --set solver.method=symplectic_euler --set springs.stretch.stiffness=1e6"
          " --set solver.dt=0.01 --duration 1 --out '" +
          path("out.txt") + "' --stats '" + path("stats.json") + "' --trace '" +
          path("trace.txt") + "' --every 1 --obj '" + path("mesh.obj") + "'");
  EXPECT_EQ(r.exit_code, 3) << r.out << r.err;
  EXPECT_NE(r.err.find("step"), std::string::npos) << r.err;
  EXPECT_FALSE(fileExists(path("out.txt")));
  EXPECT_FALSE(fileExists(path("mesh.obj")));

  const std::string stats = readFile(path("stats.json"));
  EXPECT_EQ(stats.find("\"failure\": null"), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"failure\": \""), std::string::npos) << stats;
  EXPECT_NE(stats.find("\"finite\": false"), std::string::npos) << stats;
  // No NaN or infinity printed as a number anywhere (words like "non-finite" are fine).
  const std::regex non_finite("(^|[^a-z])[-+]?(nan|inf)([^a-z]|$)");
  for (const std::string& name : {"stats.json", "trace.txt", "stdout.txt"}) {
    EXPECT_FALSE(std::regex_search(lower(readFile(path(name))), non_finite)) << name;
  }
  // The trace holds at least the initial state, all finite.
  const std::vector<std::string> trace = lines(readFile(path("trace.txt")));
  ASSERT_GE(trace.size(), 1u);
  for (const std::string& line : trace) {
    std::vector<double> v;
    ASSERT_TRUE(parseNumbers(line, &v));
    for (double x : v) ASSERT_TRUE(std::isfinite(x));
  }
}

}  // namespace
