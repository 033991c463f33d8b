#include "fit_sensor.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <vector>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "../common/sensor_choice.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/gel_rays.h"
#include "pg/core/numbers.h"
#include "pg/core/statistics.h"
#include "pg/sim/shading_fit.h"
#include "pg/sim/shading_inversion.h"

namespace pg {

namespace {

// A labelled pixel is in the contact where its normal turns this far from the undeformed gel's:
// the held-out comparison's pixels (as eval-normals' contact region, docs/learned_normals.md).
constexpr double kContactTurnRad = 0.05;

// Opens each dataset, refusing one without colour images or normals.
std::vector<Dataset> open_labelled(const std::vector<std::string>& dirs) {
  std::vector<Dataset> out;
  for (const std::string& dir : dirs) {
    Dataset d = Dataset::open(dir);
    if (!d.info().has_output("color") || !d.info().has_normals()) {
      throw InputError(dir +
                       "/dataset.json: outputs: the fit needs colour images and their "
                       "normals (a render's, or ball presses labelled by patchgraph "
                       "label-ball)");
    }
    out.push_back(std::move(d));
  }
  return out;
}

// Refuses a dataset of another image size than the sensor's (`sensor_source` names it).
void check_sizes(const std::vector<Dataset>& datasets, const SensorModel& sensor,
                 const std::string& sensor_source) {
  for (const Dataset& d : datasets) {
    const DatasetInfo& info = d.info();
    if (info.width() != sensor.camera.width || info.height() != sensor.camera.height) {
      throw InputError(d.dir() + ": frames " + std::to_string(info.width()) + "x" +
                       std::to_string(info.height()) + ", but " + sensor_source + "'s are " +
                       std::to_string(sensor.camera.width) + "x" +
                       std::to_string(sensor.camera.height));
    }
  }
}

double angle_between(const float* a, const float* b) {
  const double dot = double(a[0]) * b[0] + double(a[1]) * b[1] + double(a[2]) * b[2];
  return std::acos(std::clamp(dot, -1.0, 1.0));
}

// The median angle [rad] between the shading's inverse through each sensor and the labels, over
// the labels' contact pixels of every frame.
std::vector<double> held_out_medians(const std::vector<Dataset>& val,
                                     const std::vector<SensorModel>& sensors, bool quiet) {
  int frames = 0;
  for (const Dataset& d : val) frames += d.frames();
  std::vector<std::vector<double>> angles(sensors.size());
  Progress progress("reading held-out presses", frames, !quiet);
  int done = 0;
  const ImageF undeformed =
      undeformed_gel_normals(make_gel_rays(sensors[0].camera, sensors[0].gel));
  for (const Dataset& d : val) {
    std::vector<ShadingInversion> inversions;
    for (const SensorModel& s : sensors) {
      inversions.emplace_back(s, d.info().on_real_background());
    }
    const ImageU8 reference = d.background();
    for (int f = 0; f < d.frames(); ++f) {
      const ImageU8 color = d.color(f);
      const ImageF label = d.normal(f);
      std::vector<std::size_t> contact;
      for (std::size_t i = 0; i < label.data.size() / 3; ++i) {
        if (angle_between(&label.data[3 * i], &undeformed.data[3 * i]) > kContactTurnRad)
          contact.push_back(i);
      }
      for (std::size_t k = 0; k < sensors.size(); ++k) {
        if (contact.empty()) break;
        const ImageF n = inversions[k].normals(color, reference);
        for (std::size_t i : contact)
          angles[k].push_back(angle_between(&n.data[3 * i], &label.data[3 * i]));
      }
      progress.update(++done);
    }
  }
  std::vector<double> out;
  for (const auto& a : angles) out.push_back(a.empty() ? NAN : upper_median(a));
  return out;
}

std::string joined(const std::vector<std::string>& words) {
  std::string out;
  for (const std::string& w : words) out += (out.empty() ? "" : " ") + w;
  return out;
}

}  // namespace

CLI::App* add_fit_sensor_command(CLI::App& app, FitSensorArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "fit-sensor",
      "Measure a sensor's lights from labelled presses: its shading model fitted to their "
      "colours, written as a sensor file");
  cmd->add_option("datasets", a.datasets,
                  "Labelled presses: datasets with colour images and normals (patchgraph "
                  "label-ball on a recording of ball presses, or a render; a ball's: sharp edges, "
                  "which a sensor blurs, bend the fit)")
      ->required();
  cmd->add_option("--out,-o", a.out, "The fitted sensor file (JSON)")->required();
  cmd->add_option("--val", a.val,
                  "Held-out labelled presses: the shading's inverse read through the start's "
                  "lights and the fitted ones, against their labels");
  auto* preset = cmd->add_option("--sensor", a.sensor,
                                 "The start: a sensor preset (default: the first dataset's "
                                 "sensor)");
  cmd->add_option("--sensor-file", a.sensor_file, "The start: a sensor file (instead of --sensor)")
      ->excludes(preset);
  cmd->add_option("--iterations", a.iterations, "Levenberg-Marquardt iterations at most (100)")
      ->check(CLI::Range(1, 1000));
  cmd->add_flag("--quiet,-q", a.quiet, "No progress lines");
  return cmd;
}

