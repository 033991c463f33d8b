#pragma once
// PatchGraph: tracks an object's pose from per-frame contact clouds with a fixed-lag factor
// graph (paper eq. 3): object poses o_t and sensor poses e_t, with image-to-image (eq. 5),
// image-to-patch (eq. 6), constant-velocity (eq. 7), end-effector (eq. 8) and vision (eq. 9)
// factors, solved by Ceres over a sliding window.
#include <algorithm>
#include <array>
#include <deque>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "pg/graph/patch_map.h"
#include "pg/graph/pose_block.h"
#include "pg/tracker/contact_cloud.h"
#include "pg/tracker/icp.h"

namespace pg {

// The paper's section V-C objectives.
enum class Method {
  kConstVel,          // velocity prior (and the end-effector and vision priors) only
  kImageToImage,      // + image-to-image factors
  kPatchGraph,        // + image-to-patch factors against the local patch (the paper's method)
  kGroundTruthPatch,  // image-to-patch factors against the known object model
};
const char* to_string(Method method);

// The frame in which the motion priors (constant velocity, damping) and each new frame's
// prediction hold the object while it is in contact (see GraphOptions::motion_frame).
enum class MotionFrame {
  kSensor,  // the object is held: it moves with the sensor (in-hand manipulation)
  kWorld,   // the object stays put and the sensor moves over it (exploring a fixed object)
};
const char* to_string(MotionFrame frame);
// "sensor", "world"; throws InputError for other names.
MotionFrame motion_frame_from_string(const std::string& name);
// "constvel", "imagetoimage", "patchgraph", "gtpatch"; throws InputError for other names.
Method method_from_string(const std::string& name);
const std::vector<std::string>& method_names();

// Factor sigmas [m, rad] outside this range are refused (the damping prior's may also be 0:
// off). It holds what the stress tests solve (tests/stress/test_stress_solver.cpp: each sigma
// from 1e-9 to 1e3, all of them scaled together down to 1e-11); far below it the information
// overflows the solver's doubles, above it (1 km, 1000 rad) a factor no longer pulls at all.
inline constexpr double kMinFactorSigma = 1e-12;
inline constexpr double kMaxFactorSigma = 1e3;

struct GraphOptions {
  Method method = Method::kPatchGraph;
  // Factor sigmas, all six axes alike ([m] and [rad]); the paper's values.
  double sigma_image_to_image = 1e-3;
  double sigma_image_to_patch = 1e-3;
  double sigma_velocity = 1e-2;
  double sigma_end_effector = 1e-5;
  double sigma_vision = 1e-4;
  double sigma_damping = 1e-2;  // zero-velocity prior (see VelocityDampingFactor); 0 turns it off
  // While the object is in contact (a contact episode, frames without a measurement included)
  // the motion priors and the prediction hold its pose relative to the sensor (kSensor): held in
  // the hand, it moves with the sensor, and only its motion relative to the sensor is smooth;
  // priors in the world frame (the paper's eq. 7) resist the hand's own accelerations and, with
  // the object held, tracked a hand swinging 2 rad over 300 frames to 2.5 mm (docs/tracker.md).
  // kWorld is for a sensor that moves over a fixed object. For a still sensor the two agree.
  // Between episodes the priors always hold the world frame.
  MotionFrame motion_frame = MotionFrame::kSensor;
  // Registration factors carry no information along the directions the ICP Hessian leaves
  // unconstrained (a sphere's rotation, a flat face's slide): those follow the velocity prior
  // instead of registration noise (but for a weak pull, sigma_unconstrained, that stops a drift
  // the velocity prior cannot see). The other directions keep the sigma above.
  bool registration_information = true;
  double sigma_unconstrained = 1e-1;  // registration sigma along those free directions
  // A registration that moves the pose further than this from the prediction is rejected (and
  // counted): a wrong local minimum must not become a factor that drags the velocity along.
  double max_registration_jump_m = 3e-3;
  double max_registration_jump_rad = 0.3;
  // A solved pose further than this from an accepted registration's answer means the other
  // factors overrode the measurement (e.g. priors with sigmas far too small): it is counted
  // (TrackerEstimate::overridden_registrations) and does not count as registered below.
  double max_registration_residual_m = 1e-3;
  double max_registration_residual_rad = 0.05;
  // When both registrations of a frame hold but turn the object in the current sensor frame
  // further apart than this (the image-to-patch answer against the previous estimate carried by
  // the image-to-image one), the image-to-image factor is left out
  // (TrackerEstimate::image_to_image_dropped): the patch, fused over many frames, is the steadier
  // reference. Two factors at the full sigma that disagree by tens of sigmas along a weakly seen
  // direction were otherwise reconciled by a turn along the one neither sees (a rolling limb's
  // own axis: docs/tracker.md "The image-to-image gate"). 0 turns the gate off.
  double image_to_image_gate_rad = 2.5e-3;
  // Tracking is reported lost (TrackerEstimate::tracking_lost) once the anchoring registration
  // (image-to-patch; image-to-image for that method) failed in this many consecutive contact
  // frames: too few points or matches within max_correspondence_m, an implausible jump, a
  // solution that overrode it, or the iteration limit (no factor either); or, failing now, in
  // this many of the last 2 x this - 1 contact frames (failures alternating with registrations
  // that hold, each of which had cleared the count while the estimate ran off). While it fails
  // (not at the iteration limit) no key frame is taken. A new episode or a registration that
  // holds clears it. constvel never reports it; 0: never.
  int lost_after_frames = 3;
  int window = 5;              // frames optimised at each update; 0 keeps every frame (batch)
  int solver_iterations = 10;  // Levenberg-Marquardt iterations per update
  // Frames whose estimates and factors the tracker keeps (object_trajectory, solve_batch): 0
  // keeps every frame (about 2 kB a frame); otherwise at least window + 2 (what the window's
  // update reads: its frames and the two held before them), and the tracker's memory stays
  // bounded however long it runs. The estimates do not depend on it. Needs a window (not 0).
  int history_frames = 0;
  PatchMapOptions patch;
  IcpOptions icp;
};

// One sensor's measurement of a frame.
struct SensorInput {
  PointCloud cloud_sensor;      // the contact's points in the sensor frame; empty: no contact
  SE3 T_world_sensor_measured;  // e~_t: the end-effector pose measurement
  // The tactile image could not be read (ContactStatus::kUnreadable): whether the object touches
  // is unknown. The cloud is ignored and the frame is predicted by the motion priors, but a
  // contact episode in progress continues (its patch kept, no new vision prior) instead of
  // ending as it would at a frame without contact. Reported as invalid_input.
  bool measurement_missing = false;
};

// A frame's measurements: the first sensor's (this object's SensorInput part), any further
// sensors touching the same object, and the vision prior.
struct TrackerInput : SensorInput {
  SE3 T_world_object_prior;  // o~_t: the vision prior, used at the start of a contact episode
  // False when there is no vision prior for this frame (a recording without the object's pose
  // here): a contact episode starting at it starts from the motion priors' prediction (with a
  // fresh patch as always), and frame 0 at the identity. Not an invalid input.
  bool object_prior_given = true;
  // Further sensors on the same object (fingertips of one hand: a pinch, a grasp), the same ones
  // in the same order every frame. Each has its own sensor pose, end-effector prior,
  // registrations and local patch (its part of the object's surface); they share the object's
  // pose. The object is in contact while any of them touches it, so one finger carries the
  // episode while another lifts off and touches again (it then registers against the patch it
  // built before, or starts a fresh one if it touches elsewhere). The motion frame
  // (GraphOptions::motion_frame) is that of the sensor carrying the object: the one that carried
  // it in the previous frame while it still touches, else the first touching one. A finger that
  // lets go and moves away takes no prior with it, whichever order the sensors come in.
  std::vector<SensorInput> other_sensors;
};

// Sets a sensor's measurement from a frame's contact: its cloud, none, or missing.
void set_measurement(const ContactFrame& contact, SensorInput& input);

struct TrackerEstimate {
  SE3 T_world_object;
  SE3 T_world_sensor;                   // the first sensor's
  bool contact = false;                 // any sensor touches
  int contact_sensors = 0;              // how many sensors touch
  bool new_episode = false;             // a contact episode started at this frame
  bool image_to_image = false;          // an image-to-image factor was added
  bool image_to_patch = false;          // an image-to-patch factor was added
  bool image_to_image_dropped = false;  // disagreed with image-to-patch (see GraphOptions)
  // The rotation between where the frame's image-to-image and image-to-patch registrations put
  // the object, when both were accepted (the largest over the sensors); NaN otherwise [rad].
  // Mostly 0.1-0.2 mrad on the benchmark; tens of mrad where the contact shows its rotation
  // poorly (a sharp vertex of 60-90 points).
  double registration_disagreement_rad = std::numeric_limits<double>::quiet_NaN();
  bool keyframe = false;  // the cloud was fused into the patch
  // Of the image-to-patch registration, if it got that far; with several sensors, the directions
  // none of their registrations constrains.
  int unconstrained_directions = 0;
  int rejected_registrations = 0;     // converged, but too far from the prediction
  int unconverged_registrations = 0;  // ICP failed (too few points or matches, iteration limit)
  int overridden_registrations = 0;   // accepted, but the solution disagrees (see GraphOptions)
  bool tracking_lost = false;         // see GraphOptions::lost_after_frames
  // A non-finite sensor pose or vision prior (a zero quaternion too, ROS's unset pose) or cloud
  // point was given: it was left out (the sensor
  // pose then holds the previous frame's, the object pose the prediction); or a measurement was
  // missing (SensorInput::measurement_missing).
  bool invalid_input = false;
  double solve_ms = 0;  // graph update time
};

class PatchGraphTracker {
 public:
  // `model_object` (object frame, points with normals, built as its tree: shared by every
  // sensor's patch, and by other trackers of the object) is required by kGroundTruthPatch and
  // ignored otherwise. Throws InputError naming the option when a sigma is outside
  // [kMinFactorSigma, kMaxFactorSigma] or not a number, or another option outside the range its
  // command-line option or config file allows (a negative window, no solver iterations, ...).
  // Memory: by default every frame's estimate and factors stay (for object_trajectory and
  // solve_batch), about 2 kB a frame (0.4 GB an hour at 60 Hz, measured on 20 000 frames); the
  // update's time does not grow with them. A long-running program sets
  // GraphOptions::history_frames to keep only the last frames.
  explicit PatchGraphTracker(GraphOptions options,
                             std::shared_ptr<const PointCloudTree> model_object = nullptr);
  ~PatchGraphTracker();

