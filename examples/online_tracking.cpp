// Tracking frame by frame in a program of your own: the libraries' online API, without dataset
// files. A scene is rendered in memory one frame at a time, standing in for a live sensor's
// camera; each colour frame then takes the steps a live frame would:
//
//   colour image -> normals -> contact cloud -> one update of the tracker -> the object's pose
//
// The normals here are the sensor model's shading inverted pixel by pixel (no network; for a
// real sensor, measure its lights first: patchgraph fit-sensor). With a trained model, link
// pg_learn and take them from NormalEstimator::load(MODEL).predict(color, reference) instead.
//
// Usage: online_tracking [SCENE.json] (default: the repository's scenes/default.json)
// Prints a line every tenth frame and the final and RMS errors against the scene's poses; exit 1
// with the error on stderr for a scene that cannot be read.
#include <cmath>
#include <cstdio>
#include <exception>
#include <string>

#include "pg/graph/track_dataset.h"
#include "pg/graph/tracker.h"
#include "pg/sim/scene.h"
#include "pg/sim/scene_renderer.h"
#include "pg/sim/shading_inversion.h"
#include "pg/tracker/contact_cloud.h"

namespace {

int run(const std::string& scene_path) {
  using namespace pg;
  // The stand-in for the sensor: only the colour images are rendered.
  RenderOverrides overrides;
  overrides.outputs = {"color"};
  const SceneRenderer scene_renderer(load_scene(scene_path), overrides);
  const Scene& scene = scene_renderer.scene();
  const SensorRenderer& camera = scene_renderer.sensor(0);
  const SensorModel& sensor = camera.sensor();
  // A live sensor's reference is a frame without contact (better: the per-pixel median of a few,
  // median_image in pg/core/image_change.h); a render's is its no-contact image.
  const ImageU8& reference = camera.background_color_u8();
  const ShadingInversion shading(sensor, !camera.settings().background.empty());

  // The front end and the graph, set up as `patchgraph track --normals shading` sets them.
  TrackOptions options;
  use_estimated_normals(options);
  ContactCloudBuilder front_end(sensor, options.front_end.contact_cloud());
  GraphOptions graph = tracker_graph_options(options);
  // A live loop may run for hours: the tracker keeps only the last frames' estimates and factors
  // (its memory then stays bounded; the estimates are the same).
  graph.history_frames = 100;
  PatchGraphTracker tracker(graph);

  ContactFrame contact;
  double sum_sq_m = 0, sum_sq_rad = 0, translation_m = 0, rotation_rad = 0;
  for (int t = 0; t < scene.frames; ++t) {
    const RenderedFrame frame = scene_renderer.render_frame(t)[0];
    const SE3 T_world_sensor = scene.sensors[0].T_world_sensor.at(t);
    const SE3 truth = scene.objects[std::size_t(scene.tracked_object)].T_world_object.at(t);

    front_end.build(shading.normals(frame.images.color, reference), contact);
    TrackerInput input;
    input.T_world_sensor_measured = T_world_sensor;  // the robot's forward kinematics
    // The vision prior, read only where a contact episode starts (a camera's estimate of the
    // object; give object_prior_given = false where there is none).
    input.T_world_object_prior = truth;
    set_measurement(contact, input);
    const TrackerEstimate estimate = tracker.add(input);

    translation_m = translation_distance(estimate.T_world_object, truth);
    rotation_rad = rotation_distance(estimate.T_world_object, truth);
    sum_sq_m += translation_m * translation_m;
    sum_sq_rad += rotation_rad * rotation_rad;
    if (t % 10 == 0 || t + 1 == scene.frames) {
      const Eigen::Vector3d p = estimate.T_world_object.translation();
      std::printf(
          "frame %3d  %-10s  object at (%7.3f, %7.3f, %7.3f) mm  error %.3f mm %.4f rad"
          "  update %.2f ms%s\n",
          t, estimate.contact ? "contact" : "no contact", 1e3 * p.x(), 1e3 * p.y(), 1e3 * p.z(),
          1e3 * translation_m, rotation_rad, estimate.solve_ms,
          estimate.tracking_lost ? "  (lost)" : "");
    }
  }
  std::printf("final error %.3f mm %.4f rad; RMSE %.3f mm %.4f rad over %d frames\n",
              1e3 * translation_m, rotation_rad, 1e3 * std::sqrt(sum_sq_m / scene.frames),
              std::sqrt(sum_sq_rad / scene.frames), scene.frames);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 2) {
    std::fprintf(stderr, "usage: %s [SCENE.json]\n", argv[0]);
    return 2;
  }
  try {
    return run(argc > 1 ? argv[1] : std::string(PG_SOURCE_DIR) + "/scenes/default.json");
  } catch (const std::exception& e) {  // pg::InputError (a scene or mesh that cannot be read) too
    std::fprintf(stderr, "error: %s\n", e.what());
    return 1;
  }
}
