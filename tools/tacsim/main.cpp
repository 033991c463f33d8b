// tacsim: the tactile renderer's command line.
//   tacsim render SCENE --out DIR   render a scene into the dataset format
//   tacsim info DIR                 describe a dataset
//   tacsim bench                    the renderer's speed benchmark
//   tacsim sheet SCENES --out PNG   a contact sheet of one frame per scene
//   tacsim presses MESH --out SCENE a scene of random presses (learned normals' training data)
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "bench.h"
#include "pg/core/dataset.h"
#include "pg/core/file_io.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image_change.h"
#include "pg/core/memory.h"
#include "pg/sim/scene_renderer.h"
#include "presses.h"
#include "sensitivity.h"
#include "sheet.h"

namespace pg {
namespace {

// The comma-separated names of `s`; an empty name (",," or a comma at either end: a shell
// variable left unset, say) is a usage error naming `what`.
std::vector<std::string> split_list(const std::string& s, const std::string& what) {
  const std::vector<std::string> out = comma_items(s);
  if (std::find(out.begin(), out.end(), "") != out.end()) {
    throw UsageError(what + " " + s + ": an empty name in the list");
  }
  return out;
}

struct RenderArgs {
  std::string scene, out, outputs, background, shadows, elastic, noise;
  int threads = 0, width = 0, height = 0, frames = 0;
  bool quiet = false;
  bool outputs_given = false;  // --outputs was on the command line (perhaps empty)
};

std::optional<bool> on_off(const std::string& value) {
  if (value.empty()) return std::nullopt;
  return value == "on";
}

// A mesh of millimetres read as metres (a thousand times too large: the sensor ends up inside
// it) or the other way round (a speck no pixel shows) renders without an error, so it is said,
// as `tacsim presses` says it of its mesh.
void warn_about_object_sizes(const SceneRenderer& renderer) {
  const Scene& scene = renderer.scene();
  double pixel = std::numeric_limits<double>::infinity();  // the finest sensor's, on its gel
  for (const SceneSensor& s : scene.sensors) {
    pixel = std::min(pixel, s.model.gel.width_m / s.model.camera.width);
  }
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    const Bounds3& b = renderer.object_shape(int(i)).bounds();
    const Eigen::Vector3d extent = (b.max - b.min).cast<double>();
    const double size = extent.maxCoeff();
    if (size <= 1.0 && size >= 2 * pixel) continue;
    const SceneObject& o = scene.objects[i];
    std::fprintf(stderr,
                 "warning: %s: objects[%zu] ('%s'): %s is %s x %s x %s mm at scale %s, %s; is "
                 "its scale right (meshes are in metres: \"scale\": 0.001 for millimetres)?\n",
                 scene.path.c_str(), i, o.name.c_str(), o.mesh_path.c_str(),
                 format_number(1e3 * extent.x(), "%.4g").c_str(),
                 format_number(1e3 * extent.y(), "%.4g").c_str(),
                 format_number(1e3 * extent.z(), "%.4g").c_str(), format_number(o.scale).c_str(),
                 size > 1.0 ? "larger than a metre" : "smaller than two of the sensor's pixels");
  }
}

int run_render(const RenderArgs& a) {
  if (a.out.empty()) throw InputError("--out: empty; give the dataset's folder");
  keep_freed_memory();  // each frame's image buffers, reused (at 480x640 the page faults were a
                        // quarter of the run)
  RenderOverrides overrides;
  overrides.outputs = split_list(a.outputs, "--outputs");
  if (a.outputs_given) as_usage_error([&] { check_output_names(overrides.outputs, "--outputs"); });
  overrides.width = a.width;
  overrides.height = a.height;
  overrides.background = a.background;
  overrides.shadows = on_off(a.shadows);
  overrides.frames = a.frames;
  overrides.elastic = on_off(a.elastic);
  overrides.noise = on_off(a.noise);
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0) {
    threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
                                                    a.threads);
  }
  Scene scene = load_scene(a.scene);
  if (a.frames > scene.frames) {
    throw UsageError("--frames " + std::to_string(a.frames) + ": " + a.scene + " has " +
                     std::to_string(scene.frames) + " frames");
  }
  if (a.frames == 0 && scene.motion_frames > scene.frames) {  // a frames left as it was
    std::fprintf(stderr,
                 "warning: %s gives %lld frames of motion, the scene's frames %d: the render "
                 "stops at frame %d, and the rest is never rendered\n",
                 scene.motion_field.c_str(), static_cast<long long>(scene.motion_frames),
                 scene.frames, scene.frames - 1);
  }
  // --width and --height resize each camera's intrinsics per side: another shape of image
  // than a sensor's stretches its pixels (a sensor file says so as an error; here the scene's
  // sensors may be of several shapes).
  for (const SceneSensor& sensor : scene.sensors) {
    const CameraModel& cam = sensor.model.camera;
    if (a.width <= 0 || a.width * cam.height == a.height * cam.width) continue;
    const CameraModel resized = cam.resized(a.width, a.height);
    std::fprintf(stderr,
                 "warning: --width %d --height %d: sensor %s is %dx%d px, another shape; its "
                 "pixels become %.3g times as wide as tall (a sensor file with the new image's "
                 "camera keeps them square)\n",
                 a.width, a.height, sensor.name.c_str(), cam.width, cam.height,
                 (resized.fy / resized.fx) / (cam.fy / cam.fx));
  }
  const SceneRenderer renderer(std::move(scene), overrides);
  warn_about_object_sizes(renderer);
  Progress progress("rendering", renderer.scene().frames, !a.quiet);
  const RenderSummary s = [&] {
    try {
      const StopOnSignals stop;
      return render_scene_to_dataset(renderer, a.out,
                                     [&](int done, int) { progress.update(done); });
    } catch (const Stopped& e) {
      throw e.with_note(unfinished_dataset_note(a.out, "render"));
    }
  }();
  // Each sensor's image size ("120x160", or "120x160 + 240x320" for sensors of two sizes).
  std::vector<std::string> seen;
  std::string sizes;
  for (int k = 0; k < renderer.sensor_count(); ++k) {
    const auto& cam = renderer.sensor(k).sensor().camera;
    const std::string size = std::to_string(cam.width) + "x" + std::to_string(cam.height);
    if (std::find(seen.begin(), seen.end(), size) != seen.end()) continue;
    sizes += (seen.empty() ? "" : " + ") + size;
    seen.push_back(size);
  }
  const std::uintmax_t bytes = folder_bytes(a.out);
  std::printf(
      "rendered %d frames x %d sensor(s) at %s in %.2f s (%.1f frames/s, with image writing) -> "
      "%s (%.1f MB)\n",
      s.frames, renderer.sensor_count(), sizes.c_str(), s.seconds,
      s.frames / std::max(s.seconds, 1e-9), a.out.c_str(), bytes / 1e6);
  std::printf("contact in %d of %d frames\n", s.contact_frames, s.frames);
  if (s.frames_in_flight > 0) {
    std::fprintf(stderr,
                 "note: rendered %d frame(s) at a time, fewer than the threads, for the memory "
                 "available (about %.2f GB a frame)\n",
                 s.frames_in_flight, 1e-9 * double(s.frame_memory_bytes));
  }
  for (const std::string& earlier : s.earlier_sensor_dirs) {
    std::fprintf(stderr,
                 "note: %s, from an earlier render into %s, is not a sensor of this scene: left as "
                 "it was, no longer in %s/sensors.json\n",
                 earlier.c_str(), a.out.c_str(), a.out.c_str());
  }
  std::fflush(stdout);  // the warnings below (stderr) follow these lines in a shared log too
  const SceneRender& render_settings = renderer.scene().render;
  const bool colour = std::find(render_settings.outputs.begin(), render_settings.outputs.end(),
                                "color") != render_settings.outputs.end();
  if (colour && render_settings.noise && !render_settings.seed_given) {
    std::fprintf(stderr,
                 "note: %s has no render.seed: its camera noise is seed 0's, frame by frame the "
                 "same as every other scene's without one (give each scene of a dataset its own "
                 "seed)\n",
                 a.scene.c_str());
  }
  const std::string untracked = untracked_contact_warning(s, renderer.scene());
  if (!untracked.empty()) std::fprintf(stderr, "%s\n", untracked.c_str());
  if (s.contact_frames == 0) {
    std::fprintf(stderr,
                 "warning: %s: no object touches the gel within the camera's view in any frame; "
                 "every frame shows the background only\n",
                 a.scene.c_str());
  }
  for (int k = 0; k < renderer.sensor_count(); ++k) {
    const SensorRenderer& sensor = renderer.sensor(k);
    const std::string& name = renderer.scene().sensors[std::size_t(k)].name;
    // A camera that sees past the gel (a wide field of view of a sensor of one's own): the
    // renderer draws gel there, a real sensor its housing. More than a pixel is said.
    const GelModel& gel = sensor.sensor().gel;
    const CameraModel& camera = sensor.sensor().camera;
    const Eigen::Vector2d beyond = view_beyond_gel(camera, gel);
    if (std::max(beyond.x() * camera.fx, beyond.y() * camera.fy) / camera.distance_m > 1.0) {
      std::fprintf(stderr,
                   "warning: sensor %s's camera sees past its gel's edges, by %.1f mm along x and "
                   "%.1f mm along y (gel.width_m %.1f mm, gel.height_m %.1f mm): the render "
                   "draws gel there, where a real sensor's image shows its housing\n",
                   name.c_str(), 1e3 * beyond.x(), 1e3 * beyond.y(), 1e3 * gel.width_m,
                   1e3 * gel.height_m);
    }
    // A sensor whose no-contact image is clipped over much of it (at most one channel left to
    // change) cannot show a press there (lights too bright or too dark): said, as recording and
    // track say of a reference.
    if (!sensor.settings().color) continue;
    const std::string what = "sensor " + name + "'s no-contact image (background.png)";
    // (Not its noise: a real background's noise is in every frame, so no difference shows it.)
    const std::string warning = saturated_reference_warning(sensor.background_color_u8(), what);
    if (!warning.empty()) std::fprintf(stderr, "warning: %s\n", warning.c_str());
  }
  if (s.clamped_frames > 0) {
    const bool points = renderer.sensor(0).settings().contact_points;
    std::fprintf(stderr,
                 "warning: %s: in %d frames an object penetrates beyond the gel's maximum "
                 "indentation; the indentation was clamped there%s\n",
                 a.scene.c_str(), s.clamped_frames,
                 points ? ", and where the object reached past the gel's base no contact point "
                          "is written"
                        : "");
  }
  return kExitOk;
}