  // The first frame fixes how many sensors there are; a later frame with another count throws
  // std::invalid_argument.
  TrackerEstimate add(const TrackerInput& input);

  // The estimate of every frame kept (from first_kept_frame() on): the window's latest
  // solution, frozen before it.
  std::vector<SE3> object_trajectory() const;
  // Re-solves the frames kept with all their factors (the batch reference for the window); with
  // GraphOptions::history_frames, once frames were let go, the oldest two kept are held as they
  // are (the factors that tied them to earlier frames are gone).
  void solve_batch(int iterations = 50);

  int sensors() const { return int(sensors_.size()); }
  // Sensor k's local patch (object frame); for gtpatch, the object model.
  // Throws std::out_of_range for a sensor the tracker does not have.
  const PatchMap& patch(int sensor = 0) const {
    if (sensor < 0 || std::size_t(sensor) >= sensors_.size()) {
      throw std::out_of_range("PatchGraphTracker::patch: no sensor " + std::to_string(sensor) +
                              " (the tracker has " + std::to_string(sensors_.size()) + ")");
    }
    return sensors_[std::size_t(sensor)].patch;
  }
  const GraphOptions& options() const { return options_; }
  // Frames added so far, and the first whose estimate is still kept (GraphOptions::history_frames;
  // 0 without it).
  int frames() const { return first_kept_frame_ + int(frames_.size()); }
  int first_kept_frame() const { return first_kept_frame_; }
  // The factors kept (priors and registrations of the frames kept).
  int factors() const { return int(factors_.size()); }

