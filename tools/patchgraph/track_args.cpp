#include "track_args.h"

#include "pg/core/error.h"
#include "pg/sim/mesh.h"
#include "pg/sim/mesh_sampling.h"

namespace pg {

void add_track_options(CLI::App& app, TrackArgs& a, bool with_method) {
  if (with_method) {
    app.add_option("--method,-m", a.method, "constvel, imagetoimage, patchgraph (default), gtpatch");
  }
  app.add_option("--normals", a.normals, "Normals source: gt (the dataset's normal images)");
  app.add_option("--config", a.config, "Tracker config JSON (depth, mask, icp options)");
  app.add_option("--window", a.window, "Frames in the fixed-lag window; 0 = batch (default 5)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--keyframe-interval", a.keyframe_interval, "Frames between patch key frames")
      ->check(CLI::PositiveNumber);
  app.add_flag("--no-registration-information", a.no_registration_information,
               "Fixed sigmas for registration factors instead of the ICP Hessian's shape");
  app.add_option("--ee-noise", a.end_effector_noise, "Sigma of the sensor pose noise [m, rad]")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--vision-noise", a.vision_noise, "Sigma of the vision prior noise [m, rad]")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--seed", a.seed, "Seed of the simulated measurement noise");
  app.add_flag("--compare-batch", a.compare_batch,
               "Afterwards re-solve the whole sequence at once and report the difference");
}

TrackOptions make_track_options(const TrackArgs& a, const Dataset& dataset) {
  if (a.normals != "gt") {
    throw InputError("--normals: '" + a.normals +
                     "' is not available (only 'gt': learned normals are not built yet)");
  }
  TrackOptions o;
  o.graph.method = method_from_string(a.method);
  o.graph.window = a.window;
  o.graph.patch.keyframe_interval = a.keyframe_interval;
  o.graph.registration_information = !a.no_registration_information;
  if (!a.config.empty()) o.front_end = load_tracker_config(a.config);
  o.end_effector_noise = a.end_effector_noise;
  o.vision_noise = a.vision_noise;
  o.seed = a.seed;
  o.compare_batch = a.compare_batch;
  if (o.graph.method == Method::kGroundTruthPatch) {
    const auto& info = dataset.info();
    if (info.object_mesh.empty()) {
      throw InputError(dataset.dir() + "/dataset.json: object.mesh is empty; gtpatch needs the mesh");
    }
    const SurfaceSamples s = sample_surface(load_mesh(info.object_mesh, info.object_scale), 1e-4);
    o.model_object.points = s.points;
    o.model_object.normals = s.normals;
  }
  return o;
}

}  // namespace pg
