#include "cloth_node.hpp"

#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <set>

#include "cloth_sim/limits.hpp"

namespace cloth_sim_ros {
namespace {

using cloth_sim::Status;
using cloth_sim::Vec3;

std::string format(const char* fmt, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), fmt, value);
  return buf;
}

std::string formatPoint(const Vec3& p) {
  return "[" + format("%g", p.x()) + ", " + format("%g", p.y()) + ", " + format("%g", p.z()) +
         "]";
}

/// Range and duplicate check of request indices (the tf path needs valid
/// indices before the core sees them).
Status checkIndices(const std::vector<long>& indices, int num_nodes, std::vector<int>* out) {
  std::set<long> seen;
  out->clear();
  for (size_t k = 0; k < indices.size(); ++k) {
    const std::string field = "indices[" + std::to_string(k) + "]";
    if (indices[k] < 0 || indices[k] >= num_nodes) {
      return Status::error(field + ": node " + std::to_string(indices[k]) +
                           " out of range, the cloth has " + std::to_string(num_nodes) +
                           " nodes (0.." + std::to_string(num_nodes - 1) + ")");
    }
    if (!seen.insert(indices[k]).second) {
      return Status::error(field + ": node " + std::to_string(indices[k]) + " is listed twice");
    }
    out->push_back(static_cast<int>(indices[k]));
  }
  return Status::success();
}

std::vector<long> toLong(const std::vector<uint32_t>& indices) {
  return std::vector<long>(indices.begin(), indices.end());
}

}  // namespace

int ClothNode::stepsPerTick(double tick_s, double dt) {
  // The small slack keeps an exact fit (1/50 s over 0.004 s) from rounding up.
  // Clamped before the cast (a huge count is refused by the constructor's work limit).
  const double n = std::ceil(tick_s / dt - 1e-9);
  if (!(n < std::numeric_limits<int>::max())) return std::numeric_limits<int>::max();
  return std::max(1, static_cast<int>(n));
}