int run_fit_sensor(const FitSensorArgs& a) {
  // The sensor file goes neither into a dataset (over its dataset.json or poses.csv) nor over the
  // start it is fitted from.
  for (const auto* datasets : {&a.datasets, &a.val}) {
    for (const std::string& dir : *datasets) check_output_is_not_input(a.out, dir, "the dataset");
  }
  check_output_file(a.out, {FileKind::kJson});
  if (!a.sensor_file.empty()) check_output_is_not_input(a.out, a.sensor_file, "--sensor-file");
  check_can_write(a.out);
  // A dataset twice would weigh twice in the fit; one held out and fitted on validates nothing.
  check_given_once(a.datasets);
  check_given_once(a.val);
  warn_of_validation_in_training(a.val, a.datasets, "the datasets fitted on");
  const std::vector<Dataset> data = open_labelled(a.datasets);
  const std::vector<Dataset> val = open_labelled(a.val);
  // The start's sensor: given, or the one the first dataset was recorded or rendered with.
  SensorModel start;
  std::string source;
  if (!a.sensor_file.empty()) {
    start = load_sensor_file(a.sensor_file);
    source = a.sensor_file;
  } else if (!a.sensor.empty()) {
    start = preset_option(a.sensor);
    source = "--sensor " + a.sensor;
  } else {
    start = data.front().info().sensor;
    source = data.front().dir() + "/dataset.json's sensor";
  }
  check_sizes(data, start, source);
  check_sizes(val, start, source);
  // One reading for all: the change from a real background, or the render's own shading.
  const bool blended = data.front().info().on_real_background();
  for (const Dataset& d : data) {
    if (d.info().on_real_background() != blended) {
      throw InputError(d.dir() + ": " +
                       (blended ? "rendered on the sensor model's own background"
                                : "a real background (a recording, or a render blended onto one)") +
                       ", unlike " + data.front().dir() + "; fit each kind on its own");
    }
  }

  ShadingFitOptions options;
  options.max_iterations = a.iterations;
  ShadingFit fit(start, blended, options);
  const StopOnSignals stop;
  int frames = 0, pressed = 0;
  for (const Dataset& d : data) frames += d.frames();
  {
    Progress progress("reading presses", frames, !a.quiet);
    int done = 0;
    for (const Dataset& d : data) {
      const ImageU8 reference = d.background();
      for (int f = 0; f < d.frames(); ++f) {
        pressed += fit.add_frame(d.color(f), reference, d.normal(f)) > 0;
        progress.update(++done);
      }
    }
  }
  if (fit.pixels() == 0) {
    throw InputError(joined(a.datasets) + ": no frame has a labelled contact (normals turned " +
                     format_number(options.min_turn_rad) +
                     " rad or more from the undeformed gel's); nothing to fit the lights to");
  }
  const ShadingFitResult r = fit.solve([&](int iteration, double rms) {
    stop_if_asked();
    if (!a.quiet && (iteration <= 3 || iteration % 10 == 0))
      std::fprintf(stderr, "fitting: iteration %d, residual %.2f levels\n", iteration, rms);
  });

  std::printf("fit-sensor: %d of %d frames pressed, %zu pixels fitted (%s), from %s\n", pressed,
              frames, r.pixels,
              blended ? "their change from the no-contact image" : "their colours", source.c_str());
  std::printf(
      "residual: %.2f levels with the start's lights, %.2f fitted (RMS, %zu channels), "
      "%d iterations%s\n",
      r.rms_start_levels, r.rms_levels, r.channels, r.iterations,
      r.converged ? "" : " (not converged: --iterations)");
  for (std::size_t k = 0; k < r.sensor.lights.size(); ++k) {
    // (The lights are alike in the model: the fit may move one into another's place.)
    const PointLight& light = r.sensor.lights[k];
    const Eigen::Vector3d p = light.position_m * 1e3;
    const Eigen::Vector3d c = light.color * light.intensity;
    std::printf(
        "light %zu: position (%.2f, %.2f, %.2f) mm, colour x intensity (%.3f, %.3f, "
        "%.3f)\n",
        k, p.x(), p.y(), p.z(), c.x(), c.y(), c.z());
  }
  std::printf("specular %.3f (start %.3f)", r.sensor.shading.specular, start.shading.specular);
  if (!blended)
    std::printf(", ambient %.3f (start %.3f)", r.sensor.shading.ambient, start.shading.ambient);
  std::printf("\n");
  if (!val.empty()) {
    const std::vector<double> m = held_out_medians(val, {start, r.sensor}, a.quiet);
    if (std::isnan(m[0])) {
      std::printf("held-out presses (%s): no labelled contact to compare\n", joined(a.val).c_str());
    } else {
      std::printf(
          "held-out presses (%s): the shading's inverse, median contact angle: %.2f deg "
          "with the start's lights, %.2f deg with the fitted\n",
          joined(a.val).c_str(), m[0] * 180 / kPi, m[1] * 180 / kPi);
    }
  }
  SensorModel fitted = r.sensor;
  fitted.lights_measured = true;  // a recording made with this file needs no warning about them
  write_text_atomically(a.out, sensor_to_json(fitted).dump(2) + "\n", "sensor file");
  std::printf("wrote %s\n", a.out.c_str());
  if (!r.converged) {
    std::fprintf(stderr, "warning: the fit had not converged after %d iterations (--iterations)\n",
                 r.iterations);
  }
  return 0;
}

}  // namespace pg
