#include "pg/graph/tracker.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <string>

#include "pg/core/error.h"
#include "pg/graph/factors.h"
#include "pg/tracker/tracker_config.h"

namespace pg {

namespace {

const SE3Manifold& se3_manifold() {
  static const SE3Manifold manifold;
  return manifold;
}

// Copies the points whose position and normal are finite; returns how many were left out (all
// of them when the normals do not match the points one to one).
int copy_finite_points(const PointCloud& in, PointCloud& out) {
  out.clear();
  if (in.normals.size() != in.points.size()) return int(in.points.size());
  out.reserve(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    if (in.points[i].allFinite() && in.normals[i].allFinite()) {
      out.push_back(in.points[i], in.normals[i]);
    }
  }
  return int(in.size() - out.size());
}

// o_t = o_{t-1} (o_{t-2}^-1 o_{t-1}): the last body-frame motion repeated.
SE3 predict(const SE3& o_prev2, const SE3& o_prev) { return o_prev * (o_prev2.inverse() * o_prev); }

}  // namespace

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> names = {"constvel", "imagetoimage", "patchgraph",
                                                 "gtpatch"};
  return names;
}

const char* to_string(Method method) { return method_names()[static_cast<int>(method)].c_str(); }

Method method_from_string(const std::string& name) {
  const auto& names = method_names();
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (names[i] == name) return static_cast<Method>(i);
  }
  throw InputError("unknown method '" + name +
                   "' (known: constvel, imagetoimage, patchgraph, gtpatch)");
}

const char* to_string(MotionFrame frame) {
  return frame == MotionFrame::kSensor ? "sensor" : "world";
}

MotionFrame motion_frame_from_string(const std::string& name) {
  if (name == "sensor") return MotionFrame::kSensor;
  if (name == "world") return MotionFrame::kWorld;
  throw InputError("unknown motion frame '" + name + "' (known: sensor, world)");
}

namespace {

// `o`, once its sigmas are in range.
GraphOptions checked(GraphOptions o) {
  const struct {
    const char* name;
    double value;
    bool may_be_zero;  // the damping prior's 0 turns it off
  } sigmas[] = {{"sigma_image_to_image", o.sigma_image_to_image, false},
                {"sigma_image_to_patch", o.sigma_image_to_patch, false},
                {"sigma_velocity", o.sigma_velocity, false},
                {"sigma_end_effector", o.sigma_end_effector, false},
                {"sigma_vision", o.sigma_vision, false},
                {"sigma_damping", o.sigma_damping, true},
                {"sigma_unconstrained", o.sigma_unconstrained, false}};
  for (const auto& s : sigmas) {
    if (s.may_be_zero && s.value == 0) continue;
    check_in_range(std::string("tracker option ") + s.name, s.value, kMinFactorSigma,
                   kMaxFactorSigma, s.may_be_zero ? " (or 0: off)" : "");
  }
  // The rest as their command-line options and config file check them (a window of -1 had run
  // as a batch that grows without end, solver_iterations -1 never moved the estimate).
  const int method = int(o.method);
  check_in_range("tracker option method", method, int(Method::kConstVel),
                 int(Method::kGroundTruthPatch));
  check_in_range("tracker option window", o.window, 0, 1e6, " (0: batch)");
  check_in_range("tracker option solver_iterations", o.solver_iterations, 1, 1e6);
  if (o.history_frames != 0) {
    if (o.window == 0) {
      throw InputError("tracker option history_frames = " + std::to_string(o.history_frames) +
                       ": needs a fixed-lag window (window is 0: a batch keeps every frame)");
    }
    check_in_range("tracker option history_frames", o.history_frames, o.window + 2, 1e9,
                   " (window + 2 at least; or 0: every frame)");
  }
  check_in_range("tracker option lost_after_frames", o.lost_after_frames, 0, 1e9, " (0: never)");
  check_in_range("tracker option patch.keyframe_interval", o.patch.keyframe_interval, 1, 1e9);
  check_in_range("tracker option patch.keyframe_settle_frames", o.patch.keyframe_settle_frames, 0,
                 1e9);
  check_in_range("tracker option patch.voxel_m", o.patch.voxel_m, 0, 1, " (0: every point)");
  for (const auto& [name, value] :
       {std::pair<const char*, double>{"max_registration_jump_m", o.max_registration_jump_m},
        {"max_registration_jump_rad", o.max_registration_jump_rad},
        {"max_registration_residual_m", o.max_registration_residual_m},
        {"max_registration_residual_rad", o.max_registration_residual_rad},
        {"image_to_image_gate_rad", o.image_to_image_gate_rad}}) {
    check_in_range(std::string("tracker option ") + name, value, 0, 1e9);
  }
  TrackerConfig config;
  config.icp = o.icp;
  check_tracker_config(config, "tracker option");
  return o;
}

}  // namespace