ClothNode::ClothNode(ros::NodeHandle nh, ros::NodeHandle private_nh, const NodeParams& params,
                     const cloth_sim::Scene& scene, const std::string& scene_yaml)
    : params_(params),
      private_nh_(private_nh),
      sim_(scene),
      tick_s_(1.0 / params.rate),
      tf_listener_(tf_buffer_, nh),
      frame_pins_(tf_buffer_, params.frame_id, params.tf_timeout),
      frame_colliders_(tf_buffer_, params.frame_id, params.tf_timeout),
      // The updater reads its own ~diagnostic_period unchecked (a NaN there throws out of
      // the tick): it gets a namespace of its own, and the node keeps the schedule.
      updater_(nh, ros::NodeHandle(private_nh, "diagnostic_updater")),
      diag_period_(params.diagnostic_period) {
  divideTick();
  const Status work = cloth_sim::checkWork(
      "rate", std::ceil(tick_s_ / scene.solver.dt - 1e-9), sim_.numNodes(),
      cloth_sim::kMaxTickNodeSteps);
  if (!work) {
    throw ParamError(work.message + " in one tick of 1/rate = " + format("%g", tick_s_) +
                     " s at solver.dt " + format("%g", scene.solver.dt) + " s");
  }
  // Start-up tf pins need their frames: wait for each, then attach.
  for (size_t k = 0; k < params_.tf_pins.size(); ++k) {
    const TfPinParam& pin = params_.tf_pins[k];
    std::string error;
    if (pin.frame_id != params_.frame_id &&
        !tf_buffer_.canTransform(params_.frame_id, pin.frame_id, ros::Time(0),
                                 ros::Duration(params_.tf_wait), &error)) {
      throw ParamError("tf_pins[" + std::to_string(k) + "].frame_id: no transform from '" +
                       pin.frame_id + "' to '" + params_.frame_id + "' within tf_wait " +
                       format("%g", params_.tf_wait) + " s" +
                       (error.empty() ? "" : " (" + error + ")"));
    }
  }
  const Status status = applyTfPinParams();
  if (!status) throw ParamError(status.message);
  // Colliders with a `frame` need it too (throws naming colliders[k].frame).
  for (size_t k = 0; k < sim_.colliders().size(); ++k) {
    if (!params_.cloth_frame.empty() && sim_.colliders()[k].frame() == params_.cloth_frame) {
      throw ParamError("colliders[" + std::to_string(k) + "].frame: '" + params_.cloth_frame +
                       "' is the node's own ~cloth_frame");
    }
  }
  frame_colliders_.start(&sim_, params_.tf_wait);

  cloth_marker_ = triangleMarker(params_.frame_id, "cloth", params_.color);
  underside_marker_ = triangleMarker(params_.frame_id, "cloth_underside", params_.color);
  std_msgs::ColorRGBA opaque;
  opaque.r = opaque.g = opaque.b = opaque.a = 1.0f;  // per-vertex colours carry the strain
  strain_marker_ = triangleMarker(params_.frame_id, "strain", opaque);
  state_msg_.header.frame_id = params_.frame_id;

  cloth_pub_ = private_nh.advertise<visualization_msgs::Marker>("cloth", 2);
  underside_pub_ = private_nh.advertise<visualization_msgs::Marker>("cloth_underside", 2);
  if (params_.publish_strain) {
    strain_pub_ = private_nh.advertise<visualization_msgs::Marker>("strain", 2);
  }
  state_pub_ = private_nh.advertise<cloth_sim::ClothState>("state", 2);
  if (!params_.cloth_frame.empty()) cloth_frame_pub_ = std::make_unique<tf2_ros::TransformBroadcaster>();
  colliders_pub_ = private_nh.advertise<visualization_msgs::MarkerArray>("colliders", 2,
                                                                        /*latch=*/true);
  services_.push_back(private_nh.advertiseService("pin_nodes", &ClothNode::onPinNodes, this));
  services_.push_back(
      private_nh.advertiseService("release_nodes", &ClothNode::onReleaseNodes, this));
  services_.push_back(
      private_nh.advertiseService("set_stiffness", &ClothNode::onSetStiffness, this));
  services_.push_back(private_nh.advertiseService("reset", &ClothNode::onReset, this));
  services_.push_back(private_nh.advertiseService("grasp", &ClothNode::onGrasp, this));
  services_.push_back(
      private_nh.advertiseService("release_grasp", &ClothNode::onReleaseGrasp, this));

  DragHandles::Options drag;
  drag.frame_id = params_.frame_id;
  drag.pick_distance = params_.drag_pick_distance;
  drag.radius = params_.drag_radius;
  drag_ = std::make_unique<DragHandles>(private_nh.resolveName("drag"), drag, &sim_, tf_buffer_,
                                        [this](int node) { return !frame_pins_.attached(node); });
  clicked_sub_ = nh.subscribe("clicked_point", 5, &ClothNode::onClickedPoint, this);
  tuning_ = std::make_unique<LiveTuning>(ros::NodeHandle(private_nh, "tuning"), &sim_, scene_yaml,
                                         tick_s_, [this] { divideTick(); });

  updater_.setHardwareID("none");
  updater_.add("simulation", this, &ClothNode::diagnose);
  window_.start = ros::SteadyTime::now();
  next_diagnostics_ = window_.start + ros::WallDuration(diag_period_);
  rereadParams();  // subscribes to ~diagnostic_period here, not inside a tick

  if (model().triangles.empty()) {
    ROS_INFO("cloth has a single column: ~cloth and ~strain carry no triangles");
  }
  ROS_INFO("cloth %dx%d, %s, %g Hz: %d step(s) of %.6g s per tick in frame '%s'",
           sim_.model().rows, sim_.model().cols, cloth_sim::toString(scene.solver.method),
           params_.rate, steps_per_tick_, step_h_, params_.frame_id.c_str());

  TickStats initial;
  initial.dt = step_h_;
  initial.energy = sim_.energy();
  initial.max_strain = sim_.maxStrain();
  const ros::Time stamp = ros::Time::now();
  publish(stamp, initial);
  publishColliders(stamp, true);
  last_tick_ = initial;
  timer_ = nh.createSteadyTimer(ros::WallDuration(tick_s_), &ClothNode::onTick, this);
}

const cloth_sim::Model& ClothNode::model() const { return sim_.model(); }

void ClothNode::divideTick() {
  divided_dt_ = sim_.dt();
  steps_per_tick_ = stepsPerTick(tick_s_, divided_dt_);
  step_h_ = tick_s_ / steps_per_tick_;
}

void ClothNode::forgetNode(int node) {
  frame_pins_.detach(node);
  grasps_.forget(node);
  if (drag_) drag_->forget(node);
}

