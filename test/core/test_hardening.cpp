// Hardening (issue 17): inputs found by fuzzing, and the bounds on the work a
// scene or a run may ask for. Each input must end in a clear rejection, a
// finite run or a loud failure, never in a hang.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cloth_sim/limits.hpp"
#include "cloth_sim/scene.hpp"

namespace {

using cloth_sim::parseScene;
using cloth_sim::SceneError;

const std::string kDemo = std::string(CLOTH_SIM_SOURCE_DIR) + "/config/demo.yaml";

/// Runs fn in a child process: its exit code, or -1 if it did not finish
/// within `seconds` (then it is killed). A hang fails the test instead of
/// stopping the suite.
template <typename Fn>
int inChild(Fn fn, double seconds) {
  const pid_t pid = fork();
  if (pid == 0) {
    int code = 0;
    try {
      code = fn();
    } catch (...) {
      code = 99;
    }
    _exit(code);
  }
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() > deadline) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -2;
}

/// The SceneError message of parsing `text`, "" if it parsed.
std::string errorOf(const std::string& text, const std::vector<std::string>& overrides = {}) {
  try {
    parseScene(text, overrides);
  } catch (const SceneError& e) {
    return e.what();
  }
  return "";
}

// yaml-cpp 0.7's LoadAll never returns on these: its parser reports an empty
// document without consuming the text, again and again, while LoadAll
// collects them (~500 MB/s until memory runs out).
const std::vector<std::string> kLoadAllHangs = {",", ",a", ", x: 1", "[1],", "{a: 1},",
                                                "- a\n,", "cloth: {rows: 3, cols: 3}\n---\n,"};

TEST(HardeningYaml, TextYamlCppCannotReadPastIsASyntaxErrorNotAHang) {
  for (const std::string& text : kLoadAllHangs) {
    const int code = inChild(
        [&] {
          const std::string message = errorOf(text);
          return message.find("YAML syntax error") != std::string::npos ||
                         message.find("expected one YAML document") != std::string::npos
                     ? 0
                     : 1;
        },
        20.0);
    EXPECT_EQ(code, 0) << "input '" << text << "': " << (code == -1 ? "hung" : "not rejected");
  }
  // The message names the place and the character.
  EXPECT_EQ(errorOf(","), "YAML syntax error at line 1, column 1: unexpected ',' (not the start of a YAML value)");
  EXPECT_NE(errorOf("- a\n,").find("line 2, column 1: unexpected ','"), std::string::npos)
      << errorOf("- a\n,");
}

TEST(HardeningYaml, DocumentsAreStillCounted) {
  EXPECT_NE(errorOf("a: 1\n---\nb: 2\n").find("expected one YAML document, got 2"),
            std::string::npos);
  EXPECT_NE(errorOf("---\n---\n---\n").find("expected one YAML document, got 3"),
            std::string::npos);
  // One document, with or without markers, and the empty text, still parse.
  EXPECT_EQ(errorOf("---\ncloth: {rows: 3, cols: 3}\n...\n"), "");
  EXPECT_NE(errorOf("").find("cloth.rows: required"), std::string::npos);
  EXPECT_NE(errorOf("# only a comment\n").find("cloth.rows: required"), std::string::npos);
}

TEST(HardeningYaml, OverrideValuesGoThroughTheSameGuard) {
  const std::string base = "cloth: {rows: 3, cols: 3}";
  for (const std::string& value : kLoadAllHangs) {
    const int code = inChild([&] { return errorOf(base, {"solver.dt=" + value}).empty() ? 1 : 0; },
                             20.0);
    EXPECT_EQ(code, 0) << "override value '" << value << "'";
  }
  EXPECT_NE(errorOf(base, {"solver.dt=1\n---\n2"}).find("more than one YAML document"),
            std::string::npos);
}

TEST(HardeningYaml, DeepNestingIsRejectedNotACrash) {
  const std::string deep = "cloth: " + std::string(100000, '[') + std::string(100000, ']');
  const int code = inChild([&] { return errorOf(deep).empty() ? 1 : 0; }, 60.0);
  EXPECT_EQ(code, 0);
}