PatchGraphTracker::PatchGraphTracker(GraphOptions options,
                                     std::shared_ptr<const PointCloudTree> model_object)
    : options_(checked(std::move(options))), icp_(options_.icp), model_icp_(options_.icp) {
  // GroundtruthPatch: the mesh's face normals are exact, so its residuals are along them alone;
  // and it keeps every pair (with the pairs' normals limited its toy brick rotation was a fifth
  // better and its toy human translation RMSE a third worse, docs/tracker.md): the baseline
  // stays the one the tables measured.
  model_icp_.options().symmetric = false;
  model_icp_.options().max_normal_angle_rad = 0.0;
  // The window solves a frame for the last time window - 1 frames after it: settling later
  // would move nothing, and keep key frames' clouds for nothing (0: the window holds every frame).
  // (Both are at least 0: checked.)
  settle_frames_ = options_.window > 0
                       ? std::min(options_.patch.keyframe_settle_frames, options_.window - 1)
                       : options_.patch.keyframe_settle_frames;
  sensors_.resize(1);
  sensors_[0].patch = PatchMap(options_.patch);
  if (options_.method == Method::kGroundTruthPatch) {
    if (!model_object || model_object->size() == 0) {
      throw std::invalid_argument("PatchGraphTracker: gtpatch needs the object model's points");
    }
    sensors_[0].patch.set_model(std::move(model_object));
  }
}

void PatchGraphTracker::add_sensors(std::size_t count) {
  while (sensors_.size() < count) {
    SensorTrack& s = sensors_.emplace_back();
    s.patch = PatchMap(options_.patch);
    if (options_.method == Method::kGroundTruthPatch) {
      s.patch.set_model(sensors_[0].patch.model());
    }
  }
}

PatchGraphTracker::~PatchGraphTracker() = default;

Matrix6d PatchGraphTracker::registration_sqrt_info(const IcpResult& r, double sigma) const {
  if (!options_.registration_information || r.degeneracy.unconstrained == 0) {
    return isotropic_sqrt_info(sigma);
  }
  // The registration says nothing along the directions its Hessian leaves free (a sphere's
  // rotations, a flat face's slide and spin): give those zero information, the others the
  // factor's sigma. The report's twists perturb T_target_source on the left (target frame); the
  // factors' residuals live in the right tangent: T exp(xi_R) = exp(xi_L) T, xi_R = Ad_T^-1 xi_L.
  const Matrix6Xd free_left = r.degeneracy.unconstrained_twists_at_origin();
  const Matrix6Xd free_right = r.T_target_source.inverse().adjoint() * free_left;
  const Matrix6d projector =
      Matrix6d::Identity() -
      free_right * (free_right.transpose() * free_right).inverse() * free_right.transpose();
  // Not zero, though: with nothing else pinning them (the velocity prior only penalises changes
  // of velocity), the free directions could drift linearly without bound. A weak pull toward the
  // registration's answer there (its initial guess, the prediction) keeps them still.
  // P and I - P are orthogonal projectors: S^T S = P / s^2 + (I - P) / s_free^2.
  return projector / sigma + (Matrix6d::Identity() - projector) / options_.sigma_unconstrained;
}

