// patchgraph: the tracker's command line.
//   patchgraph track DATASET [DATASET...] --method M --normals gt --out OUT
//   patchgraph eval --datasets DIR... --methods M... --out OUT
//   patchgraph train-normals --data DIR... --arch unet|resnet|mlp --out MODEL
//   patchgraph eval-normals --model MODEL --data DIR...
//   patchgraph bench [--quick] --out OUT
// Built twice (tools/CMakeLists.txt): `patchgraph-torch`, the whole program, and
// `patchgraph-core`, without LibTorch (PG_NETWORK_PROGRAM), which runs a command that needs a
// network in the other. The `patchgraph` launcher (launcher.cpp) picks one of the two.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <utility>
#include <vector>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "bench.h"
#include "eval.h"
#include "fit_sensor.h"
#include "label_ball.h"
#include "normals_cli.h"
#include "pg/core/image_change.h"
#include "pg/core/json_fields.h"
#include "recording.h"
#include "sibling.h"
#include "track_args.h"

namespace pg {
namespace {

// The tracker takes the sensor poses as given (a held object's estimate follows the sensor,
// --motion-frame sensor): say so where they jump as no hand moves.
void warn_about_sensor_jumps(const Dataset& dataset) {
  const SensorJumps jumps = sensor_jumps(dataset.poses());
  if (jumps.count == 0) return;
  std::fprintf(stderr,
               "warning: %s: a glitch in %s/poses.csv? The tracker takes the sensor poses as "
               "given\n",
               describe(jumps).c_str(), dataset.dir().c_str());
}

// A folder that holds an earlier track run: its summary.json, a JSON object with a method and
// the errors track writes (what eval's runs hold too).
const EarlierRun kEarlierTrack = {
    "summary.json of an earlier track", [](const std::filesystem::path& folder) {
      try {
        const nlohmann::json j = parse_json_file((folder / "summary.json").string());
        return j.is_object() && j.contains("method") && j.contains("translation_rmse_m");
      } catch (const std::exception&) {
        return false;  // none, or not one
      }
    }};

int run_track(const TrackArgs& a) {
  const NormalsModels models = load_normals_models(a);
  std::vector<Dataset> datasets;
  // One sensor's measurements twice would count double: each folder once, however reached.
  std::map<std::string, std::string> seen;  // canonical folder -> the argument that gave it
  for (const std::string& given : a.datasets) {
    check_output_is_not_input(a.out, given, "the dataset");  // its poses.csv would be replaced
    // A render of several sensors stands for its sensors' datasets, in the scene's order.
    for (Dataset& d : open_sequence(given)) {
      const auto [it, fresh] =
          seen.emplace(std::filesystem::weakly_canonical(d.dir()).string(), given);
      if (!fresh) {
        throw UsageError(d.dir() + ": given twice (" +
                         (it->second == d.dir() ? "also as " : "also through ") + it->second +
                         (given == d.dir() ? ")" : "; this time through " + given + ")"));
      }
      datasets.push_back(std::move(d));
    }
  }
  const std::vector<const Dataset*> sensors = dataset_pointers(datasets);
  // Before the output folder is made.
  check_normals_models(a.normals, models, sensors, a.blend_shading > 0);
  check_same_sequence(sensors);
  const Dataset& dataset = datasets[0];
  const int unpaired_frames = note_missing_frames(sensors);
  const TrackOptions options = make_track_options(a, sensors, models);
  if (dataset.info().scene.empty() && (a.end_effector_noise < 0 || a.vision_noise < 0)) {
    std::fprintf(stderr,
                 "note: %s has no scene (a recording): its poses are taken as measured, without "
                 "simulated noise (--ee-noise, --vision-noise add it)\n",
                 dataset.dir().c_str());
  }
  for (const Dataset& d : datasets) {
    if (a.normals == "gt") continue;
    const bool file = std::filesystem::exists(std::filesystem::path(d.dir()) / "background.png");
    for (const std::string& w :
         reference_warnings(d.background(), file ? d.dir() + "/background.png, the no-contact "
                                                             "reference,"
                                                 : "the no-contact reference of " + d.dir())) {
      std::fprintf(stderr, "warning: %s\n", w.c_str());
    }
    if (file) continue;
    // The network reads each frame minus this reference: a frame wrongly marked without contact
    // would skew every estimate, so the choice is shown.
    const std::vector<int> frames = d.reference_frames();
    if (frames.size() == 1) {
      std::fprintf(
          stderr,
          "note: %s has no background.png: frame %d, the one frame that poses.csv marks as "
          "without contact, is the no-contact reference image (with several, their median "
          "would hold less camera noise)\n",
          d.dir().c_str(), frames[0]);
    } else if (frames.size() > 1) {
      std::fprintf(
          stderr,
          "note: %s has no background.png: the median of %zu frames that poses.csv marks as "
          "without contact (%d to %d) is the no-contact reference image\n",
          d.dir().c_str(), frames.size(), frames.front(), frames.back());
    }
  }
  note_long_batch(a, dataset);
  const OutputFolder out(a.out, kTrackOutputFiles, kEarlierTrack);
  Progress progress("tracking", dataset.frames(), !a.quiet);
  const TrackRun run = [&] {
    try {
      const StopOnSignals stop;
      return track_dataset(sensors, options, [&](int done, int) { progress.update(done); });
    } catch (const Stopped& e) {
      throw e.with_note("nothing written to " + a.out);
    }
  }();
  write_track_outputs(run, sensors, a.out);
  const TrackSummary& s = run.summary;
  std::string names;
  for (const Dataset& d : datasets) names += (names.empty() ? "" : " + ") + d.dir();
  const std::string& object = dataset.info().object_name;
  std::printf("%s on %s%s: %d frames, %d with contact, %d episode(s)\n", s.method.c_str(),
              names.c_str(), object.empty() ? "" : (" (" + object + ")").c_str(), s.frames,
              s.contact_frames, s.episodes);
  std::fflush(stdout);  // the warnings below (stderr) follow this line in a shared log too
  // Which to say: track_warnings' (summary.json's `warnings`), so that the two never differ.
  const std::vector<std::string> warnings = track_warnings(s);
  const auto warned = [&](const char* name) {
    return std::find(warnings.begin(), warnings.end(), name) != warnings.end();
  };
  if (warned("no_contact")) {
    std::fprintf(stderr,
                 "warning: no frame with contact: nothing was registered, the estimate is the "
                 "first pose's prior carried on by the motion priors, and its errors say nothing "
                 "of the tracking (an accuracy gate on this run checks only that prior)\n");
  }
  if (warned("rejected_registrations")) {
    std::fprintf(stderr, "warning: %d registrations were rejected as implausible jumps\n",
                 s.rejected_registrations);
  }
  if (warned("lost_frames")) {
    std::fprintf(stderr, "warning: tracking was reported lost in %d frame(s) (errors.csv)\n",
                 s.lost_frames);
  }
  // The registrations hardly ever count (too few points or matches, or --config's iteration
  // limit or convergence thresholds), so the track is the motion priors'.
  if (warned("unconverged_registrations")) {
    std::fprintf(stderr,
                 "warning: %d registrations did not converge in %d contact frames (up to two "
                 "per frame and sensor: image-to-image and image-to-patch); those frames "
                 "follow the motion priors (errors.csv: unconverged_registrations; --config's "
                 "icp.max_iterations and convergence thresholds)\n",
                 s.unconverged_registrations, s.contact_frames);
  }
  // No registration got as far as its analysis (a contact or patch smaller than icp.min_points,
  // too few matches): the frame's pose is the motion priors' prediction alone. Counted as lost
  // only when a registration was tried and failed, so said here (it had been a note among the
  // flat patches' free directions).
  const int unregistered = s.unconstrained_direction_frames[6];
  if (warned("unregistered_frames")) {
    std::fprintf(stderr,
                 "warning: in %d of %d contact frames no registration held the pose (the contact "
                 "cloud or the patch smaller than --config's icp.min_points, or too few matches "
                 "within icp.max_correspondence_m): those poses are the motion priors' "
                 "predictions alone (errors.csv: unconstrained_directions 6)\n",
                 unregistered, s.contact_frames);
  }
  if (warned("contact_not_found")) {
    std::fprintf(stderr,
                 "warning: the dataset marks %d frame(s) as in contact, the tracker found contact "
                 "in %d (the contact mask's settings, mask.* in --config, or the normals)\n",
                 s.marked_contact_frames, s.contact_frames);
  }
  if (warned("sensor_pose_jumps")) {
    for (const Dataset& d : datasets) warn_about_sensor_jumps(d);
  }
  if (warned("overridden_registrations")) {
    std::fprintf(stderr,
                 "warning: the solved poses overrode %d accepted registration(s): the motion "
                 "priors outweighed them (errors.csv: overridden_registrations)\n",
                 s.overridden_registrations);
  }
  if (warned("rejected_normals")) {
    std::fprintf(stderr,
                 "warning: %d frame(s) had unusable normal pixels (non-finite, not unit length "
                 "or facing the camera; a dropped colour frame counts all of its pixels) "
                 "(errors.csv: rejected_normals)\n",
                 s.rejected_normal_frames);
  }
  if (warned("reference_mismatch")) {
    std::fprintf(stderr,
                 "warning: in %d frame(s) more than half of the image differs from the "
                 "no-contact reference, more than a press changes: the lighting changed or the "
                 "camera moved since it was taken? The network reads that as contact everywhere "
                 "(errors.csv: reference_mismatch)\n",
                 s.reference_mismatch_frames);
  }
  if (warned("disagreeing_registrations")) {
    std::fprintf(stderr,
                 "warning: in %d of %d frames the image-to-image and image-to-patch "
                 "registrations turned the object more than %.0f mrad apart: the contact shows "
                 "its rotation poorly (a sharp vertex, a small or rolling contact), and the "
                 "rotation, with the position of what lies far from the contact, may be off by "
                 "as much or more (summary.json: disagreeing_registration_frames)\n",
                 s.disagreeing_registration_frames, s.two_registration_frames,
                 kDisagreeingRegistrationsRad * 1e3);
  }
  if (warned("saturated")) {
    const bool estimated = s.normals != "gt";  // the depth is then the normals' integral
    std::fprintf(stderr,
                 "warning: in %d frame(s) the contact reached the gel's maximum indentation "
                 "(%.2f mm, the dataset's sensor gel.max_indentation_m)%s: the object pressed "
                 "further than the gel can show, its shape there is cut flat, and those frames' "
                 "registrations see a plateau, not the object%s\n",
                 s.saturated_frames, dataset.info().sensor.gel.max_indentation_m * 1e3,
                 estimated ? " in the depth integrated from the estimated normals" : "",
                 estimated ? "; or the estimated normals overstate the contact's slopes and so "
                             "its depth (compare with the press you expect)"
                           : "");
  }
  if (warned("invalid_input")) {
    std::fprintf(stderr,
                 "warning: %d frame(s) had a non-finite sensor pose, vision prior or point, or "
                 "an image too corrupt to tell whether the object touches (unusable normals, or "
                 "a uniform colour frame: a camera dropout)%s; left out, an episode in progress "
                 "continued (errors.csv: invalid_input)\n",
                 s.invalid_input_frames,
                 unpaired_frames > 0 ? ", or a sensor without a frame at that time (above)" : "");
  }
  if (s.degenerate_frames > 0) {
    // How many directions were free, frame by frame: an edge's slide alone (1) tracks, its turn
    // free as well (2) in many frames is how a shallow cube edge drifts off (docs/tracker.md).
    std::string counts;
    for (int n = 1; n <= 6; ++n) {
      const int frames = s.unconstrained_direction_frames[std::size_t(n)];
      if (frames == 0) continue;
      counts += counts.empty() ? std::to_string(n) +
                                     (n == 1 ? " free direction in " : " free directions in ") +
                                     std::to_string(frames) + " frames"
                               : ", " + std::to_string(n) + " in " + std::to_string(frames);
    }
    // A turn left free in more than a quarter of the contact frames is a warning
    // ("turn_unseen"), the rest a note.
    const bool drift = warned("turn_unseen");
    std::fprintf(stderr,
                 "%s: in %d of %d contact frames the contact did not constrain every direction "
                 "of the pose (%s; a flat, cylindrical or spherical patch, or a contact too small "
                 "to register: all 6); the estimate follows the motion prior along those "
                 "(errors.csv: unconstrained_directions)",
                 drift ? "warning" : "note", s.degenerate_frames, s.contact_frames, counts.c_str());
    if (drift) {
      std::fprintf(stderr,
                   "; in %d of them two or more were free, a turn among them (about an edge's "
                   "or a cylinder's axis, a flat face's spin, a sphere's rotations): the "
                   "rotation can drift with no registration failing or frame reported lost",
                   turn_unseen_frames(s));
    }
    std::fprintf(stderr, "\n");
  }
  if (warned("coarse_pixels")) {
    std::fprintf(stderr,
                 "warning: the sensor's pixels are %.2f mm on the gel, coarser than the %.2f mm "
                 "the tracker's settings were made for (the DIGIT's are 0.16 mm at 120x160): a "
                 "contact's rims and edges fall between too few pixels, and the rotation can be "
                 "several times worse than at 120x160 with nothing else warned of "
                 "(docs/tracker.md, \"Other resolutions\"; summary.json: coarsest_pixel_m)\n",
                 s.coarsest_pixel_m * 1e3, kCoarsePixelM * 1e3);
  }
  if (s.object_frame != "dataset") {
    std::fprintf(
        stderr,
        "note: the dataset has no object poses; poses.csv gives the object's motion with its "
        "frame placed at the sensor's frame at frame 0, and there are no errors to report\n");
  }
  if (std::isfinite(s.final_translation_error_m)) {
    std::printf("final error     %.3f mm  %.4f rad\n", s.final_translation_error_m * 1e3,
                s.final_rotation_error_rad);
  } else if (s.ground_truth_frames > 0) {
    std::printf("final error     none: the dataset has no object pose at the last frame\n");
  }
  if (s.ground_truth_frames > 0) {
    std::printf("RMSE            %.3f mm  %.4f rad", s.translation_rmse_m * 1e3,
                s.rotation_rmse_rad);
    if (s.ground_truth_frames < s.frames) {
      std::printf(" (over the %d of %d frames with an object pose)", s.ground_truth_frames,
                  s.frames);
    }
    std::printf("\n");
  }
  if (s.window_vs_batch_translation_rms_m >= 0) {
    if (std::isfinite(s.batch_translation_rmse_m)) {
      std::printf("batch RMSE      %.3f mm  %.4f rad; ", s.batch_translation_rmse_m * 1e3,
                  s.batch_rotation_rmse_rad);
    }
    std::printf("fixed-lag vs batch RMS %.4f mm  %.5f rad\n",
                s.window_vs_batch_translation_rms_m * 1e3, s.window_vs_batch_rotation_rms_rad);
  }
  std::printf("per-frame update median %.3f ms (%.0f Hz), mean %.3f ms -> %s\n", s.median_frame_ms,
              s.hz, s.mean_frame_ms, a.out.c_str());
  if (s.normals != "gt") {
    std::printf("of which normals from the %s: median %.3f ms\n",
                s.normals == kShadingNormals ? "shading's inverse" : "model", s.median_normals_ms);
  }
  // (More than 1000 / the update's ms when the next frame's images and model run beside it.)
  std::printf("whole run       %.3g frames/s (reading the images included; %s)\n", s.throughput_fps,
              a.no_prefetch ? "one frame after the other"
                            : "each frame read beside the update of the one before");
  std::fflush(stdout);
  if (!within_accuracy_gate(a, names, s.final_translation_error_m, s.final_rotation_error_rad)) {
    return kExitAccuracy;
  }
  return kExitOk;
}

}  // namespace
}  // namespace pg