 private:
  struct SensorState {
    double e[kPoseBlockSize];  // T_world_sensor
    bool contact = false;
    SE3 T_sensor_world;  // the inverse of the sensor pose given (the previous one when missing)
  };
  struct Frame {
    double o[kPoseBlockSize];  // T_world_object
    std::vector<SensorState> sensors;
    bool contact = false;  // any sensor touches
    bool held = false;     // in a contact episode (contact, or in one and a measurement missing)
    int carrier = 0;       // the sensor whose frame holds the motion priors (TrackerInput)
  };
  // What the tracker keeps per sensor between frames.
  struct SensorTrack {
    PatchMap patch;
    int last_keyframe = -1;
    bool in_episode = false;  // this sensor's own contact (or missing measurement within it)
    std::unique_ptr<PointCloudTree> previous_tree;  // the previous frame's cloud, for eq. 5
    PointCloud cloud;                               // this frame's
    // Key frames fused with their frame's first estimate, to be moved to the window's settled
    // one (PatchMapOptions::keyframe_settle_frames): {frame, the patch's key frame number}.
    std::vector<std::array<int, 2>> unsettled;
  };
  enum class FactorKind {
    kImageToImage,
    kImageToPatch,
    kVelocity,
    kDamping,
    kEndEffector,
    kVision
  };
  struct Factor {
    FactorKind kind;
    int frames[3] = {-1, -1, -1};  // absolute frame indices, oldest first; the last is the newest
    int sensor = 0;                // whose pose and measurement (registrations, end-effector prior)
    SE3 measured;
    Matrix6d sqrt_info;
    int newest_frame() const { return std::max({frames[0], frames[1], frames[2]}); }
  };
  // What became of one registration.
  enum class Outcome {
    kNotTried,      // nothing to register against (no previous cloud, empty patch)
    kAccepted,      // a factor was added
    kNotConverged,  // iteration limit: no factor; counts toward lost as kFailed does
    kFailed,        // too few points or matches, an implausible jump, or overridden
  };
  void solve(int first_frame, int iterations);
  // Sensor k's registrations of this frame's cloud; register_to_patch adds the directions it
  // left free (twists about the object's origin) to `free_twists`.
  // (and counts in `analysed` a registration that got as far as its degeneracy analysis).
  Outcome register_to_patch(int k, TrackerEstimate& est, std::vector<Matrix6Xd>& free_twists,
                            int& analysed);
  Outcome register_to_previous(int k, TrackerEstimate& est);
  Outcome add_registration(FactorKind kind, std::array<int, 3> frames, int sensor,
                           const IcpResult& r, const SE3& guess, double sigma,
                           TrackerEstimate& est);
  void add_sensors(std::size_t count);
  Matrix6d registration_sqrt_info(const IcpResult& r, double sigma) const;
  bool plausible(const IcpResult& r, const SE3& guess) const;
  // Whether the motion from frame `before` to `after` is held in the sensor's frame: both in a
  // contact episode, and GraphOptions::motion_frame says so.
  bool sensor_frame_motion(const Frame& after, const Frame& before) const {
    return options_.motion_frame == MotionFrame::kSensor && after.held && before.held;
  }
  // F^-1 of a motion prior's frame F at frame g (factors.h): sensor `carrier`'s or the world's.
  // A prior spanning several frames takes its newest frame's carrier for all of them.
  static SE3 motion_frame_inverse(const Frame& g, bool in_sensor, int carrier) {
    return in_sensor ? g.sensors[std::size_t(carrier)].T_sensor_world : SE3();
  }
  // Frame t (absolute, from first_kept_frame_ on).
  Frame& frame(int t) { return frames_[std::size_t(t - first_kept_frame_)]; }
  const Frame& frame(int t) const { return frames_[std::size_t(t - first_kept_frame_)]; }
  // Lets go of the frames before the last GraphOptions::history_frames, and of their factors.
  void forget_old_frames();
  bool registration_disagrees(const Factor& factor) const;
  // How far apart this frame's image-to-image and image-to-patch factors of one sensor (from
  // first_registration on) turn the object in the current sensor frame [rad]: the patch's answer
  // against the previous estimate carried by the image-to-image one. NaN unless both were
  // accepted; `to_previous` is then the image-to-image factor's index.
  double registration_disagreement(std::size_t first_registration, std::size_t& to_previous) const;
  // Removes this frame's image-to-image factor (from first_registration on) when it and the
  // frame's image-to-patch factor turn the object further apart than
  // GraphOptions::image_to_image_gate_rad; true if it did. `disagreement`: as above.
  bool gate_image_to_image(std::size_t first_registration, double& disagreement);

  GraphOptions options_;
  int settle_frames_ = 0;             // PatchMapOptions::keyframe_settle_frames, at most window - 1
  std::vector<SensorTrack> sensors_;  // at least one
  PointToPlaneIcp icp_;
  // gtpatch's registrations against the object model: with the model's normals alone. The
  // model's normals are its faces' (sharp at every edge), the clouds' the sensor's (smoothed over
  // neighbouring pixels), and the symmetric objective, which mixes the two, tracked worse with
  // them (docs/tracker.md).
  PointToPlaneIcp model_icp_;
  std::deque<Frame> frames_;  // from first_kept_frame_ on
  int first_kept_frame_ = 0;
  std::deque<Factor> factors_;  // in the order of their newest frame
  bool in_episode_ = false;
  // The episode's last contact frames, newest last: whether each one's anchor failed
  // (GraphOptions::lost_after_frames).
  std::deque<bool> recent_anchor_failures_;
};

}  // namespace pg