double PatchGraphTracker::registration_disagreement(std::size_t first_registration,
                                                    std::size_t& to_previous) const {
  to_previous = factors_.size();
  std::size_t to_patch = factors_.size();
  for (std::size_t k = first_registration; k < factors_.size(); ++k) {
    if (factors_[k].kind == FactorKind::kImageToImage) to_previous = k;
    if (factors_[k].kind == FactorKind::kImageToPatch) to_patch = k;
  }
  if (to_previous == factors_.size() || to_patch == factors_.size()) {
    return std::numeric_limits<double>::quiet_NaN();
  }
  // The object in the current sensor frame, as each registration has it: the patch's answer
  // T_object_sensor inverted, and the previous frame's estimate carried by the image-to-image
  // answer T_previous_current.
  const Frame& p = frame(factors_[to_patch].frames[0] - 1);
  const SE3 from_patch = factors_[to_patch].measured.inverse();
  const SE3 from_previous =
      factors_[to_previous].measured.inverse() *
      (pose_from_block(p.sensors[factors_[to_previous].sensor].e).inverse() * pose_from_block(p.o));
  return rotation_distance(from_previous, from_patch);
}

bool PatchGraphTracker::gate_image_to_image(std::size_t first_registration, double& disagreement) {
  std::size_t to_previous = 0;
  disagreement = registration_disagreement(first_registration, to_previous);
  if (options_.image_to_image_gate_rad <= 0 || !(disagreement > options_.image_to_image_gate_rad)) {
    return false;
  }
  factors_.erase(factors_.begin() + std::ptrdiff_t(to_previous));
  return true;
}

bool PatchGraphTracker::plausible(const IcpResult& r, const SE3& guess) const {
  return translation_distance(r.T_target_source, guess) <= options_.max_registration_jump_m &&
         rotation_distance(r.T_target_source, guess) <= options_.max_registration_jump_rad;
}

bool PatchGraphTracker::registration_disagrees(const Factor& fac) const {
  // What the solved poses say the registration should have measured (eq. 5 and 6).
  SE3 solved;
  if (fac.kind == FactorKind::kImageToPatch) {
    const Frame& f = frame(fac.frames[0]);
    solved = pose_from_block(f.o).inverse() * pose_from_block(f.sensors[fac.sensor].e);
  } else {
    const Frame& p = frame(fac.frames[0]);
    const Frame& c = frame(fac.frames[1]);
    solved = (pose_from_block(p.sensors[fac.sensor].e).inverse() * pose_from_block(p.o)) *
             (pose_from_block(c.sensors[fac.sensor].e).inverse() * pose_from_block(c.o)).inverse();
  }
  return translation_distance(solved, fac.measured) > options_.max_registration_residual_m ||
         rotation_distance(solved, fac.measured) > options_.max_registration_residual_rad;
}

PatchGraphTracker::Outcome PatchGraphTracker::register_to_previous(int k, TrackerEstimate& est) {
  const int t = frames() - 1;
  const SensorTrack& s = sensors_[std::size_t(k)];
  if (!s.previous_tree || t < 1 || !frame(t - 1).sensors[k].contact) return Outcome::kNotTried;
  // A previous contact too small to register against is no failure of this frame's.
  if (int(s.previous_tree->size()) < icp_.options().min_points) return Outcome::kNotTried;
  const Frame& p = frame(t - 1);
  const Frame& f = frame(t);
  // Guess from the current (predicted) estimates: T_prev_cur = (e_p^-1 o_p)(e_c^-1 o_c)^-1.
  const SE3 T_sp_o = pose_from_block(p.sensors[k].e).inverse() * pose_from_block(p.o);
  const SE3 T_sc_o = pose_from_block(f.sensors[k].e).inverse() * pose_from_block(f.o);
  const SE3 guess = T_sp_o * T_sc_o.inverse();
  const IcpResult r = icp_.align(s.cloud, *s.previous_tree, guess);
  return add_registration(FactorKind::kImageToImage, {t - 1, t, -1}, k, r, guess,
                          options_.sigma_image_to_image, est);
}