int main(int argc, char** argv) {
  using namespace pg;
  CLI::App app{"patchgraph: in-hand object tracking from tactile images (PatchGraph)"};
  app.require_subcommand(1);

  TrackArgs track;
  CLI::App* cmd_track = app.add_subcommand(
      "track", "Track the object of one dataset (or of several sensors' datasets together)");
  cmd_track
      ->add_option("dataset", track.datasets,
                   "Dataset folder (from tacsim render); several, or a render of several "
                   "sensors: the sensors of one sequence on one object, tracked together (the "
                   "first is the primary)")
      ->required();
  cmd_track->add_option("--out,-o", track.out, "Output folder")->required();
  add_track_options(*cmd_track, track);
  cmd_track->add_flag("--quiet,-q", track.quiet, "No progress line");

  EvalArgs eval;
  CLI::App* cmd_eval =
      app.add_subcommand("eval", "Run methods x datasets and summarise the errors");
  cmd_eval
      ->add_option("--datasets", eval.datasets,
                   "Dataset folders (a render of several sensors: its sensors together), "
                   "or folders of them")
      ->required();
  cmd_eval->add_option("--methods", eval.methods, "Methods (default: all four)")
      ->check(CLI::IsMember(method_names()));
  cmd_eval->add_option("--out,-o", eval.out, "Output folder")->required();
  add_track_options(*cmd_eval, eval.track, /*with_method=*/false);
  cmd_eval
      ->add_option("--seeds", eval.seeds,
                   "Several noise seeds instead of --seed: every dataset and method runs once "
                   "with each (runs/<name>_<method>_seed<S>), summary.md gives the medians over "
                   "all of them and seed by seed")
      ->check(kSeed)
      ->excludes("--seed");
  cmd_eval
      ->add_option("--jobs,-j", eval.jobs,
                   "Runs tracked at once (default 1; 0: one per core). The errors are the same "
                   "bits; the update times (median update, Hz) then share the cores and read "
                   "slower, so time a method with 1")
      ->check(kThreads);
  cmd_eval->add_flag("--resume", eval.resume,
                     "Keep the runs that an earlier eval into --out finished with the same "
                     "settings (their summary.json) and track only the others: an eval stopped "
                     "part-way, or one given more datasets, methods or seeds");
  cmd_eval->add_flag("--no-plots,--no-plot", eval.no_plots, "Skip the matplotlib plots");
  cmd_eval->add_flag("--quiet,-q", eval.track.quiet, "No progress lines");

  TrackBenchArgs bench;
  CLI::App* cmd_bench = app.add_subcommand(
      "bench", "Run time against error over the tracker's knobs (docs/benchmarks.md)");
  cmd_bench->add_option("--out,-o", bench.out, "Output folder (bench.csv, bench.md, bench.png)");
  cmd_bench->add_option("--scenes", bench.scenes,
                        "Scene files (default: benchmark 00-02 per object)");
  cmd_bench->add_option("--cache", bench.cache, "Rendered datasets, reused (default: OUT/cache)");
  cmd_bench->add_option("--normals", bench.normals,
                        "Normals sources, one row each: gt, shading, MODEL, or MODEL+shading:W "
                        "(track's --normals MODEL --blend-shading W) (default: gt)");
  // Fewer frames time the first updates alone and end every setting at the first pose's prior.
  cmd_bench
      ->add_option("--frames", bench.frames,
                   "Frames per scene, at least 10 (default: all; --quick: 60)")
      ->check(at_least(10));
  cmd_bench->add_option("--threads", bench.threads, "Threads (default: all cores)")
      ->check(kThreads);
  cmd_bench->add_flag("--quick", bench.quick, "2 scenes x 60 frames, 6 settings (smoke test)");
  cmd_bench->add_flag("--no-plot,--no-plots", bench.no_plot, "Skip the matplotlib plot");
  cmd_bench->add_flag("--quiet,-q", bench.quiet, "No progress lines");

  TrainNormalsArgs train_normals_args;
  CLI::App* cmd_train_normals = add_train_normals_command(app, train_normals_args);
  EvalNormalsArgs eval_normals_args;
  CLI::App* cmd_eval_normals = add_eval_normals_command(app, eval_normals_args);
  ModelInfoArgs model_info_args;
  CLI::App* cmd_model_info = add_model_info_command(app, model_info_args);
  RecordingArgs recording_args;
  CLI::App* cmd_recording = add_recording_command(app, recording_args);
  LabelBallArgs label_ball_args;
  CLI::App* cmd_label_ball = add_label_ball_command(app, label_ball_args);
  FitSensorArgs fit_sensor_args;
  CLI::App* cmd_fit_sensor = add_fit_sensor_command(app, fit_sensor_args);

  return run_cli(app, argc, argv, [&]() -> int {
#ifdef PG_NETWORK_PROGRAM
    const std::string command = app.get_subcommands().front()->get_name();
    if (is_network_command(command) || (cmd_track->parsed() && names_a_model(track.normals)) ||
        (cmd_eval->parsed() && names_a_model(eval.track.normals)) ||
        (cmd_bench->parsed() &&
         std::any_of(bench.normals.begin(), bench.normals.end(), names_a_model))) {
      // The launcher's reading of the words missed it (or this program was run directly).
      throw InputError(exec_sibling(PG_NETWORK_PROGRAM, argv));
    }
#endif
    if (cmd_train_normals->parsed()) {
      for (const char* option :
           {"--l1-weight", "--gan-weight", "--depth", "--width", "--hidden", "--contact-weight",
            "--shift", "--gain-jitter", "--offset-jitter", "--noise-augment"}) {
        if (cmd_train_normals->count(option) > 0)
          train_normals_args.options.given.push_back(option);
      }
      return run_train_normals(train_normals_args);
    }
    if (cmd_eval_normals->parsed()) return run_eval_normals(eval_normals_args);
    if (cmd_model_info->parsed()) return run_model_info(model_info_args);
    if (cmd_recording->parsed()) return run_recording(recording_args);
    if (cmd_label_ball->parsed()) return run_label_ball(label_ball_args);
    if (cmd_fit_sensor->parsed()) return run_fit_sensor(fit_sensor_args);
    if (cmd_bench->parsed()) return run_track_bench(bench);
    if (cmd_track->parsed()) return run_track(track);
    if (cmd_eval->parsed()) return run_eval(eval);
    return kExitUsage;
  });
}
