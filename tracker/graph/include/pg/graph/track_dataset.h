#pragma once
// Tracking a rendered (or recorded) dataset end to end: normals -> contact cloud -> PatchGraph,
// with the paper's simulated measurement noise, and the errors against ground truth.
#include <array>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "pg/core/dataset.h"
#include "pg/graph/tracker.h"
#include "pg/tracker/tracker_config.h"

namespace pg {

// Simulated pose noise above this sigma (1 m, 1 rad: a pose anywhere) is refused.
inline constexpr double kMaxPoseNoise = 1.0;

// Frames that one run has prepared (its images decoded and, with learned normals, read by the
// model), kept for later runs of the same datasets with the same normals source: eval's other
// methods and seeds, which then neither decode nor run the model again. Safe for runs on several
// threads at once; a frame prepared by two of them at the same time is kept once (the same either
// way). A run of other datasets or another normals_name than the first run's is refused
// (std::logic_error): the cache belongs to one sequence and source. Whatever shapes the normals
// should be in normals_name (patchgraph's names a model's phases and blend); anything that is
// not is the caller's to keep the same.
class PreparedFrames;
std::shared_ptr<PreparedFrames> make_prepared_frames();

struct TrackOptions {
  GraphOptions graph;
  TrackerConfig front_end;  // depth, mask and ICP options (the ICP options go to graph.icp)
  // Simulated measurement noise (paper eq. 8 and 9): sensor poses e~ = e exp(N(0, s^2 I)) and
  // the vision prior o~ = o exp(N(0, s^2 I)), seeded. Units [m] and [rad] alike; from 0 to
  // kMaxPoseNoise (track_dataset throws InputError otherwise).
  double end_effector_noise = 1e-5;
  double vision_noise = 1e-4;
  std::uint64_t seed = 0;
  // The known object's surface points with normals (object frame), built as a tree, for the
  // GroundtruthPatch baseline; one tree may serve every run of the object (eval's do).
  std::shared_ptr<const PointCloudTree> model_object;
  // After tracking, re-solve the whole sequence with every factor (the batch reference) and
  // report how far the fixed-lag estimates are from it (over the frames the tracker kept, with
  // graph.history_frames).
  bool compare_batch = false;
  // Where the normals come from: null = the dataset's ground-truth normal images ("gt"); else a
  // function of the sensor (its dataset's index in track_dataset's list: each sensor may have
  // its own model), the frame's colour image and that dataset's no-contact reference image
  // (Dataset::background; a learned model), timed as part of the frame.
  std::function<ImageF(std::size_t sensor, const ImageU8& color, const ImageU8& reference)> normals;
  std::string normals_name = "gt";  // for the summary (with a model per sensor, their list)
  // The model files' digests (file_digest), in normals_name's order, joined with commas; empty
  // for ground-truth normals and the shading's inverse. summary.json records it and eval
  // --resume compares it: a model trained again into the same file is another source.
  std::string normals_digest;
  // Decode the next frame's images, and read them with `normals`, on a second thread while the
  // tracker updates with this frame's (`normals` is then called from that thread, one call at a
  // time); false: all on the calling thread, one frame after the other. The same results either
  // way.
  bool prefetch = true;
  // Null: every frame prepared by this run. Else frames already there are taken from it (with the
  // model's time, measured when it ran, still counted in the update's) and new ones kept in it.
  std::shared_ptr<PreparedFrames> prepared_frames;
};

struct FrameResult {
  int frame = 0;
  SE3 T_world_object;              // estimated, as it was right after this frame's update
  SE3 T_world_object_gt;           // ground truth, where the dataset has it
  bool ground_truth = true;        // false: the dataset has no object pose at this frame
  double translation_error_m = 0;  // NaN without ground truth
  double rotation_error_rad = 0;
  bool contact = false;     // the frame's cloud was used (any sensor's)
  int contact_sensors = 0;  // how many sensors touched
  bool new_episode = false;
  bool image_to_patch = false;
  bool image_to_image_dropped = false;       // TrackerEstimate::image_to_image_dropped
  double registration_disagreement_rad = 0;  // TrackerEstimate's (NaN: not both registrations)
  int rejected_registrations = 0;
  int unconverged_registrations = 0;  // TrackerEstimate's counts, per frame
  int overridden_registrations = 0;
  // A non-finite sensor pose, prior or point was left out, or the frame was unreadable
  // (TrackerInput::measurement_missing).
  bool invalid_input = false;
  // Normal pixels rejected as unusable (ContactFrame::rejected_normals: non-finite, far from
  // unit length, or facing the camera; every pixel of a dropped colour frame); 0 when clean.
  int rejected_normals = 0;
  // Learned normals only: more than half of a colour frame differs from its no-contact reference
  // (pg/core/image_change.h), more than any press changes: the lighting changed or the camera
  // moved since the reference was taken, which the network reads as contact everywhere.
  bool reference_mismatch = false;
  // A sensor's contact reached its gel's maximum indentation (the mask's deepest, a 98th
  // percentile, at 98 % of gel.max_indentation_m or more): pressed further than the gel can
  // show, the contact's shape is cut flat there.
  bool saturated = false;
  bool tracking_lost = false;  // the tracker's own report (TrackerEstimate::tracking_lost)
  // Directions of the pose the image-to-patch registration could not see (0-6; a flat face 3, a
  // sphere 3, a rounded edge 2): the estimate follows the motion prior along them.
  int unconstrained_directions = 0;
  // Points of the frame's contact cloud (0 without contact; every sensor's together), and whether
  // they are the contact's core only (ContactFrame::core: the pixels deeper than
  // mask.core_relative_depth of the deepest; with several sensors, every touching one's).
  int contact_points = 0;
  bool contact_core = false;
  // Normals -> cloud -> registrations -> graph update (image decoding excluded; the model's
  // part timed on the thread that ran it, TrackOptions::prefetch).
  double frame_ms = 0;
  double normals_ms = 0;  // of which estimating the normals (0 for ground-truth normals)
};

// Two registrations of one frame turning the object further apart than this disagree
// (TrackSummary::disagreeing_registration_frames): 10 mrad, beyond the benchmark's 99th
// percentile on the cube and the toy brick (6.8 and 4.5 mrad; the toy human 27).
constexpr double kDisagreeingRegistrationsRad = 0.01;

// A sensor whose pixels are larger than this on the gel (at its centre) is coarser than the
// tracker's settings were made for (TrackSummary::coarsest_pixel_m, the warning
// "coarse_pixels"): 0.25 mm, between the DIGIT's 0.16 mm at 120x160, where the benchmark runs,
// and its 0.32 mm at 60x80 (docs/tracker.md, "Other resolutions").
constexpr double kCoarsePixelM = 0.25e-3;

struct TrackSummary {
  std::string method;
  std::uint64_t seed = 0;  // of the simulated sensor-pose and vision-prior noise
  int frames = 0;
  int sensors = 1;  // datasets tracked together
  // Where the object's frame comes from: "dataset" (the vision prior at frame 0) or "sensor at
  // frame 0" (a recording without object poses: poses are relative to the sensor's start).
  std::string object_frame = "dataset";
  int ground_truth_frames = 0;  // frames with the object's pose in the dataset
  int contact_frames = 0;
  int episodes = 0;
  int rejected_registrations = 0;  // implausible registrations dropped (a tracking warning)
  int lost_frames = 0;             // frames the tracker reported tracking as lost
  // Registrations that did not converge (too few points or matches, the iteration limit), and
  // accepted ones the solved poses then disagreed with (the priors outweighed them; see
  // GraphOptions::max_registration_residual_m), both tracking warnings.
  int unconverged_registrations = 0;
  int overridden_registrations = 0;
  int invalid_input_frames = 0;       // frames with a non-finite or missing input left out
  int rejected_normal_frames = 0;     // frames with any rejected normal pixel
  int reference_mismatch_frames = 0;  // frames with FrameResult::reference_mismatch
  int saturated_frames = 0;           // frames with FrameResult::saturated
  // Frames where both registrations of a sensor held, and those of them whose two answers turned
  // the object more than kDisagreeingRegistrationsRad apart (FrameResult::
  // registration_disagreement_rad): where the contact shows its rotation poorly.
  int two_registration_frames = 0;
  int disagreeing_registration_frames = 0;
  // Frames whose image-to-image factor was left out for disagreeing with the image-to-patch one.
  int image_to_image_dropped = 0;
  // Contact frames whose image-to-patch registration left a direction unconstrained: where the
  // touch alone cannot tell the pose (a sphere's rotation, an edge's slide), a tracking warning.
  int degenerate_frames = 0;
  // Contact frames by how many directions their image-to-patch registration left unconstrained
  // (0 to 6; a frame past an episode's first where it never got that far, too small to register,
  // counts as 6; ImageToImage's and ConstVel's frames as 0): a sphere's three rotations, an edge's
  // slide (1) or its slide and turn (2, where the estimate follows only the motion priors).
  std::array<int, 7> unconstrained_direction_frames{};
  // Frames some dataset's poses.csv marks as in contact (its `contact` column), and the sensor
  // pose jumps in the datasets' poses (sensor_jumps), for track_warnings.
  int marked_contact_frames = 0;
  int sensor_pose_jumps = 0;
  // The largest of the sensors' pixels on the gel, at its centre [m] (for the warning
  // "coarse_pixels", kCoarsePixelM).
  double coarsest_pixel_m = 0;
  // Errors against ground truth: RMSE over the frames that have it, final = the last frame's;
  // NaN where there is none.
  double translation_rmse_m = 0;
  double rotation_rmse_rad = 0;
  double final_translation_error_m = 0;
  double final_rotation_error_rad = 0;
  double mean_frame_ms = 0;
  double median_frame_ms = 0;
  double hz = 0;  // 1000 / median_frame_ms
  // Frames per second of the whole loop: decoding the images, the normals and the update (the
  // next frame's decoding and model overlapped with this one's update, TrackOptions::prefetch).
  double throughput_fps = 0;
  std::string normals = "gt";
  std::string normals_digest;  // TrackOptions::normals_digest
  double median_normals_ms = 0;
  // The settings the run used beyond the graph's own (PatchGraphTracker::options()): the front
  // end's depth, mask and ICP options (what --config takes) and the simulated pose noise.
  TrackerConfig front_end;
  double end_effector_noise = 0, vision_noise = 0;
  // With compare_batch: the batch solution's errors against ground truth, and the RMS distance
  // between the fixed-lag and the batch trajectories (-1 when not compared).
  double batch_translation_rmse_m = -1, batch_rotation_rmse_rad = -1;
  double window_vs_batch_translation_rms_m = -1, window_vs_batch_rotation_rms_rad = -1;
};

struct TrackRun {
  std::vector<FrameResult> frames;
  TrackSummary summary;
  std::unique_ptr<PatchGraphTracker> tracker;
};

// Sets what tracking normals estimated from colour images (a network's, the shading's inverse)
// needs instead of rendered ones (`patchgraph track --normals MODEL|shading` does the same; each
// measured in docs/learned_normals.md): a contact mask of the pixels deeper than a fifth of the
// frame's deepest, the ICP's residual along the target's normal alone, the averaged integration,
// three free directions rolling about a centre beyond 2 cm read as a flat face's, and no
// image-to-image gate. A program tracking a live sensor calls it once on its options.
void use_estimated_normals(TrackOptions& options);

// The graph's options as a tracker of `options` runs with them: options.graph with the front
// end's ICP options (TrackOptions::front_end), which its registrations use.
GraphOptions tracker_graph_options(const TrackOptions& options);

// Where the object's frame comes from: the pose at frame 0 (false), or, in a recording with no
// object pose at all, the sensor's frame at frame 0 (true). Poses that begin after frame 0 cannot
// start a track consistently: InputError naming `poses_csv`.
bool object_frame_is_sensor(const std::vector<FramePose>& poses, const std::string& poses_csv);

// Reads the dataset's normal images ("gt" normals), or its colour images through
// options.normals, frame by frame. Throws InputError when the dataset lacks that output or a
// frame is unreadable.
TrackRun track_dataset(const Dataset& dataset, const TrackOptions& options,
                       const std::function<void(int, int)>& progress = nullptr);
// The same for several sensors touching one object in one sequence (a scene with several
// sensors renders a dataset for each), tracked together (TrackerInput::other_sensors): the first
// is the primary (its sensor pose and poses.csv columns are the outputs'; the motion frame is the
// carrying sensor's, TrackerInput::other_sensors). The ground truth and vision prior are the
// object poses of sequence_poses(); check_same_sequence() must hold. Frames are the primary's:
// each other sensor gives its frame at that time (sequence_frames), and where it has none its
// measurement is missing there (SensorInput::measurement_missing: an invalid input, its pose
// interpolated, sensor_pose_at).
TrackRun track_dataset(const std::vector<const Dataset*>& datasets, const TrackOptions& options,
                       const std::function<void(int, int)>& progress = nullptr);

// Throws InputError naming the dataset unless it holds the images tracking reads: its normal
// images for `normals` "gt", else its colour images for the model `normals` names.
void check_normals_source(const Dataset& dataset, const std::string& normals);
// Each sensor's frame at each of the primary's (datasets[0]'s) frames: frames[k][i] is sensor
// k's frame taken at the time of the primary's frame i, within half of the primary's frame (the
// rates may differ), or -1 where it has none (its camera started later, stopped earlier, dropped
// a frame or runs slower; two cameras' clocks may disagree a little). Each frame is taken once
// and in time order, by the primary's frame it is nearest to, and the nearest of those near one
// frame. frames[0][i] = i; datasets of as many frames all within half a frame of each other's
// (sensors rendered together) pair i with i.
std::vector<std::vector<int>> sequence_frames(const std::vector<const Dataset*>& datasets);
// Throws InputError (naming the file, line or field) unless `datasets` (one per sensor) can be
// tracked together: some frames at the same times (sequence_frames) and the same object pose at
// the primary's times wherever two give one (object_pose_at): 1e-6 m, 1e-5 rad apart at a frame's
// own time, and the motion between the two frames more where interpolated.
void check_same_sequence(const std::vector<const Dataset*>& datasets);
// The first dataset's poses, with the object's pose taken from another dataset at that time
// (object_pose_at, where that one has a frame then: sequence_frames) where the first gives none:
// the sequence's ground truth and vision prior.
std::vector<FramePose> sequence_poses(const std::vector<const Dataset*>& datasets);
// A dataset's poses at `time_s`: a frame's own at its time (`frame`'s, the one paired with that
// time, where it is stamped then: a coarse clock may stamp two alike), else interpolated between
// the frames around it (linear, slerp). The object's only where both frames give it (nullopt
// else, and outside the frames); the sensor's the first or last frame's outside them.
std::optional<SE3> object_pose_at(const std::vector<FramePose>& poses, double time_s,
                                  int frame = -1);
SE3 sensor_pose_at(const std::vector<FramePose>& poses, double time_s, int frame = -1);

// The summary of per-frame results (RMSE over the frames with ground truth, final = last frame).
TrackSummary summarize(const std::vector<FrameResult>& frames, const std::string& method);

// Contact frames whose image-to-patch registration left two to five directions free, a turn
// among them (an edge's or a cylinder's turn about its axis beside the slide, a flat face's spin,
// a sphere's rotations; six is no registration at all).
int turn_unseen_frames(const TrackSummary& s);

// What a run's summary warns of, by name, in the order `patchgraph track` says it: summary.json's
// `warnings`, for a pipeline to check without reading the messages (docs/outputs.md):
// "no_contact", "rejected_registrations", "lost_frames", "unconverged_registrations" (more than
// half the contact frames), "unregistered_frames" (no registration held the pose in more than
// half), "contact_not_found" (in fewer than half the frames the datasets mark as in contact),
// "sensor_pose_jumps", "overridden_registrations", "rejected_normals", "reference_mismatch",
// "disagreeing_registrations" (in more than a quarter of the frames where both held, at least
// 10), "saturated", "invalid_input", "turn_unseen" (two to five free directions in more than a
// quarter of the contact frames: the rotation can drift with nothing failing), "coarse_pixels"
// (a sensor's pixels larger than kCoarsePixelM on the gel).
std::vector<std::string> track_warnings(const TrackSummary& s);

// OUT/poses.csv (the dataset's pose columns, estimated; the primary's with several sensors),
// OUT/errors.csv, OUT/summary.json, OUT/patch.ply (every sensor's patch, object frame), the
// files kTrackOutputFiles names. Throws InputError naming the path.
inline const std::vector<std::string> kTrackOutputFiles = {"poses.csv", "errors.csv",
                                                           "summary.json", "patch.ply"};
void write_track_outputs(const TrackRun& run, const std::vector<const Dataset*>& datasets,
                         const std::string& out_dir);
void write_track_outputs(const TrackRun& run, const Dataset& dataset, const std::string& out_dir);

// A run's outputs that an earlier run left in out_dir (eval --resume): when every file of
// kTrackOutputFiles is there and its summary.json records the settings that a run of `datasets`
// with `options` would record (the datasets, method, seed, normals source, the graph's and the
// front end's options and the noise; with compare_batch, the batch's results), the summary and
// the warnings it records; else none (a summary.json that does not parse too). The normals
// source is compared by its name and its model files' digest (TrackOptions::normals_name and
// normals_digest).
struct KeptRun {
  TrackSummary summary;  // as written (marked_contact_frames and sensor_pose_jumps are not)
  std::vector<std::string> warnings;
};
std::optional<KeptRun> kept_track_run(const std::vector<const Dataset*>& datasets,
                                      const TrackOptions& options, const std::string& out_dir);

}  // namespace pg