PatchGraphTracker::Outcome PatchGraphTracker::register_to_patch(int k, TrackerEstimate& est,
                                                                std::vector<Matrix6Xd>& free_twists,
                                                                int& analysed) {
  const SensorTrack& s = sensors_[std::size_t(k)];
  PointToPlaneIcp& icp = options_.method == Method::kGroundTruthPatch ? model_icp_ : icp_;
  // A patch still smaller than a registration needs (the first touch of a slow approach) is
  // not tried; it grows by a key frame each frame until it is large enough (add).
  if (s.patch.empty() || int(s.patch.tree().size()) < icp.options().min_points)
    return Outcome::kNotTried;
  const int t = frames() - 1;
  const Frame& f = frame(t);
  const SE3 guess = pose_from_block(f.o).inverse() * pose_from_block(f.sensors[k].e);
  const IcpResult r = icp.align(s.cloud, s.patch.tree(), guess);
  // What the contact let the registration see, whether or not its answer is used (a failed
  // one, with too few points or matches, never analysed its Hessian).
  if (r.status == IcpStatus::kConverged || r.status == IcpStatus::kMaxIterations) {
    est.unconstrained_directions = r.degeneracy.unconstrained;
    ++analysed;
    if (sensors_.size() > 1) free_twists.push_back(r.degeneracy.unconstrained_twists_at_origin());
  }
  return add_registration(FactorKind::kImageToPatch, {t, -1, -1}, k, r, guess,
                          options_.sigma_image_to_patch, est);
}

PatchGraphTracker::Outcome PatchGraphTracker::add_registration(FactorKind kind,
                                                               std::array<int, 3> frames,
                                                               int sensor, const IcpResult& r,
                                                               const SE3& guess, double sigma,
                                                               TrackerEstimate& est) {
  if (!r.converged) {
    ++est.unconverged_registrations;
    // At the iteration limit the clouds still matched (every point an inlier, as a registration
    // that is nearly there oscillates below the tight convergence thresholds); with too few
    // points or matches they did not.
    return r.status == IcpStatus::kMaxIterations ? Outcome::kNotConverged : Outcome::kFailed;
  }
  if (!plausible(r, guess)) {
    ++est.rejected_registrations;
    return Outcome::kFailed;
  }
  Factor factor{kind,
                {frames[0], frames[1], frames[2]},
                sensor,
                r.T_target_source,
                registration_sqrt_info(r, sigma)};
  factors_.push_back(factor);
  (kind == FactorKind::kImageToPatch ? est.image_to_patch : est.image_to_image) = true;
  return Outcome::kAccepted;
}

void set_measurement(const ContactFrame& contact, SensorInput& input) {
  input.cloud_sensor.clear();
  if (contact.status == ContactStatus::kContact) input.cloud_sensor = contact.cloud_sensor;
  input.measurement_missing = contact.status == ContactStatus::kUnreadable;
}

