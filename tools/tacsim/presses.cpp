#include "presses.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "../common/sensor_choice.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/json_fields.h"
#include "pg/sim/mesh.h"
#include "pg/sim/presses.h"

namespace pg {
namespace {

namespace fs = std::filesystem;

// Where the presses go, as fractions of the gel the camera sees (visible_gel_area, +-8.3 x
// +-10.9 mm about the gel's centre on the DIGIT): the point that touches first within 0.45 of
// it, every penetrating point within 0.85; on the DIGIT about the repository's training scenes'
// +-4 x +-5 mm and +-7.2 x +-9 mm (make_scenes).
constexpr double kTargetFraction = 0.45, kContactFraction = 0.85;

// `path` as the scene file at `scene` names it: relative to the scene's folder when the two
// share a top folder (a project's scenes/ and meshes/), else absolute.
std::string path_from_scene(const std::string& path, const std::string& scene) {
  const fs::path target = fs::absolute(path).lexically_normal();
  const fs::path folder = fs::absolute(scene).lexically_normal().parent_path();
  const auto top = [](const fs::path& p) {
    auto it = p.begin();
    return ++it == p.end() ? fs::path() : *it;  // the component after the root
  };
  if (top(target) != top(folder)) return target.generic_string();
  return target.lexically_relative(folder).generic_string();
}

}  // namespace

int run_presses(const PressesArgs& a) {
  if (a.out.empty()) throw InputError("--out: empty; give the scene file to write");
  if (fs::is_directory(a.out)) {
    throw InputError("--out " + a.out + ": is a folder; give the scene file to write (a .json)");
  }
  const SensorModel sensor = chosen_sensor(a.sensor, a.sensor_file);
  // The defaults follow the sensor (0.3-1.5 mm on the presets' 2 mm gels), so that only what
  // was given is blamed.
  const double max_indentation = sensor.gel.max_indentation_m;
  const double max_depth = a.max_depth_m > 0 ? a.max_depth_m : 0.75 * max_indentation;
  const double min_depth = a.min_depth_m > 0 ? a.min_depth_m : 0.2 * max_depth;
  as_usage_error([&] {
    check_in_range("--max-depth", max_depth, 1e-6, max_indentation,
                   " [m]: the gel takes at most its max_indentation_m");
    check_in_range("--min-depth", min_depth, 1e-6, max_depth,
                   " [m]: positive and at most --max-depth");
  });
  std::error_code ec;
  if (fs::equivalent(a.out, a.mesh, ec)) {
    throw InputError("--out " + a.out + ": is the mesh; give the scene file to write (a .json)");
  }
  if (lower_extension(a.out) != ".json") {
    throw UsageError("--out " + a.out + ": a scene file is JSON; give a .json file");
  }
  check_output_file(a.out, {FileKind::kJson});

  const TriangleMesh mesh = load_mesh(a.mesh, a.scale);
  const Bounds3 bounds = mesh_bounds(mesh);
  const Eigen::Vector3d extent = (bounds.max - bounds.min).cast<double>();
  // A wrong --scale, most likely: an object thinner than the deepest press would sink into the
  // gel whole (and one of a few microns never shows); one larger than a metre (millimetres read
  // as metres) would cover the gel in every press, its surface grid too coarse to keep each
  // contact inside the image.
  const auto scale_slip = [&](double unit, const char* unit_name, const std::string& why) {
    const auto size = [&](double v) { return format_number(v / unit, "%.3g"); };
    return InputError(a.mesh + (a.scale != 1.0 ? " at scale " + format_number(a.scale) : "") +
                      ": " + size(extent.x()) + " x " + size(extent.y()) + " x " +
                      size(extent.z()) + " " + unit_name + ", " + why +
                      "; is --scale right (meshes are in metres: --scale 0.001 for millimetres)?");
  };
  if (extent.minCoeff() <= max_depth) {
    throw scale_slip(1e-3, "mm",
                     "no thicker than the deepest press (" +
                         format_number(1e3 * max_depth, "%.3g") +
                         " mm): it would sink into the gel whole");
  }
  if (extent.maxCoeff() > 1.0) {
    throw scale_slip(1.0, "m", "larger than a metre: each press would cover the gel");
  }
  // Grid points 0.25 mm apart (the repository's scenes), closer on a small object so that a
  // press's depth is measured to a small part of it; the spacing grows until there are at most
  // two million (a 0.6 m sphere at 0.25 mm would be 70 million, and a CAD part's long thin
  // triangles many more than their area needs). The grid keeps the corners and edges, so a
  // coarser one errs only on curved surfaces, by spacing^2 / 8 radius.
  constexpr std::size_t kMaxPoints = 2'000'000;
  double spacing = std::min(0.25e-3, extent.norm() / 50);
  while (surface_grid_size(mesh, spacing) > kMaxPoints) spacing *= 1.25;
  const std::vector<Eigen::Vector3d> points = surface_grid(mesh, spacing);

  RandomPressOptions options;
  options.frames = a.frames;
  options.min_depth_m = min_depth;
  options.max_depth_m = max_depth;
  const GelArea visible = visible_gel_area(sensor);
  options.centre_m = visible.centre_m;
  options.target_half_m = kTargetFraction * visible.half_m;
  options.contact_half_m = kContactFraction * visible.half_m;
  options.seed = a.seed;
  std::vector<Waypoint> presses;
  try {
    Progress progress("presses", a.frames, !a.quiet, "presses");
    presses = random_presses(points, sensor.gel, options, [&](int done) { progress.update(done); });
  } catch (const InputError& e) {
    throw InputError(a.mesh + (a.scale != 1.0 ? " at scale " + format_number(a.scale) : "") + ": " +
                     e.what());
  }

  nlohmann::ordered_json waypoints = nlohmann::ordered_json::array();
  for (const Waypoint& w : presses) {
    waypoints.push_back({{"frame", w.frame},
                         {"position", {w.position_m.x(), w.position_m.y(), w.position_m.z()}},
                         {"rpy", {w.rpy_rad.x(), w.rpy_rad.y(), w.rpy_rad.z()}}});
  }
  nlohmann::ordered_json sensor_entry = {{"name", a.sensor_file.empty() ? sensor.name : "sensor"}};
  if (!a.sensor_file.empty()) {
    sensor_entry["sensor_file"] = path_from_scene(a.sensor_file, a.out);
  } else {
    sensor_entry["sensor"] = a.sensor.empty() ? "digit" : a.sensor;
  }
  nlohmann::ordered_json object = {
      {"name", a.name.empty() ? fs::path(a.mesh).stem().string() : a.name},
      {"mesh", path_from_scene(a.mesh, a.out)}};
  if (a.scale != 1.0) object["scale"] = a.scale;
  object["trajectory"] = {{"waypoints", waypoints}};
  // As the repository's training scenes: the non-ideal effects on (shadows, noise; the gel as
  // the sensor says), so that a network trained on them sees what a real sensor shows.
  const nlohmann::ordered_json scene = {{"frames", a.frames},
                                        {"fps", 60},
                                        {"sensors", {sensor_entry}},
                                        {"objects", {object}},
                                        {"render",
                                         {{"outputs", {"color", "normal", "depth", "mask"}},
                                          {"noise", true},
                                          {"shadows", true},
                                          {"background", "synthetic"},
                                          {"seed", a.seed}}}};
  if (fs::path(a.out).has_parent_path()) fs::create_directories(fs::path(a.out).parent_path(), ec);
  write_text_file(a.out, format_json(scene) + "\n");
  // The depths the presses have: a draw whose contact leaves the area is drawn again, and deep
  // presses of a large object leave it more often than shallow ones.
  double shallowest = max_depth, deepest = 0;
  for (const Waypoint& w : presses) {
    const double depth =
        measure_press(points, SE3(quaternion_from_rpy(w.rpy_rad), w.position_m), sensor.gel)
            .depth_m;
    shallowest = std::min(shallowest, depth);
    deepest = std::max(deepest, depth);
  }
  const Eigen::Vector2d lo = options.centre_m - options.contact_half_m;
  const Eigen::Vector2d hi = options.centre_m + options.contact_half_m;
  std::printf(
      "wrote %s: %d random presses of %s, %.2f-%.2f mm deep (asked %.2f-%.2f), within x %.1f to "
      "%.1f mm, y %.1f to %.1f mm\n",
      a.out.c_str(), a.frames, a.mesh.c_str(), 1e3 * shallowest, 1e3 * deepest, 1e3 * min_depth,
      1e3 * max_depth, 1e3 * lo.x(), 1e3 * hi.x(), 1e3 * lo.y(), 1e3 * hi.y());
  if (a.frames >= 10 && deepest < min_depth + 0.6 * (max_depth - min_depth)) {
    std::fprintf(stderr,
                 "warning: the presses reach only %.2f mm of the %.2f asked: deeper ones of this "
                 "object leave the gel the camera sees and were drawn again (a smaller "
                 "--max-depth, a smaller object, or a sensor that sees more of its gel)\n",
                 1e3 * deepest, 1e3 * max_depth);
  }
  std::printf("render it: tacsim render %s --out DIR\n", shell_word(a.out).c_str());
  return kExitOk;
}

}  // namespace pg