void ClothNode::onClickedPoint(const geometry_msgs::PointStamped::ConstPtr& msg) {
  std::string error;
  const int node = drag_->addHandle(*msg, &error);
  if (node < 0) {
    ROS_WARN("clicked point: no drag handle: %s", error.c_str());
  } else {
    ROS_INFO("drag handle on node %d", node);
  }
}

// ------------------------------------------------------------------ tick ----

void ClothNode::onTick(const ros::SteadyTimerEvent& /*event*/) {
  const ros::SteadyTime start = ros::SteadyTime::now();
  const double sim_before = sim_.time();

  if (sim_.dt() != divided_dt_) divideTick();  // ~reset back to the scene's dt
  const std::map<std::string, std::string> lost = frame_pins_.update(&sim_, tick_s_);
  releaseLostGrasps(lost);
  for (const auto& [frame, error] : lost) {
    if (frame_pins_.hasFrame(frame)) {
      ROS_WARN_THROTTLE(2.0, "tf pin: %s; its nodes hold their last position", error.c_str());
      window_.tf_lost += 1;
      window_.tf_error = error;
    }
  }
  drag_->update(tick_s_);
  updateFrameColliders();

  TickStats tick;
  tick.dt = step_h_;
  if (sim_.adaptive()) {
    // Error-controlled: as many steps as the tick needs, the last on its end.
    tick.add(sim_.advanceTo(sim_.time() + tick_s_));
  } else {
    for (int k = 0; k < steps_per_tick_; ++k) {
      tick.add(sim_.step(step_h_));
      if (!tick.ok) break;  // the core rolled back; the next tick tries again
    }
  }
  const ros::SteadyTime publish_start = ros::SteadyTime::now();
  const ros::Time stamp = ros::Time::now();  // the cloth and its colliders at once
  publish(stamp, tick);
  publishColliders(stamp, false);
  const double publish_s = (ros::SteadyTime::now() - publish_start).toSec();
  drag_->publishPoses();
  tuning_->sync();

  const double busy = (ros::SteadyTime::now() - start).toSec();
  const bool overrun = busy > tick_s_;
  window_.ticks += 1;
  window_.overruns += overrun ? 1 : 0;
  overruns_total_ += overrun ? 1 : 0;
  window_.busy_s += busy;
  window_.busy_max_s = std::max(window_.busy_max_s, busy);
  window_.step_s += tick.wall_time_s;
  window_.publish_s += publish_s;
  window_.publish_max_s = std::max(window_.publish_max_s, publish_s);
  window_.cg_iterations += tick.cg_iterations;
  window_.cg_max = std::max(window_.cg_max, tick.cg_iterations);
  window_.residual_max = std::max(window_.residual_max, tick.residual);
  window_.rejected += tick.rejected;
  window_.error_rejected += tick.error_rejected;
  window_.h_min = cloth_sim::smallerStep(window_.h_min, tick.h_min);
  window_.h_max = std::max(window_.h_max, tick.h_max);
  window_.sim_time_s += sim_.time() - sim_before;
  if (!tick.ok) {
    window_.failures += 1;
    failures_total_ += 1;
    ROS_ERROR_THROTTLE(2.0, "solver step failed: %s; publishing the last good state",
                       tick.failure.c_str());
  }
  if (!tick.failure.empty()) window_.failure = tick.failure;
  last_tick_ = tick;
  rereadParams();
  updateDiagnostics(ros::SteadyTime::now());
}

void ClothNode::rereadParams() {
  XmlRpc::XmlRpcValue value;
  if (!private_nh_.getParamCached("diagnostic_period", value)) value = XmlRpc::XmlRpcValue();
  // Compared as XML (type and text): NaN == NaN there, so a bad value is said once.
  const std::string seen = value.valid() ? value.toXml() : std::string();
  if (seen == diag_period_seen_) return;  // unchanged since the last tick
  diag_period_seen_ = seen;
  if (!value.valid()) {  // deleted: the last good period stays
    if (!refused_param_.empty()) {
      ROS_INFO("parameter ~diagnostic_period removed; diagnostics stay every %g s", diag_period_);
    }
    refused_param_.clear();
    return;
  }
  double period = diag_period_;
  try {
    period = readDiagnosticPeriod(value);
  } catch (const ParamError& e) {
    refused_param_ = std::string("~") + e.what() + "; diagnostics stay every " +
                     format("%g", diag_period_) + " s";
    ROS_WARN("bad parameter %s", refused_param_.c_str());
    return;
  }
  if (period != diag_period_ || !refused_param_.empty()) {
    ROS_INFO("parameter ~diagnostic_period: diagnostics every %g s (was %g s)", period,
             diag_period_);
  }
  refused_param_.clear();
  const ros::SteadyTime sooner = ros::SteadyTime::now() + ros::WallDuration(period);
  if (sooner < next_diagnostics_) next_diagnostics_ = sooner;
  diag_period_ = period;
}