// Reads every frame of every output, as tracking or training would: a damaged, truncated or
// wrong-sized file throws InputError naming it; so does background.png. Returns the number of
// files read.
long decode_every_frame(const Dataset& d) {
  long files = 0;
  for (const std::string& output : d.info().outputs) {
    for (int i = 0; i < d.frames(); ++i) {
      if (output == "color") d.color(i);
      // A float frame's numbers finite too: a NaN decodes as well as a number (the tracker
      // counts such normals as rejected, but a dataset should not hold them).
      const auto finite = [&](const ImageF& image, const char* name) {
        if (const auto bad = first_non_finite(image)) {
          throw InputError(dataset_frame_path(d.dir(), name, i) + ": pixel (" +
                           std::to_string((*bad)[0]) + ", " + std::to_string((*bad)[1]) +
                           ") is not a finite number");
        }
      };
      if (output == "normal") finite(d.normal(i), "normal");
      if (output == "normal_png") d.normal_png(i);
      if (output == "depth") finite(d.depth(i), "depth");
      if (output == "mask") {
        // poses.csv's contact is the mask's: a pixel of it, or none (an edited file, or a mask
        // copied from another frame, decodes as well as the right one).
        const ImageU8 mask = d.mask(i);
        const FramePose& pose = d.poses()[std::size_t(i)];
        const bool touched =
            std::any_of(mask.data.begin(), mask.data.end(), [](std::uint8_t m) { return m > 0; });
        if (pose.contact_known && pose.contact != touched) {
          throw InputError(dataset_frame_path(d.dir(), "mask", i) + ": " +
                           (touched ? "shows contact" : "shows no contact") + ", but poses.csv " +
                           (pose.contact ? "marks" : "does not mark") + " frame " +
                           std::to_string(i) + " as in contact");
        }
      }
      if (output == "points") d.contact_points(i);
      ++files;
    }
  }
  if (std::filesystem::exists(std::filesystem::path(d.dir()) / "background.png")) {
    d.background();
    ++files;
  }
  return files;
}