TEST(HardeningLimits, CheckWorkNamesTheLimit) {
  EXPECT_TRUE(cloth_sim::checkWork("--steps", 1000, 576, cloth_sim::kMaxRunNodeSteps).ok);
  const cloth_sim::Status too_much = cloth_sim::checkWork("--steps", 1e9, 576, 1e10);
  EXPECT_FALSE(too_much.ok);
  EXPECT_EQ(too_much.message,
            "--steps: 1e+09 steps of 576 nodes = 5.76e+11 node-steps exceeds the limit of 1e+10");
  EXPECT_FALSE(cloth_sim::checkWork("x", std::nan(""), 1, 1e10).ok);
}

TEST(HardeningLimits, GridTooLargeIsRefusedWithTheLimit) {
  const std::string message = errorOf("cloth: {rows: 200000, cols: 200000}");
  EXPECT_NE(message.find("exceeds the limit of"), std::string::npos) << message;
}

// ------------------------------------------------------------------ CLI ----

struct CliResult {
  int exit_code = -1;
  std::string err;
  double seconds = 0.0;
};

CliResult runCli(const std::string& args) {
  char pattern[] = "/tmp/cloth_sim_hardening_XXXXXX";
  const std::string dir = mkdtemp(pattern);
  const std::string err = dir + "/stderr.txt";
  const auto start = std::chrono::steady_clock::now();
  const std::string cmd = std::string("timeout 60 '") + CLOTH_SIM_RUN_PATH + "' " + args +
                          " </dev/null >/dev/null 2>'" + err + "'";
  const int status = std::system(cmd.c_str());
  CliResult r;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  std::ifstream in(err);
  std::stringstream text;
  text << in.rdbuf();
  r.err = text.str();
  std::system(("rm -rf '" + dir + "'").c_str());
  return r;
}

TEST(HardeningCli, SceneFileThatHungLoadAllExitsTwo) {
  char pattern[] = "/tmp/cloth_sim_comma_XXXXXX";
  const std::string dir = mkdtemp(pattern);
  for (const std::string& text : {std::string(","), std::string(", x: 1")}) {
    const std::string path = dir + "/scene.yaml";
    std::ofstream(path) << text;
    const CliResult r = runCli("'" + path + "' --steps 1");
    EXPECT_EQ(r.exit_code, 2) << text << ": " << r.err;
    EXPECT_NE(r.err.find("YAML syntax error at line 1, column 1"), std::string::npos) << r.err;
  }
  std::system(("rm -rf '" + dir + "'").c_str());
}

TEST(HardeningCli, RunTooLongIsRefusedUpFrontWithTheLimit) {
  const CliResult steps = runCli("'" + kDemo + "' --steps 100000000000");
  EXPECT_EQ(steps.exit_code, 2) << steps.err;
  EXPECT_NE(steps.err.find("--steps: 1e+11 steps of 576 nodes"), std::string::npos) << steps.err;
  EXPECT_NE(steps.err.find("exceeds the limit of 1e+10"), std::string::npos) << steps.err;
  EXPECT_LT(steps.seconds, 10.0);

  const CliResult duration = runCli("'" + kDemo + "' --set solver.dt=1e-300 --duration 1");
  EXPECT_EQ(duration.exit_code, 2) << duration.err;
  EXPECT_NE(duration.err.find("--duration (at solver.dt 1e-300 s)"), std::string::npos)
      << duration.err;
  EXPECT_NE(duration.err.find("exceeds the limit"), std::string::npos) << duration.err;
}

}  // namespace

namespace {

// Found by the fuzzer: a --set key of NUL bytes gave "\0\0...solver: unknown
// key", whose what() is empty (a C string ends at the first NUL).
TEST(HardeningMessages, ControlCharactersInKeysAreEscapedNotTruncated) {
  const std::string key = std::string(3, '\0') + "solver";
  const std::string message = errorOf("cloth: {rows: 3, cols: 3}", {key + ".dt=0.1"});
  ASSERT_FALSE(message.empty());
  EXPECT_EQ(message.rfind("\\x00\\x00\\x00solver: unknown key", 0), 0u) << message;
  const std::string tab = errorOf("cloth: {rows: 3, cols: 3}\nsolver: {\"d\\tt\": 1}");
  EXPECT_EQ(tab.rfind("solver.d\\x09t: unknown key", 0), 0u) << tab;
}

}  // namespace