void ClothNode::updateDiagnostics(const ros::SteadyTime& now) {
  if (now < next_diagnostics_) return;
  next_diagnostics_ = now + ros::WallDuration(diag_period_);
  try {
    updater_.force_update();
  } catch (const std::exception& e) {  // never out of the tick: the cloth runs on
    ROS_ERROR_THROTTLE(10.0, "diagnostics not published: %s", e.what());
  }
}

void ClothNode::publish(const ros::Time& stamp, TickStats tick) {
  const bool finite = sim_.positions().allFinite() && sim_.velocities().allFinite();
  if (finite) {
    setTrianglePoints(model(), sim_.positions(), &cloth_marker_);
    fillClothState(sim_, &state_msg_);
  } else if (tick.ok) {
    tick.ok = false;  // never claim success for a state we do not show
    tick.failure = "state became non-finite";
  }
  fillTickStats(tick, &state_msg_);
  cloth_marker_.header.stamp = stamp;
  state_msg_.header.stamp = stamp;
  cloth_pub_.publish(cloth_marker_);

  if (underside_pub_.getNumSubscribers() > 0) {  // built only for a viewer
    if (finite) {
      setUndersidePoints(model(), sim_.positions(), &underside_marker_);
      underside_valid_ = true;
    }
    if (underside_valid_) {
      underside_marker_.header.stamp = stamp;
      underside_pub_.publish(underside_marker_);
    }
  } else {
    underside_valid_ = false;  // stale once nobody listens
  }

  if (params_.publish_strain && strain_pub_.getNumSubscribers() > 0) {
    if (finite) {
      setTrianglePoints(model(), sim_.positions(), &strain_marker_);
      setStrainColors(model(), sim_.nodeStrain(), &strain_marker_);
      strain_valid_ = true;
    }
    if (strain_valid_) {
      strain_marker_.header.stamp = stamp;
      strain_pub_.publish(strain_marker_);
    }
  } else {
    strain_valid_ = false;  // stale once nobody listens
  }
  state_pub_.publish(state_msg_);

  if (cloth_frame_pub_ && finite && stamp > cloth_frame_stamp_) {
    geometry_msgs::TransformStamped frame =
        clothFrame(model(), sim_.positions(), params_.frame_id, params_.cloth_frame);
    frame.header.stamp = stamp;
    cloth_frame_pub_->sendTransform(frame);
    cloth_frame_stamp_ = stamp;
  }
}

void ClothNode::updateFrameColliders() {
  if (frame_colliders_.size() == 0) return;
  const std::map<std::string, std::string> was_lost = frame_colliders_.lost();
  const std::map<std::string, std::string> newly_lost = frame_colliders_.update(&sim_, tick_s_);
  for (const auto& [frame, why] : newly_lost) {
    ROS_WARN("collider frame lost: %s; its colliders keep their last pose", why.c_str());
  }
  for (const auto& entry : was_lost) {
    if (!frame_colliders_.lost().count(entry.first)) {
      ROS_INFO("collider frame '%s' is back; its colliders follow it again",
               entry.first.c_str());
    }
  }
}

void ClothNode::publishColliders(const ros::Time& stamp, bool force) {
  const size_t n = sim_.colliders().size();
  if (n == 0 && !force) return;
  bool moved = force || published_collider_poses_.size() != n;
  for (size_t k = 0; k < n && !moved; ++k) {
    const cloth_sim::Pose& now = sim_.colliderState(static_cast<int>(k)).pose;
    const cloth_sim::Pose& then = published_collider_poses_[k];
    moved = now.translation != then.translation || now.rotation != then.rotation;
  }
  if (!moved) return;
  published_collider_poses_.resize(n);
  for (size_t k = 0; k < n; ++k) {
    published_collider_poses_[k] = sim_.colliderState(static_cast<int>(k)).pose;
  }
  fillColliderMarkers(sim_, params_.frame_id, defaultColliderColor(), &collider_markers_);
  for (visualization_msgs::Marker& m : collider_markers_.markers) m.header.stamp = stamp;
  colliders_pub_.publish(collider_markers_);
}