void print_dataset_info(const std::string& dir, bool check) {
  const Dataset d = Dataset::open(dir);
  const DatasetInfo& info = d.info();
  int contact = 0, contact_unknown = 0, object_known = 0;
  for (const auto& p : d.poses()) {
    contact += p.contact_known && p.contact;
    contact_unknown += !p.contact_known;
    object_known += p.object_known;
  }
  std::string outputs;
  for (const auto& o : info.outputs) outputs += (outputs.empty() ? "" : ", ") + o;
  std::printf("dataset   %s\n", dir.c_str());
  std::printf("sensor    %s, %dx%d px, fx %.2f px\n", info.sensor.name.c_str(), info.width(),
              info.height(), info.sensor.camera.fx);
  std::printf("frames    %d at %g fps (%d with contact", info.frames, info.fps, contact);
  if (contact_unknown > 0) std::printf(", %d not known", contact_unknown);
  std::printf(")\n");
  if (object_known < info.frames) {
    std::printf("poses     the object's pose is given in %d of %d frames\n", object_known,
                info.frames);
  }
  std::printf("outputs   %s\n", outputs.c_str());
  if (!info.object_mesh.empty()) {
    std::printf("object    %s (%s, scale %g)\n", info.object_name.c_str(), info.object_mesh.c_str(),
                info.object_scale);
  } else {
    std::printf("object    %s (no mesh)\n",
                info.object_name.empty() ? "-" : info.object_name.c_str());
  }
  if (!info.scene.empty()) {
    std::printf("scene     %s (seed %llu)\n", info.scene.c_str(), (unsigned long long)info.seed);
    std::printf("render    %s gel, noise sigma %g, ",
                info.sensor.gel.elastic.enabled ? "elastic" : "rigid", info.sensor.noise.sigma);
    if (info.render_known) {
      std::printf("shadows %s, %s background\n", info.shadows ? "on" : "off",
                  info.background.empty() ? "the sensor's synthetic" : info.background.c_str());
    } else {
      std::printf("shadows and background not recorded (an older render)\n");
    }
  } else {
    std::printf("scene     none (a recording)\n");
  }
  if (check) {
    std::fflush(stdout);
    const long files = decode_every_frame(d);
    std::printf("checked   %ld frame files: each reads, at %dx%d\n", files, info.width(),
                info.height());
  }
}

