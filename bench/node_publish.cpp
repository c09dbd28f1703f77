// Publish speed of cloth_sim_node (issue 16, part 4): subscribes to what RViz
// and a state consumer would (~cloth, ~strain, ~state), so the node really
// serializes every message, and reads the node's own per-tick timings from
// /diagnostics for `duration` seconds after a `warmup`. Prints one JSON object:
// ticks' mean publish and step time, the publish share of the tick period.
//
//   rosrun cloth_sim cloth_sim_publish_bench _node:=/cloth_sim _duration:=20 _warmup:=3
// (scripts/bench_node starts the node on hang64 at 60 Hz and runs this.)
#include <cstdio>
#include <string>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <ros/ros.h>
#include <visualization_msgs/Marker.h>

#include "cloth_sim/ClothState.h"

namespace {

struct Sample {
  double publish_ms = 0, publish_max_ms = 0, step_ms = 0, tick_max_ms = 0, rate = 0, achieved = 0;
};

double valueOf(const diagnostic_msgs::DiagnosticStatus& s, const std::string& key) {
  for (const auto& kv : s.values) {
    if (kv.key == key) return std::stod(kv.value);
  }
  return -1.0;
}

}  // namespace

int main(int argc, char** argv) {
  ros::init(argc, argv, "cloth_sim_publish_bench");
  ros::NodeHandle nh, pnh("~");
  std::string node = pnh.param<std::string>("node", "/cloth_sim");
  const double duration = pnh.param("duration", 20.0);
  const double warmup = pnh.param("warmup", 3.0);
  long markers = 0, strains = 0, states = 0;
  size_t points = 0;
  uint32_t nodes = 0;
  auto s1 = nh.subscribe<visualization_msgs::Marker>(
      node + "/cloth", 2, [&](const visualization_msgs::Marker::ConstPtr& m) {
        ++markers;
        points = m->points.size();
      });
  auto s2 = nh.subscribe<visualization_msgs::Marker>(
      node + "/strain", 2, [&](const visualization_msgs::Marker::ConstPtr&) { ++strains; });
  auto s3 = nh.subscribe<cloth_sim::ClothState>(
      node + "/state", 2, [&](const cloth_sim::ClothState::ConstPtr& s) {
        ++states;
        nodes = s->rows * s->cols;
      });
  std::vector<Sample> samples;
  const ros::WallTime start = ros::WallTime::now();
  const std::string prefix = node.substr(1) + ":";
  auto s4 = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 10, [&](const diagnostic_msgs::DiagnosticArray::ConstPtr& msg) {
        if ((ros::WallTime::now() - start).toSec() < warmup) return;
        for (const auto& st : msg->status) {
          if (st.name.rfind(prefix, 0) != 0) continue;
          Sample s;
          s.publish_ms = valueOf(st, "publish time (ms per tick)");
          s.publish_max_ms = valueOf(st, "publish time max (ms)");
          s.step_ms = valueOf(st, "step time (ms per tick)");
          s.tick_max_ms = valueOf(st, "tick time max (ms)");
          s.rate = valueOf(st, "rate (Hz)");
          s.achieved = valueOf(st, "achieved rate (Hz)");
          samples.push_back(s);
        }
      });
  while (ros::ok() && (ros::WallTime::now() - start).toSec() < warmup + duration) {
    ros::spinOnce();
    ros::WallDuration(0.002).sleep();
  }
  if (samples.empty()) {
    std::fprintf(stderr, "cloth_sim_publish_bench: no diagnostics from %s\n", node.c_str());
    return 1;
  }
  Sample mean, worst;
  for (const Sample& s : samples) {
    mean.publish_ms += s.publish_ms / samples.size();
    mean.step_ms += s.step_ms / samples.size();
    mean.achieved += s.achieved / samples.size();
    worst.publish_max_ms = std::max(worst.publish_max_ms, s.publish_max_ms);
    worst.tick_max_ms = std::max(worst.tick_max_ms, s.tick_max_ms);
  }
  const double rate = samples.back().rate;
  const double period_ms = 1e3 / rate;
  std::printf(
      "{\"nodes\": %u, \"marker_points\": %zu, \"rate_hz\": %g, \"achieved_rate_hz\": %.2f, "
      "\"periods\": %zu, \"publish_ms_per_tick\": %.3f, \"publish_max_ms\": %.3f, "
      "\"step_ms_per_tick\": %.3f, \"tick_max_ms\": %.3f, \"publish_share_of_period\": %.4f, "
      "\"publish_share_of_busy_tick\": %.4f, \"received\": {\"cloth\": %ld, \"strain\": %ld, "
      "\"state\": %ld}}\n",
      nodes, points, rate, mean.achieved, samples.size(), mean.publish_ms, worst.publish_max_ms,
      mean.step_ms, worst.tick_max_ms, mean.publish_ms / period_ms,
      mean.publish_ms / (mean.publish_ms + mean.step_ms), markers, strains, states);
  return 0;
}