// -------------------------------------------------------------- services ----

Status ClothNode::pinNodes(const std::vector<long>& indices, const std::vector<Vec3>& positions,
                           const std::string& frame) {
  if (indices.empty()) return Status::error("indices: must not be empty");
  if (!positions.empty() && positions.size() != indices.size()) {
    return Status::error("positions: expected none or one per index (" +
                         std::to_string(indices.size()) + "), got " +
                         std::to_string(positions.size()));
  }
  for (size_t k = 0; k < positions.size(); ++k) {
    if (!positions[k].allFinite()) {
      return Status::error("positions[" + std::to_string(k) + "]: must be finite, got " +
                           formatPoint(positions[k]));
    }
  }
  std::vector<int> nodes;
  const Status valid = checkIndices(indices, sim_.numNodes(), &nodes);
  if (!valid) return valid;

  if (!params_.cloth_frame.empty() && frame == params_.cloth_frame) {
    return Status::error("frame_id: '" + frame +
                         "' is the node's own ~cloth_frame: a pin on it would follow the cloth it holds");
  }
  const bool attach = !frame.empty() && frame != params_.frame_id;
  std::vector<Vec3> targets = positions;  // fixed frame; empty: where they are
  std::vector<Vec3> offsets;
  if (attach) {
    Eigen::Isometry3d transform;
    std::string error;
    if (!frame_pins_.lookup(frame, &transform, &error)) return Status::error(error);
    for (size_t k = 0; k < nodes.size(); ++k) {
      if (positions.empty()) {
        offsets.push_back(transform.inverse() * sim_.position(nodes[k]));
      } else {
        offsets.push_back(positions[k]);
        targets[k] = transform * positions[k];
      }
    }
  }
  const Status pinned = sim_.pin(nodes, targets);
  if (!pinned) return pinned;
  for (size_t k = 0; k < nodes.size(); ++k) {
    forgetNode(nodes[k]);  // a new pin replaces whatever held the node
    if (attach) {
      frame_pins_.attach(nodes[k], frame, offsets[k], sim_.pins().at(nodes[k]).position);
    }
  }
  return Status::success("pinned " + std::to_string(nodes.size()) + " node(s)" +
                         (attach ? " to frame '" + frame + "'" : ""));
}

Status ClothNode::applyTfPinParams() {
  for (size_t k = 0; k < params_.tf_pins.size(); ++k) {
    const TfPinParam& pin = params_.tf_pins[k];
    const Status status =
        pinNodes(std::vector<long>(pin.indices.begin(), pin.indices.end()), pin.positions,
                 pin.frame_id);
    if (!status) return Status::error("tf_pins[" + std::to_string(k) + "]." + status.message);
  }
  return Status::success();
}

bool ClothNode::onPinNodes(cloth_sim::PinNodes::Request& req,
                           cloth_sim::PinNodes::Response& res) {
  std::vector<Vec3> positions;
  for (const geometry_msgs::Point& p : req.positions) positions.emplace_back(p.x, p.y, p.z);
  const Status status = pinNodes(toLong(req.indices), positions, req.frame_id);
  res.success = status.ok;
  res.message = status.message;
  if (!status) {  // at most 5 lines a second: a flood of bad calls must not flood /rosout
    window_.refused += 1;
    ROS_WARN_THROTTLE(0.2, "pin_nodes rejected: %s", status.message.c_str());
  }
  return true;
}