TrackerEstimate PatchGraphTracker::add(const TrackerInput& input) {
  const auto start = std::chrono::steady_clock::now();
  TrackerEstimate est;
  const int t = frames();
  const std::size_t n_sensors = 1 + input.other_sensors.size();
  if (t == 0) add_sensors(n_sensors);
  if (n_sensors != sensors_.size()) {
    throw std::invalid_argument("PatchGraphTracker::add: frame " + std::to_string(t) + " has " +
                                std::to_string(n_sensors) + " sensor(s), the first frame had " +
                                std::to_string(sensors_.size()));
  }
  const auto sensor_input = [&](std::size_t k) -> const SensorInput& {
    return k == 0 ? input : input.other_sensors[k - 1];
  };
  // A non-finite measurement (a live pipeline's glitch; datasets are checked when read) is
  // dropped and reported: inside the window one NaN would poison every later estimate.
  const bool prior_ok = input.object_prior_given && is_finite(input.T_world_object_prior);
  est.invalid_input = input.object_prior_given && !prior_ok;
  Frame f;
  f.sensors.resize(n_sensors);
  std::vector<bool> sensor_ok(n_sensors);
  bool missing = false;  // the measurement of a sensor in the episode (as of the frame before)
  for (std::size_t k = 0; k < n_sensors; ++k) {
    const SensorInput& in = sensor_input(k);
    SensorTrack& track = sensors_[k];
    SensorState& state = f.sensors[k];
    sensor_ok[k] = is_finite(in.T_world_sensor_measured);
    const int dropped_points = copy_finite_points(in.cloud_sensor, track.cloud);
    if (in.measurement_missing) track.cloud.clear();  // its cloud, if any, is not used
    est.invalid_input =
        est.invalid_input || !sensor_ok[k] || dropped_points > 0 || in.measurement_missing;
    pose_to_block(sensor_ok[k] ? in.T_world_sensor_measured
                  : t >= 1     ? pose_from_block(frame(t - 1).sensors[k].e)
                               : SE3(),
                  state.e);
    state.T_sensor_world = pose_from_block(state.e).inverse();
    state.contact = !track.cloud.empty();
    f.contact = f.contact || state.contact;
    est.contact_sensors += state.contact;
    missing = missing || (in.measurement_missing && track.in_episode);
  }
  // A missing measurement of a sensor that held the object says nothing about its contact: the
  // episode goes on. One of a sensor that did not (a camera started late or stopped early, away
  // from the object) keeps no episode going once the others let go.
  f.held = f.contact || (missing && in_episode_);
  f.carrier = t >= 1 ? frame(t - 1).carrier : 0;
  if (!f.sensors[std::size_t(f.carrier)].contact) {
    for (std::size_t k = 0; k < n_sensors; ++k) {
      if (f.sensors[k].contact) {
        f.carrier = int(k);
        break;
      }
    }
  }
  SE3 o_init = prior_ok ? input.T_world_object_prior : SE3();
  if (t >= 1 && sensor_frame_motion(f, frame(t - 1))) {
    // Held: the object's pose in the sensor's frame is predicted (the last relative motion
    // repeated, when there is one) and placed at this frame's sensor pose, so the hand's own
    // motion, accelerations included, is followed exactly.
    const auto in_sensor = [&f](const Frame& g) {
      return g.sensors[std::size_t(f.carrier)].T_sensor_world * pose_from_block(g.o);
    };
    const Frame& p1 = frame(t - 1);
    const SE3 x = t >= 2 && sensor_frame_motion(p1, frame(t - 2))
                      ? predict(in_sensor(frame(t - 2)), in_sensor(p1))
                      : in_sensor(p1);
    o_init = f.sensors[std::size_t(f.carrier)].T_sensor_world.inverse() * x;
  } else if (t >= 2) {
    o_init = predict(pose_from_block(frame(t - 2).o), pose_from_block(frame(t - 1).o));
  } else if (t == 1) {
    o_init = pose_from_block(frame(0).o);
  }
  pose_to_block(o_init, f.o);
  frames_.push_back(std::move(f));
  Frame& cur = frames_.back();

  // Priors: the end-effector measurements every frame (eq. 8), the velocity prior (eq. 7), and
  // the vision prior on the first pose of each contact episode (eq. 9) and of the sequence.
  for (std::size_t k = 0; k < n_sensors; ++k) {
    if (!sensor_ok[k]) continue;
    factors_.push_back({FactorKind::kEndEffector,
                        {t, -1, -1},
                        int(k),
                        sensor_input(k).T_world_sensor_measured,
                        isotropic_sqrt_info(options_.sigma_end_effector)});
  }
  if (t >= 2) {
    factors_.push_back({FactorKind::kVelocity,
                        {t - 2, t - 1, t},
                        0,
                        SE3(),
                        isotropic_sqrt_info(options_.sigma_velocity)});
  }
  if (t >= 1 && options_.sigma_damping > 0) {
    factors_.push_back({FactorKind::kDamping,
                        {t - 1, t, -1},
                        0,
                        SE3(),
                        isotropic_sqrt_info(options_.sigma_damping)});
  }
  est.contact = cur.contact;
  est.new_episode = cur.contact && !in_episode_;
  if ((t == 0 || est.new_episode) && prior_ok) {
    pose_to_block(input.T_world_object_prior, cur.o);
    factors_.push_back({FactorKind::kVision,
                        {t, -1, -1},
                        0,
                        input.T_world_object_prior,
                        isotropic_sqrt_info(options_.sigma_vision)});
  }
  // Sensors that touch again while another held the object (an episode goes on while one
  // lifts off): they first try the patch they built before, which ties the estimate back to
  // what they saw then (the others may not see every direction), and start a fresh one if they
  // touch elsewhere (below).
  std::vector<bool> rejoining(n_sensors, false);
  for (std::size_t k = 0; k < n_sensors; ++k) {
    SensorTrack& track = sensors_[k];
    if (options_.method == Method::kPatchGraph &&
        (est.new_episode || (cur.sensors[k].contact && !track.in_episode))) {
      rejoining[k] = !est.new_episode && !track.patch.empty();
      if (!rejoining[k]) {
        track.patch.reset();
        track.last_keyframe = -1;
        track.unsettled.clear();
      }
    }
    track.in_episode =
        cur.sensors[k].contact || (sensor_input(k).measurement_missing && track.in_episode);
  }
  in_episode_ = cur.held;

  // Registrations (eq. 5 and 6) at the predicted poses, sensor by sensor.
  const std::size_t first_registration = factors_.size();
  // The anchor: image-to-patch where the method has it. Image-to-image alone follows the motion
  // from a wrong pose as happily as from the right one (after a jump, say), so it cannot tell
  // whether tracking holds.
  std::vector<Outcome> anchors(n_sensors, Outcome::kNotTried);
  std::vector<Matrix6Xd> free_twists;  // of each image-to-patch registration that got that far
  int analysed = 0;                    // image-to-patch registrations that got that far
  for (std::size_t k = 0; k < n_sensors; ++k) {
    if (!cur.sensors[k].contact) continue;
    const std::size_t first_of_sensor = factors_.size();
    const Method m = options_.method;
    Outcome to_previous = Outcome::kNotTried, to_patch = Outcome::kNotTried;
    if (m == Method::kImageToImage || m == Method::kPatchGraph) {
      to_previous = register_to_previous(int(k), est);
    }
    if (m == Method::kPatchGraph || m == Method::kGroundTruthPatch) {
      to_patch = register_to_patch(int(k), est, free_twists, analysed);
    }
    anchors[k] = m == Method::kImageToImage ? to_previous : to_patch;
    // When both registrations were accepted (a factor each from first_of_sensor on), the gate
    // may leave the image-to-image one out.
    double disagreement = 0;
    if (gate_image_to_image(first_of_sensor, disagreement)) est.image_to_image_dropped = true;
    est.registration_disagreement_rad = std::fmax(est.registration_disagreement_rad, disagreement);
  }
  // Another sensor's image-to-image factor may hold where one sensor's was left out.
  est.image_to_image =
      std::any_of(factors_.begin() + std::ptrdiff_t(first_registration), factors_.end(),
                  [](const Factor& f) { return f.kind == FactorKind::kImageToImage; });
  if (free_twists.size() > 1)
    est.unconstrained_directions = common_unconstrained_directions(free_twists);
  // A contact frame past an episode's first whose image-to-patch registration never got to its
  // analysis (a patch or cloud smaller than a registration needs, too few matches) constrained
  // nothing: said so, all 6, not 0.
  const bool with_patch =
      options_.method == Method::kPatchGraph || options_.method == Method::kGroundTruthPatch;
  if (cur.contact && !est.new_episode && with_patch && analysed == 0) {
    est.unconstrained_directions = 6;
  }

  const int first = options_.window > 0 ? std::max(0, t - options_.window + 1) : 0;
  solve(first, options_.solver_iterations);

  // Registrations the solution overrode (see registration_disagrees) do not hold the pose.
  const FactorKind anchor_kind = options_.method == Method::kImageToImage
                                     ? FactorKind::kImageToImage
                                     : FactorKind::kImageToPatch;
  for (std::size_t k = first_registration; k < factors_.size(); ++k) {
    if (!registration_disagrees(factors_[k])) continue;
    ++est.overridden_registrations;
    if (factors_[k].kind == anchor_kind)
      anchors[std::size_t(factors_[k].sensor)] = Outcome::kFailed;
  }
  for (std::size_t k = 0; k < n_sensors; ++k) {
    if (!rejoining[k] || anchors[k] == Outcome::kAccepted) continue;
    // It touched elsewhere than before: a fresh patch from here (not a failure).
    sensors_[k].patch.reset();
    sensors_[k].last_keyframe = -1;
    sensors_[k].unsettled.clear();
    anchors[k] = Outcome::kNotTried;
  }
  // The frame's anchor failed when no sensor's that was tried was accepted: each failed to
  // match, as a plausible jump or against the solution, or stopped at the iteration limit (which
  // adds no factor either: frame after frame of it is a patch that no longer holds the object,
  // as when it turns faster than the registrations follow).
  const auto tried = [](Outcome a) { return a != Outcome::kNotTried; };
  const bool anchor_failed = std::any_of(anchors.begin(), anchors.end(), tried) &&
                             std::none_of(anchors.begin(), anchors.end(),
                                          [](Outcome a) { return a == Outcome::kAccepted; });
  // Lost: contact, and the anchor fails now and failed in lost_after_frames of the last
  // 2 x lost_after_frames - 1 (so when it failed that many frames running, or every other one).
  if (cur.contact) {
    const bool failed = anchor_failed && !est.new_episode;
    if (est.new_episode) recent_anchor_failures_.clear();
    recent_anchor_failures_.push_back(failed);
    const int n = options_.lost_after_frames;
    while (int(recent_anchor_failures_.size()) > std::max(1, 2 * n - 1))
      recent_anchor_failures_.pop_front();
    const long recent =
        std::count(recent_anchor_failures_.begin(), recent_anchor_failures_.end(), true);
    est.tracking_lost = options_.method != Method::kConstVel && n > 0 && failed && recent >= n;
  }

  Frame& solved = frames_.back();
  for (std::size_t k = 0; k < n_sensors; ++k) {
    SensorTrack& track = sensors_[k];
    const bool contact = solved.sensors[k].contact;
    // Key frames fused settle_frames ago move to the pose the window has settled on since (a
    // key frame is first fused with its frame's filtered estimate, so that the next frames can
    // register against its surface at once).
    const auto T_object_sensor = [k](const Frame& f) {
      return pose_from_block(f.o).inverse() * pose_from_block(f.sensors[k].e);
    };
    while (!track.unsettled.empty() && t - track.unsettled.front()[0] >= settle_frames_) {
      track.patch.move_keyframe(track.unsettled.front()[1],
                                T_object_sensor(frame(track.unsettled.front()[0])));
      track.unsettled.erase(track.unsettled.begin());
    }
    // Key frame: fuse the cloud into the sensor's patch with the solved pose, unless its patch
    // registration failed: after a jump, say, the cloud would be fused at a wrong pose, and
    // every later registration would agree with the polluted patch instead of reporting the
    // loss. The next frame whose registration holds takes its place.
    const bool patch_too_small =
        track.patch.empty() || int(track.patch.tree().size()) < icp_.options().min_points;
    const bool keyframe_due = contact && anchors[k] != Outcome::kFailed &&
                              (track.last_keyframe < 0 || patch_too_small ||
                               t - track.last_keyframe >= options_.patch.keyframe_interval);
    if (keyframe_due && options_.method == Method::kPatchGraph) {
      const int keyframe =
          track.patch.add_keyframe(track.cloud, T_object_sensor(solved), settle_frames_ > 0);
      if (settle_frames_ > 0) track.unsettled.push_back({t, keyframe});
      track.last_keyframe = t;
      est.keyframe = true;
    } else if (keyframe_due && options_.method == Method::kGroundTruthPatch) {
      // GroundtruthPatch fuses nothing; its key frames mark the part of the model they touched,
      // which patch.ply exports instead of the whole model.
      track.patch.mark_touched(track.cloud, T_object_sensor(solved));
      track.last_keyframe = t;
    }
    // This frame's cloud becomes the next frame's image-to-image target.
    if (contact &&
        (options_.method == Method::kImageToImage || options_.method == Method::kPatchGraph)) {
      track.previous_tree = std::make_unique<PointCloudTree>(track.cloud);
    } else {
      track.previous_tree.reset();
    }
  }

  est.T_world_object = pose_from_block(solved.o);
  est.T_world_sensor = pose_from_block(solved.sensors[0].e);
  forget_old_frames();
  est.solve_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return est;
}