// A dataset, or a render of several sensors (its sensors.json): each sensor's dataset in turn.
int run_info(const std::string& dir, bool check) {
  std::vector<std::string> sensors = sensor_dataset_dirs(dir);
  if (sensors.size() == 1 && sensors[0] == dir) sensors.clear();
  if (sensors.empty()) {
    print_dataset_info(dir, check);  // Dataset::open says what DIR lacks
    return kExitOk;
  }
  std::string names;
  for (const std::string& s : sensors) {
    names += (names.empty() ? "" : ", ") + std::filesystem::path(s).filename().string();
  }
  std::printf("render    %s: %zu sensors (%s): %s\n", dir.c_str(), sensors.size(), kSensorIndexFile,
              names.c_str());
  for (const std::string& s : sensors) {
    std::printf("\n");
    print_dataset_info(s, check);
  }
  return kExitOk;
}

// --width and --height, which go together: the intrinsics scale with each side, so one alone
// would stretch the pixels.
void add_image_size_options(CLI::App& cmd, int& width, int& height, const std::string& what) {
  CLI::Option* w = cmd.add_option("--width", width, "Override " + what + " width [px]")
                       ->check(range_check(kMinImageSide, kMaxImageSide));
  CLI::Option* h = cmd.add_option("--height", height, "Override " + what + " height [px]")
                       ->check(range_check(kMinImageSide, kMaxImageSide));
  w->needs(h);
  h->needs(w);
}

}  // namespace
}  // namespace pg