bool ClothNode::onReleaseNodes(cloth_sim::ReleaseNodes::Request& req,
                               cloth_sim::ReleaseNodes::Response& res) {
  Status status;
  if (req.all) {
    if (!req.indices.empty()) {
      status = Status::error("indices: must be empty when all is true, got " +
                             std::to_string(req.indices.size()) + " index(es)");
    } else {
      const size_t count = sim_.pinnedNodes().size();
      sim_.releaseAll();
      frame_pins_.clear();
      grasps_.clear();
      drag_->clearDrags();
      status = Status::success("released all " + std::to_string(count) + " pinned node(s)");
    }
  } else if (req.indices.empty()) {
    status = Status::error("indices: must not be empty (or set all: true)");
  } else {
    std::vector<int> nodes;
    status = checkIndices(toLong(req.indices), sim_.numNodes(), &nodes);
    if (status) status = sim_.release(nodes);
    if (status) {
      for (int node : nodes) forgetNode(node);
      status = Status::success("released " + std::to_string(nodes.size()) + " node(s)");
    }
  }
  res.success = status.ok;
  res.message = status.message;
  if (!status) {  // at most 5 lines a second: a flood of bad calls must not flood /rosout
    window_.refused += 1;
    ROS_WARN_THROTTLE(0.2, "release_nodes rejected: %s", status.message.c_str());
  }
  return true;
}

bool ClothNode::onSetStiffness(cloth_sim::SetStiffness::Request& req,
                               cloth_sim::SetStiffness::Response& res) {
  std::map<std::string, double> before;  // a jump by orders of magnitude is worth a warning
  for (int type = 0; type < cloth_sim::kNumSpringTypes; ++type) {
    const auto t = static_cast<cloth_sim::SpringType>(type);
    if (sim_.group(t).present) before[cloth_sim::toString(t)] = sim_.group(t).stiffness;
  }
  Status status = sim_.setStiffness(req.spring_type, req.stiffness, req.damping);
  if (status) {
    for (const auto& [name, old_k] : before) {
      if (req.spring_type != "all" && req.spring_type != name) continue;
      const double ratio = req.stiffness / old_k;
      if (ratio > 1e3 || ratio < 1e-3) {
        ROS_WARN("set_stiffness: %s stiffness changed %.3g times in one call (%g -> %g N/m); "
                 "the solver may split steps until the cloth settles",
                 name.c_str(), ratio, old_k, req.stiffness);
      }
    }
  }
  if (status && status.message.empty()) {
    status.message = "set " + req.spring_type + " stiffness to " + format("%g", req.stiffness) +
                     " N/m" +
                     (req.damping == -1.0 ? "" : ", damping to " + format("%g", req.damping) +
                                                     " N*s/m");
  }
  res.success = status.ok;
  res.message = status.message;
  if (!status) {  // at most 5 lines a second: a flood of bad calls must not flood /rosout
    window_.refused += 1;
    ROS_WARN_THROTTLE(0.2, "set_stiffness rejected: %s", status.message.c_str());
  }
  return true;
}

bool ClothNode::onReset(std_srvs::Trigger::Request& /*req*/,
                        std_srvs::Trigger::Response& res) {
  sim_.reset();
  frame_pins_.clear();  // attachments made by ~pin_nodes and ~grasp end here
  grasps_.clear();
  drag_->clearDrags();  // handles stay, on their nodes
  divideTick();         // the scene's dt again
  frame_colliders_.snap(&sim_);  // reset put them at their scene poses
  const Status reattached = applyTfPinParams();  // grabs the nodes where they now are
  res.success = true;
  res.message = "reset to the initial state";
  if (!reattached) {  // the reset happened, but the cloth is not held as the parameters say
    res.success = false;
    res.message += "; " + reattached.message + " (not re-attached)";
    ROS_WARN("reset: %s", reattached.message.c_str());
  }
  TickStats initial;
  initial.dt = step_h_;
  initial.energy = sim_.energy();
  initial.max_strain = sim_.maxStrain();
  const ros::Time stamp = ros::Time::now();
  publish(stamp, initial);  // show the initial state before the next step
  publishColliders(stamp, true);
  last_tick_ = initial;
  drag_->publishPoses();
  tuning_->sync();  // the scene's settings again
  return true;
}

// ----------------------------------------------------------- diagnostics ----