void PatchGraphTracker::solve(int first_frame, int iterations) {
  ceres::Problem::Options problem_options;
  problem_options.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  auto* manifold = const_cast<SE3Manifold*>(&se3_manifold());
  auto add_block = [&](double* block, int frame) {
    if (problem.HasParameterBlock(block)) return;
    problem.AddParameterBlock(block, kPoseBlockSize, manifold);
    // Frames before the window are held at their estimates (conditioning, see docs).
    if (frame < first_frame) problem.SetParameterBlockConstant(block);
  };
  // Factors are stored in the order of their newest frame: walk back to the window's start.
  for (auto it = factors_.rbegin(); it != factors_.rend(); ++it) {
    const Factor& fac = *it;
    if (fac.newest_frame() < first_frame) break;
    Frame& a = frame(fac.frames[0]);
    double* a_e = a.sensors[fac.sensor].e;
    switch (fac.kind) {
      case FactorKind::kEndEffector:
        add_block(a_e, fac.frames[0]);
        problem.AddResidualBlock(PosePriorFactor::create(fac.measured, fac.sqrt_info), nullptr,
                                 a_e);
        break;
      case FactorKind::kVision:
        add_block(a.o, fac.frames[0]);
        problem.AddResidualBlock(PosePriorFactor::create(fac.measured, fac.sqrt_info), nullptr,
                                 a.o);
        break;
      case FactorKind::kImageToPatch:
        add_block(a.o, fac.frames[0]);
        add_block(a_e, fac.frames[0]);
        problem.AddResidualBlock(ImageToPatchFactor::create(fac.measured, fac.sqrt_info), nullptr,
                                 a.o, a_e);
        break;
      case FactorKind::kImageToImage: {
        Frame& b = frame(fac.frames[1]);
        double* b_e = b.sensors[fac.sensor].e;
        add_block(a.o, fac.frames[0]);
        add_block(a_e, fac.frames[0]);
        add_block(b.o, fac.frames[1]);
        add_block(b_e, fac.frames[1]);
        problem.AddResidualBlock(ImageToImageFactor::create(fac.measured, fac.sqrt_info), nullptr,
                                 a.o, a_e, b.o, b_e);
        break;
      }
      case FactorKind::kDamping: {
        Frame& b = frame(fac.frames[1]);
        add_block(a.o, fac.frames[0]);
        add_block(b.o, fac.frames[1]);
        const bool in_sensor = sensor_frame_motion(b, a);
        problem.AddResidualBlock(
            VelocityDampingFactor::create(fac.sqrt_info,
                                          {motion_frame_inverse(a, in_sensor, b.carrier),
                                           motion_frame_inverse(b, in_sensor, b.carrier)}),
            nullptr, a.o, b.o);
        break;
      }
      case FactorKind::kVelocity: {
        Frame& b = frame(fac.frames[1]);
        Frame& c = frame(fac.frames[2]);
        add_block(a.o, fac.frames[0]);
        add_block(b.o, fac.frames[1]);
        add_block(c.o, fac.frames[2]);
        const bool in_sensor = sensor_frame_motion(b, a) && sensor_frame_motion(c, b);
        problem.AddResidualBlock(
            ConstantVelocityFactor::create(fac.sqrt_info,
                                           {motion_frame_inverse(a, in_sensor, c.carrier),
                                            motion_frame_inverse(b, in_sensor, c.carrier),
                                            motion_frame_inverse(c, in_sensor, c.carrier)}),
            nullptr, a.o, b.o, c.o);
        break;
      }
    }
  }
  ceres::Solver::Options solver_options;
  solver_options.max_num_iterations = iterations;
  // Dense for a fixed-lag window's few frames, sparse for many (a batch solve of a whole
  // sequence, --compare-batch: dense, its normal matrix grew with the square of the frames).
  const int solved_frames = frames() - first_frame;
  solver_options.linear_solver_type =
      solved_frames <= 40 ? ceres::DENSE_NORMAL_CHOLESKY : ceres::SPARSE_NORMAL_CHOLESKY;
  solver_options.num_threads = 1;
  solver_options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver_options, &problem, &summary);
}

void PatchGraphTracker::forget_old_frames() {
  if (options_.history_frames == 0 || int(frames_.size()) <= options_.history_frames) return;
  while (int(frames_.size()) > options_.history_frames) {
    frames_.pop_front();
    ++first_kept_frame_;
  }
  // Every factor is added with the frame it ends at, so they go in that order. One ending before
  // the second frame kept may reach a frame let go (a velocity prior spans three); those ending
  // later reach the first frame kept at most. The window never reads further back.
  while (!factors_.empty() && factors_.front().newest_frame() < first_kept_frame_ + 2) {
    factors_.pop_front();
  }
}

std::vector<SE3> PatchGraphTracker::object_trajectory() const {
  std::vector<SE3> out;
  out.reserve(frames_.size());
  for (const auto& f : frames_) out.push_back(pose_from_block(f.o));
  return out;
}

void PatchGraphTracker::solve_batch(int iterations) {
  // Once frames were let go, the two oldest kept are what the factors left anchor to.
  solve(first_kept_frame_ > 0 ? first_kept_frame_ + 2 : 0, iterations);
}

}  // namespace pg