int main(int argc, char** argv) {
  using namespace pg;
  CLI::App app{"tacsim: a vision-based tactile sensor simulator (DIGIT, GelSight Mini)"};
  app.require_subcommand(1);

  RenderArgs render;
  CLI::App* cmd_render = app.add_subcommand("render", "Render a scene file into a dataset folder");
  cmd_render->add_option("scene", render.scene, "Scene file (JSON)")->required();
  cmd_render->add_option("--out,-o", render.out, "Output dataset folder")->required();
  cmd_render->add_option(
      "--outputs", render.outputs,
      "Comma-separated outputs (color,normal,normal_png,depth,mask,points); default: the "
      "scene's");
  cmd_render->add_option("--threads", render.threads, "Worker threads (default: all cores)")
      ->check(kThreads);
  add_image_size_options(*cmd_render, render.width, render.height, "the sensors' image");
  cmd_render->add_option("--background", render.background,
                         "Real background image for every sensor (TACTO-style blend), or "
                         "synthetic (none): the renderer's own, whatever the scene says");
  cmd_render->add_option("--shadows", render.shadows, "Override the scene: on or off")
      ->check(CLI::IsMember({"on", "off"}));
  cmd_render->add_option("--elastic", render.elastic, "Override the gel's elastic model: on or off")
      ->check(CLI::IsMember({"on", "off"}));
  cmd_render
      ->add_option("--noise", render.noise,
                   "Override the scene's camera noise: on (the sensor's sigma) or off (noise-free "
                   "frames, e.g. for train-normals --noise-augment)")
      ->check(CLI::IsMember({"on", "off"}));
  cmd_render
      ->add_option("--frames", render.frames,
                   "Render only the scene's first N frames (a quick run of a long scene)")
      ->check(range_check(1, 10000000));
  cmd_render->add_flag("--quiet,-q", render.quiet, "No progress line");

  std::string info_dir;
  CLI::App* cmd_info = app.add_subcommand("info", "Describe a dataset folder");
  cmd_info->add_option("dataset", info_dir, "Dataset folder")->required();
  bool info_check = false;
  cmd_info->add_flag("--check", info_check,
                     "Also read every frame file (without: only that each exists), naming the "
                     "first that does not decode or has the wrong size");

  BenchArgs bench;
  CLI::App* cmd_bench = app.add_subcommand("bench", "Benchmark the renderer (frames/s per case)");
  CLI::Option* bench_frames = cmd_bench
                                  ->add_option("--frames", bench.frames,
                                               "Frames per timed run (not with --ablation, "
                                               "whose runs are timed by length)")
                                  ->check(kPositive);
  cmd_bench->add_option("--repeats", bench.repeats, "Timed runs per case (median reported)")
      ->check(kPositive);
  cmd_bench->add_option("--threads", bench.threads, "Threads (default: all cores)")
      ->check(kThreads);
  cmd_bench->add_option("--markdown", bench.markdown, "Also write the table to this file");
  cmd_bench->add_flag("--quick", bench.quick,
                      "A smoke test: at most 200 frames and 3 repeats whatever --frames and "
                      "--repeats say");
  cmd_bench
      ->add_flag("--ablation", bench.ablation,
                 "Switch each of the renderer's skips off in turn and report its cost ratio")
      ->excludes(bench_frames);

  SheetArgs sheet;
  CLI::App* cmd_sheet =
      app.add_subcommand("sheet", "Render one frame of each scene into a contact sheet PNG");
  cmd_sheet->add_option("scenes", sheet.scenes, "Scene files")->required();
  cmd_sheet->add_option("--out,-o", sheet.out, "Output PNG")->required();
  cmd_sheet
      ->add_option("--frame", sheet.frame,
                   "Frame of each scene (default 0; a shorter scene's last), its first sensor")
      ->check(kNonNegative);
  add_image_size_options(*cmd_sheet, sheet.width, sheet.height, "the image");
  cmd_sheet->add_option("--background", sheet.background,
                        "Real background image for every scene, or synthetic (none)");

  PressesArgs presses;
  CLI::App* cmd_presses = app.add_subcommand(
      "presses",
      "Write a scene of random presses of a mesh, one per frame: training data for a normals "
      "model (render it with tacsim render)");
  cmd_presses->add_option("mesh", presses.mesh, "The object's mesh (glTF/GLB, OBJ, STL, PLY, OFF)")
      ->required();
  cmd_presses->add_option("--out,-o", presses.out, "The scene file to write (JSON)")->required();
  cmd_presses->add_option("--frames", presses.frames, "Presses, one per frame (default 50)")
      ->check(range_check(1, 1000000));
  cmd_presses
      ->add_option("--min-depth", presses.min_depth_m,
                   "Shallowest press [m] (default a fifth of --max-depth: 0.0003 on a DIGIT)")
      ->check(kPositive);
  cmd_presses
      ->add_option("--max-depth", presses.max_depth_m,
                   "Deepest press [m] (default 0.75 of the gel's maximum indentation: "
                   "0.0015 on a DIGIT, 0.001125 on a GelSight Mini)")
      ->check(kPositive);
  cmd_presses->add_option("--scale", presses.scale, "Multiplies the mesh (meshes are in metres)")
      ->check(range_check(1e-6, 1e6));
  CLI::Option* preset =
      cmd_presses->add_option("--sensor", presses.sensor, "Sensor preset (default digit)");
  cmd_presses->add_option("--sensor-file", presses.sensor_file, "Sensor configuration file (JSON)")
      ->excludes(preset);
  cmd_presses->add_option("--name", presses.name, "The object's name (default: the mesh's stem)");
  cmd_presses
      ->add_option("--seed", presses.seed, "Seeds the presses and the scene's noise (default 1)")
      ->check(kSeed);
  cmd_presses->add_flag("--quiet,-q", presses.quiet, "No progress line");

  SensitivityArgs sensitivity;
  CLI::App* cmd_sensitivity = app.add_subcommand(
      "sensitivity",
      "How accurately one colour frame can tell the gel's normal at each pixel: the per-pixel "
      "Cramer-Rao bound through the sensor's lights and camera noise");
  CLI::Option* sensitivity_preset =
      cmd_sensitivity->add_option("--sensor", sensitivity.sensor, "Sensor preset (default digit)");
  cmd_sensitivity
      ->add_option("--sensor-file", sensitivity.sensor_file, "Sensor configuration file (JSON)")
      ->excludes(sensitivity_preset);
  cmd_sensitivity
      ->add_option("--sigma", sensitivity.sigma,
                   "Camera noise [levels on 0-255] (default: the sensor's noise.sigma)")
      ->check(range_check(0.0, 255.0));
  cmd_sensitivity
      ->add_option("--tilt", sensitivity.tilt_deg,
                   "Also normals tilted this far from the undeformed gel's, in eight directions "
                   "[deg] (default 20; 0: only the undeformed gel)")
      ->check(range_check(0.0, 89.0));
  cmd_sensitivity->add_option("--out,-o", sensitivity.out,
                              "Write the per-pixel bound [rad] as an image (EXR)");

  return run_cli(app, argc, argv, [&]() -> int {
    if (cmd_sensitivity->parsed()) return run_sensitivity(sensitivity);
    if (cmd_presses->parsed()) return run_presses(presses);
    if (cmd_sheet->parsed()) return run_sheet(sheet);
    if (cmd_render->parsed()) {
      render.outputs_given = cmd_render->count("--outputs") > 0;
      return run_render(render);
    }
    if (cmd_info->parsed()) return run_info(info_dir, info_check);
    if (cmd_bench->parsed()) return run_bench(bench);
    return kExitUsage;
  });
}