void ClothNode::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat) {
  using diagnostic_msgs::DiagnosticStatus;
  const ros::SteadyTime now = ros::SteadyTime::now();
  const double wall = std::max(1e-9, (now - window_.start).toSec());
  const Window& w = window_;
  const double ticks = std::max(1, w.ticks);

  if (w.failures > 0) {
    stat.summaryf(DiagnosticStatus::ERROR,
                  "solver failed in %d tick(s): %s; publishing the last good state", w.failures,
                  w.failure.c_str());
  } else if (!frame_colliders_.lost().empty()) {
    const auto& first = *frame_colliders_.lost().begin();
    stat.summaryf(DiagnosticStatus::WARN,
                  "collider frame lost: %s; its colliders keep their last pose",
                  first.second.c_str());
  } else if (w.overruns > 0) {
    stat.summaryf(DiagnosticStatus::WARN, "%d tick(s) overran the %.1f ms period", w.overruns,
                  1e3 * tick_s_);
  } else if (w.tf_lost > 0) {
    stat.summaryf(DiagnosticStatus::WARN, "tf pin frame lost in %d tick(s): %s; its nodes hold "
                  "their last position", w.tf_lost, w.tf_error.c_str());
  } else if (w.rejected > 0) {
    stat.summaryf(DiagnosticStatus::WARN, "recovered: %d step(s) rolled back and retried: %s",
                  w.rejected, w.failure.c_str());
  } else if (!refused_param_.empty()) {
    stat.summaryf(DiagnosticStatus::WARN, "bad parameter %s", refused_param_.c_str());
  } else {
    stat.summary(DiagnosticStatus::OK, "running");
  }
  stat.add("rate (Hz)", params_.rate);
  stat.addf("diagnostic period (s)", "%g", diag_period_);
  stat.add("bad parameter", refused_param_.empty() ? std::string("none") : refused_param_);
  stat.addf("achieved rate (Hz)", "%.2f", w.ticks / wall);
  stat.add("overruns", w.overruns);
  stat.add("overruns total", overruns_total_);
  stat.addf("step time (ms per tick)", "%.3f", 1e3 * w.step_s / ticks);
  stat.addf("publish time (ms per tick)", "%.3f", 1e3 * w.publish_s / ticks);
  stat.addf("publish time max (ms)", "%.3f", 1e3 * w.publish_max_s);
  stat.addf("tick time max (ms)", "%.3f", 1e3 * w.busy_max_s);
  stat.add("steps per tick", steps_per_tick_);
  stat.addf("dt (s)", "%.17g", step_h_);
  // The sizes the steps had (error control picks them; recovery may split).
  stat.addf("step size min (s)", "%.6g", w.h_min);
  stat.addf("step size max (s)", "%.6g", w.h_max);
  if (sim_.adaptive()) {
    stat.addf("error tolerance", "%.3g", *sim_.scene().solver.error_tolerance);
    stat.add("error-rejected steps", w.error_rejected);
  }
  stat.addf("CG iterations (per tick)", "%.1f", w.cg_iterations / ticks);
  stat.add("CG iterations max (per tick)", w.cg_max);
  stat.addf("residual max", "%.3g", w.residual_max);
  stat.addf("energy (J)", "%.6g", last_tick_.energy);
  stat.addf("max strain", "%.6g", last_tick_.max_strain);
  stat.addf("real-time factor", "%.3f", w.sim_time_s / wall);
  stat.addf("simulated time (s)", "%.3f", sim_.time());
  stat.add("rejected steps", w.rejected);
  stat.add("refused requests", w.refused);
  stat.add("failures total", failures_total_);
  stat.add("pinned nodes", sim_.pinnedNodes().size());
  stat.add("tf pins", frame_pins_.size());
  stat.add("grasped nodes", grasps_.numNodes());
  stat.add("drag handles", drag_->numHandles());
  stat.add("colliders", sim_.colliders().size());
  stat.add("tf colliders", frame_colliders_.size());
  stat.add("tf colliders lost frames", frame_colliders_.lost().size());
  stat.add("contacts", last_tick_.contacts);
  stat.addf("contact normal force (N)", "%.6g", last_tick_.contact_normal_force);
  stat.addf("max penetration (m)", "%.3g", sim_.maxPenetration());
  stat.add("self contacts", last_tick_.self_contacts);
  stat.addf("min self distance (m)", "%.3g", sim_.minSelfDistance());
  stat.add("tf pins lost (ticks)", w.tf_lost);
  for (int type = 0; type < cloth_sim::kNumSpringTypes; ++type) {
    const cloth_sim::SpringGroup& group = sim_.group(static_cast<cloth_sim::SpringType>(type));
    if (!group.present) continue;
    const std::string name = cloth_sim::toString(static_cast<cloth_sim::SpringType>(type));
    stat.addf(name + " stiffness (N/m)", "%.17g", group.stiffness);
    stat.addf(name + " damping (N*s/m)", "%.17g", group.damping);
  }
  window_ = Window();
  window_.start = now;
}

}  // namespace cloth_sim_ros
