// make_scenes REPO_ROOT: writes the benchmark scene set (scenes/benchmark/<object>_<NN>.json), the
// README demo (scenes/default.json) and the example scenes (scenes/examples/), after checking
// every frame of every scene: the object must press 0.2-2.0 mm into the gel, inside the part of
// the gel the camera sees. Deterministic: the same build writes the same bytes. The families of
// motion and the scene schema are described in scenes/README.md.
//
// The world is the (static) sensor frame S: +z points out of the gel toward the object, so an
// object presses into the gel from +z and penetrates where its surface lies below surface_z(x, y).
#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "common/cli_main.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/hash.h"
#include "pg/core/json_fields.h"
#include "pg/core/random.h"
#include "pg/core/se3.h"
#include "pg/core/sensor.h"
#include "pg/sim/mesh.h"
#include "pg/sim/presses.h"
#include "pg/sim/scene.h"

namespace {

namespace fs = std::filesystem;
using Eigen::AngleAxisd;
using Eigen::Quaterniond;
using Eigen::Vector2d;
using Eigen::Vector3d;
using nlohmann::ordered_json;
using pg::kPi;
using pg::round_to;

constexpr double kMm = 1e-3;
constexpr double kDeg = kPi / 180.0;
constexpr int kWaypointStep = 10;  // frames between waypoints

// What every frame of a scene with contact must satisfy, in every sensor.
constexpr double kMinDepth = 0.2 * kMm;   // deepest point below the gel surface [m]
constexpr double kMaxDepth = 2.0 * kMm;   // the gel's maximum indentation [m]
constexpr double kVisibleX = 8.0 * kMm;   // penetrating points need |x| < this [m]
constexpr double kVisibleY = 10.0 * kMm;  // and |y| < this (the camera sees ~19 x 25 mm) [m]

// ------------------------------------------------------------------------- random numbers

// FNV-1a of the scene name, cut to 53 bits so that any JSON reader keeps it exact.
std::uint64_t scene_seed(const std::string& name) { return pg::fnv1a(name) >> 11; }

// ------------------------------------------------------------------------- motions

// Where the object is at one frame: its orientation, and the world xy of one of its points (the
// pivot). The height follows from the press depth.
struct Placement {
  Quaterniond q_world_object = Quaterniond::Identity();
  Vector3d pivot_object = Vector3d::Zero();
  Vector2d pivot_xy_world = Vector2d::Zero();
};
using Motion = std::function<Placement(int frame)>;

// A rotation about a world axis through the pivot: angle = amplitude sin(2 pi cycles f / F + phase).
struct Sweep {
  Vector3d axis_world;
  double amplitude_rad;
  double phase_rad;
};

Motion sweep_motion(const Quaterniond& q_base, const Vector3d& pivot_object,
                    const Vector2d& centre, const std::vector<Sweep>& sweeps, double cycles,
                    int frames) {
  return [=](int f) {
    Quaterniond q = Quaterniond::Identity();
    for (const Sweep& s : sweeps) {
      const double angle = s.amplitude_rad * std::sin(2 * kPi * cycles * f / frames + s.phase_rad);
      q = q * AngleAxisd(angle, s.axis_world.normalized());
    }
    return Placement{q * q_base, pivot_object, centre};
  };
}

// Rolling without slipping along a square: each side of `side_frames` frames moves the centre by
// `side` and turns the ball by side / radius about z x (direction of motion), since the contact
// point on the gel (at -z from the centre) must stay still: v + w x (-r z) = 0.
Motion rolling_square(const Vector2d& centre, double side, int side_frames, double heading_rad,
                      double turn, double radius) {
  const Vector2d u0(std::cos(heading_rad), std::sin(heading_rad));
  const Vector2d u1(std::cos(heading_rad + turn * kPi / 2), std::sin(heading_rad + turn * kPi / 2));
  const Vector2d start = centre - 0.5 * side * (u0 + u1);
  return [=](int f) {
    Placement p;
    p.pivot_xy_world = start;
    for (int k = 0, left = f; left > 0; ++k, left -= side_frames) {
      const double a = heading_rad + turn * k * kPi / 2;
      const Vector3d u(std::cos(a), std::sin(a), 0.0);
      const double d = side * std::min(left, side_frames) / side_frames;
      p.pivot_xy_world += d * u.head<2>();
      p.q_world_object = AngleAxisd(d / radius, Vector3d::UnitZ().cross(u)) * p.q_world_object;
    }
    return p;
  };
}

// ------------------------------------------------------------------------- objects

// A mesh with its surface samples and bounds, loaded once.
struct Shape {
  std::vector<Vector3d> points;
  Vector3d lo, hi;
};

const Shape& shape(const fs::path& meshes_dir, const std::string& file) {
  static std::map<std::string, Shape> cache;
  const std::string path = (meshes_dir / file).lexically_normal().string();
  auto it = cache.find(path);
  if (it != cache.end()) return it->second;
  const pg::TriangleMesh mesh = pg::load_mesh(path);
  const pg::Bounds3 b = pg::mesh_bounds(mesh);
  Shape s{pg::surface_grid(mesh, 0.25 * kMm), b.min.cast<double>(), b.max.cast<double>()};
  return cache.emplace(path, std::move(s)).first->second;
}

// A way of holding an object against the gel: its orientation before any sweep, which part of
// it touches (a band of object z), the in-plane axis its roll sweeps turn about, and limits that
// keep its contact inside the visible gel.
struct ContactMode {
  std::string name;
  Quaterniond q_base;
  Vector3d roll_axis_world = Vector3d::UnitY();
  double z_band_lo = 0.0, z_band_hi = 1.0;  // fractions of the object's height
  double max_depth = 1.5 * kMm;
  double max_roll = 20 * kDeg;
  double centre_scale = 1.0;  // of the +-1 mm (x), +-1.5 mm (y) contact centre offsets
};

// The shortest rotation taking direction a to direction b (not opposite ones). Eigen's
// FromTwoVectors would do, but its SVD trips a false -Wmaybe-uninitialized in GCC 12 with AVX-512.
Quaterniond rotation_between(const Vector3d& a, const Vector3d& b) {
  const Vector3d axis = a.cross(b);
  if (axis.norm() < 1e-12) return Quaterniond::Identity();
  return Quaterniond(AngleAxisd(std::atan2(axis.norm(), a.dot(b)), axis.normalized()));
}

Quaterniond rotation_from_columns(const Vector3d& x, const Vector3d& y, const Vector3d& z) {
  Eigen::Matrix3d R;
  R << x, y, z;
  return Quaterniond(R);
}

// The object point a mode presses first: the deepest in a flat world, within the mode's band.
Vector3d mode_pivot(const Shape& s, const ContactMode& m) {
  const double h = s.hi.z() - s.lo.z();
  const Vector3d down_object = m.q_base.conjugate() * -Vector3d::UnitZ();
  return pg::extreme_centroid(s.points, down_object, s.lo.z() + m.z_band_lo * h - 1e-9,
                              s.lo.z() + m.z_band_hi * h + 1e-9);
}

// The brick lies along the gel's long axis (y) with its studs toward the gel; "stud_edge" tilts
// it about that axis so one row of studs and the long edge of the stud face press.
ContactMode brick_mode(int kind, double yaw0, pg::Random& rng) {
  const Quaterniond studs_down = AngleAxisd(kPi / 2, Vector3d::UnitZ()) *
                                 AngleAxisd(kPi, Vector3d::UnitX());
  const Quaterniond yaw(AngleAxisd(yaw0, Vector3d::UnitZ()));
  if (kind == 0) {
    // Deeper than 1 mm the outer studs (12 mm out along y) start to touch near the image edge.
    ContactMode m{"studs", yaw * studs_down, yaw * Vector3d::UnitY()};
    m.max_depth = 1.0 * kMm;
    m.max_roll = 15 * kDeg;
    return m;
  }
  const double tilt = rng.uniform(25, 35) * kDeg;
  ContactMode m{"stud_edge", yaw * AngleAxisd(tilt, Vector3d::UnitY()) * studs_down,
                yaw * Vector3d::UnitY()};
  m.max_depth = 1.2 * kMm;
  m.max_roll = 12 * kDeg;
  return m;
}

// The figure (head +z, facing +y) lies along the gel's y axis: face down with the head or the
// legs over the contact, or on its side with the arm and hand pressed.
ContactMode human_mode(int kind, double yaw0) {
  const Quaterniond yaw(AngleAxisd(yaw0, Vector3d::UnitZ()));
  const Quaterniond face_down(AngleAxisd(-kPi / 2, Vector3d::UnitX()));
  if (kind == 0) {
    ContactMode m{"head", yaw * face_down, yaw * Vector3d::UnitX(), 0.72, 0.95};
    m.max_roll = 10 * kDeg;  // tipping further brings the torso onto the gel
    return m;
  }
  if (kind == 1) {
    // The hands hang down to a quarter of the height, in front of the legs: stay below them.
    // The legs' front is flat and 14.4 mm wide: deep or off-centre, it fills the image.
    // Rolls tip it toward the feet or the hips (about x): about y one leg's outer edge would
    // press at the image edge.
    ContactMode m{"legs", yaw * face_down, yaw * Vector3d::UnitX(), 0.0, 0.24};
    m.max_depth = 0.9 * kMm;
    m.max_roll = 10 * kDeg;
    m.centre_scale = 0.5;
    return m;
  }
  const Quaterniond side = rotation_from_columns(-Vector3d::UnitZ(), -Vector3d::UnitX(),
                                                 Vector3d::UnitY());
  return {"arm_side", yaw * side, yaw * Vector3d::UnitY()};
}

// ------------------------------------------------------------------------- scenes

struct SceneSpec {
  std::string file;    // relative to the repository root
  std::string object;  // object name, also the name of the tracked object
  std::string mesh;    // file in meshes/
  std::string family;  // for the summary
  int frames = 300;
  double depth = 1.0 * kMm;  // press depth at every waypoint [m]
  std::uint64_t seed = 0;
  Motion motion;
};

std::string relative_mesh(const std::string& scene_file, const std::string& mesh) {
  return fs::path(mesh).lexically_relative(fs::path(scene_file).parent_path()).generic_string();
}

ordered_json vec_json(const Vector3d& v) { return {v.x(), v.y(), v.z()}; }

ordered_json render_json(std::uint64_t seed) {
  return {{"outputs", {"color", "normal", "depth", "mask"}},
          {"noise", true},
          {"shadows", false},
          {"background", "synthetic"},
          {"seed", seed}};
}

ordered_json scene_json(int frames, ordered_json sensors, ordered_json object,
                        std::uint64_t seed) {
  const std::string name = object["name"];
  return {{"frames", frames},
          {"fps", 60},
          {"sensors", std::move(sensors)},
          {"objects", {std::move(object)}},
          {"tracked_object", name},
          {"render", render_json(seed)}};
}

const ordered_json kOneDigit = {{{"name", "digit"}, {"sensor", "digit"}}};
// The paper's simulated data came from TACTO, whose gel is rigid (a z-buffer): the benchmark and
// the default scene render the same way, so that their tracking errors compare with the paper's.
const ordered_json kPaperDigit = {
    {{"name", "digit"},
     {"sensor", {{"preset", "digit"}, {"gel", {{"elastic", {{"enabled", false}}}}}}}}};

// Waypoints every kWaypointStep frames up to the first at or past the last frame; positions
// rounded to 0.1 um and angles to 1 urad, with the height solved for the rounded orientation.
ordered_json waypoints_json(const SceneSpec& spec, const Shape& s, const pg::GelModel& gel) {
  ordered_json waypoints = ordered_json::array();
  for (int f = 0; f - kWaypointStep < spec.frames - 1; f += kWaypointStep) {
    const Placement p = spec.motion(f);
    Vector3d rpy = pg::rpy_from_quaternion(p.q_world_object);
    for (int i = 0; i < 3; ++i) rpy[i] = round_to(rpy[i], 1e6);
    const Quaterniond q = pg::quaternion_from_rpy(rpy);
    Vector3d t;
    t.head<2>() = p.pivot_xy_world - (q * p.pivot_object).head<2>();
    t.z() = 0.0;
    t.z() = pg::measure_press(s.points, pg::SE3(q, t), gel).depth_m - spec.depth;
    for (int i = 0; i < 3; ++i) t[i] = round_to(t[i], 1e7);
    waypoints.push_back({{"frame", f}, {"position", vec_json(t)}, {"rpy", vec_json(rpy)}});
  }
  return waypoints;
}

ordered_json sequence_json(const SceneSpec& spec, const fs::path& root) {
  const Shape& s = shape(root / "meshes", spec.mesh);
  const pg::GelModel gel = pg::sensor_preset("digit").gel;
  ordered_json object = {{"name", spec.object},
                         {"mesh", relative_mesh(spec.file, "meshes/" + spec.mesh)},
                         {"trajectory", {{"waypoints", waypoints_json(spec, s, gel)}}}};
  return scene_json(spec.frames, kPaperDigit, std::move(object), spec.seed);
}

// ------------------------------------------------------------------------- the benchmark set

SceneSpec benchmark_spec(const std::string& object, int index, const fs::path& root) {
  char nn[16];  // any int fits
  std::snprintf(nn, sizeof nn, "%02d", index);
  SceneSpec spec;
  spec.object = object;
  spec.file = "scenes/benchmark/" + object + "_" + nn + ".json";
  spec.seed = scene_seed(object + "_" + nn);
  pg::Random rng(spec.seed);
  const Vector2d centre(rng.uniform(-1, 1) * kMm, rng.uniform(-1.5, 1.5) * kMm);
  const double cycles = rng.uniform(1.0, 2.5);
  const double depth_fraction = rng.uniform(0, 1);  // where in a mode's depth range
  const double yaw0 = rng.uniform(-10, 10) * kDeg;
  auto depth_in = [&](double lo, double hi) { return lo + (hi - lo) * depth_fraction; };
  auto sweep = [&](const Vector3d& axis, double lo_deg, double hi_deg) {
    return Sweep{axis, rng.uniform(lo_deg, hi_deg) * kDeg, 0.0};
  };

  if (object == "sphere") {
    spec.mesh = "sphere_r6mm.glb";
    const Shape& s = shape(root / "meshes", spec.mesh);
    const double side = rng.uniform(2, 5) * kMm;
    const int side_frames = 10 * rng.integer(4, 7);
    const double heading = rng.integer(0, 3) * kPi / 2;
    spec.family = "square_roll";
    spec.depth = depth_in(0.5, 1.5) * kMm;
    spec.motion = rolling_square(Vector2d(centre.x() * 0.5, centre.y()), side, side_frames,
                                 heading, rng.sign(), 0.5 * (s.hi.x() - s.lo.x()));
    return spec;
  }
  if (object == "cube") {
    spec.mesh = "cube.glb";
    const Shape& s = shape(root / "meshes", spec.mesh);
    if (index % 2 == 0) {  // a corner pressed, the cube rocking about it
      const Vector3d corner = -Vector3d::Ones().normalized();
      const Quaterniond q_base = AngleAxisd(rng.uniform(0, 360) * kDeg, Vector3d::UnitZ()) *
                                 rotation_between(corner, -Vector3d::UnitZ());
      const ContactMode m{"corner", q_base};
      spec.family = "corner_rock";
      spec.depth = depth_in(0.5, 1.5) * kMm;
      spec.motion = sweep_motion(q_base, mode_pivot(s, m), centre,
                                 {sweep(Vector3d::UnitX(), 5, 15),
                                  {Vector3d::UnitY(), rng.uniform(5, 15) * kDeg,
                                   rng.uniform(0, 2 * kPi)}},
                                 cycles, spec.frames);
    } else {  // an edge along the gel's long axis pressed, the cube turning about it
      const Vector3d edge = Vector3d(-1, 0, -1).normalized();
      const Quaterniond q_base = AngleAxisd(yaw0, Vector3d::UnitZ()) *
                                 rotation_between(edge, -Vector3d::UnitZ());
      const ContactMode m{"edge", q_base};
      spec.family = "edge_rotate";
      spec.depth = depth_in(0.5, 1.2) * kMm;
      spec.motion = sweep_motion(q_base, mode_pivot(s, m), centre,
                                 {sweep(q_base * Vector3d::UnitY(), 5, 15)}, cycles, spec.frames);
    }
    return spec;
  }
  // toy_brick and toy_human: yaw sweeps (even NN) and roll sweeps (odd NN) over contact modes.
  const bool brick = object == "toy_brick";
  spec.mesh = object + ".glb";
  const Shape& s = shape(root / "meshes", spec.mesh);
  const ContactMode m = brick ? brick_mode((index / 2) % 2, yaw0, rng)
                              : human_mode((index / 2) % 3, yaw0);
  const bool yaw = index % 2 == 0;
  const Sweep sw = yaw ? sweep(Vector3d::UnitZ(), 5, 20)
                       : sweep(m.roll_axis_world, 5, m.max_roll / kDeg);
  spec.family = std::string(yaw ? "yaw_sweep" : "roll_sweep") + " (" + m.name + ")";
  spec.depth = depth_in(0.5, m.max_depth / kMm) * kMm;
  spec.motion = sweep_motion(m.q_base, mode_pivot(s, m), m.centre_scale * centre, {sw}, cycles,
                             spec.frames);
  return spec;
}

// ------------------------------------------------------------------------- the demo and examples

// What a sensor should see at a frame.
enum class Expect { kContact, kNone, kEither };
using Expectation = std::function<Expect(const std::string& sensor, int frame)>;
Expect always_contact(const std::string&, int) { return Expect::kContact; }

SceneSpec default_spec(const fs::path& root) {
  SceneSpec spec;
  spec.file = "scenes/default.json";
  spec.object = "cube";
  spec.mesh = "cube.glb";
  spec.family = "corner_rock";
  spec.frames = 60;
  spec.seed = scene_seed("default");
  const Quaterniond q_base =
      rotation_between(-Vector3d::Ones().normalized(), -Vector3d::UnitZ());
  const Vector3d pivot = mode_pivot(shape(root / "meshes", spec.mesh), {"corner", q_base});
  spec.motion = sweep_motion(q_base, pivot, Vector2d::Zero(),
                             {{Vector3d::UnitX(), 10 * kDeg, 0.0},
                              {Vector3d::UnitY(), 10 * kDeg, kPi / 2}},
                             1.0, spec.frames);
  return spec;
}

// A constant pose with the object's lowest point `depth` below the gel (negative: above it).
ordered_json pressed_pose(const Shape& s, const Vector2d& xy, double depth) {
  const pg::GelModel gel = pg::sensor_preset("digit").gel;
  Vector3d t(xy.x(), xy.y(), 0.0);
  t.z() = round_to(pg::measure_press(s.points, pg::SE3::Translation(t), gel).depth_m - depth, 1e7);
  return {{"position", vec_json(t)}, {"rpy", vec_json(Vector3d::Zero())}};
}

ordered_json sphere_press_json(const fs::path& root) {
  const Shape& s = shape(root / "meshes", "sphere_r6mm.glb");
  ordered_json object = {{"name", "sphere"},
                         {"mesh", "../../meshes/sphere_r6mm.glb"},
                         {"pose", pressed_pose(s, Vector2d::Zero(), 1.0 * kMm)}};
  return scene_json(10, kOneDigit, std::move(object), scene_seed("sphere_press"));
}

// A corner grasp: sensor 0 under the 20 mm cube, sensor 1 at its +x side (its z axis along -x),
// each pressed 0.6 mm into a face. The cube shifts by up to 0.2 mm toward or from either gel and
// turns by up to 0.02 rad about each axis; the side sensor lets go (backs off 3 mm) over frames
// 25-41 and grasps again. Each face alone leaves a slide and the turn about its normal free;
// together they leave only the slide along y (tracking several sensors: docs/tracker.md).
ordered_json two_digits_regrasp_json() {
  const double press = 0.6 * kMm, cube = 20.0 * kMm;
  // The cube's centre height and the side gel's x at the start.
  const double c = round_to(0.5 * cube - press, 1e7);
  const Vector3d side_rpy(0, -kPi / 2, 0);
  ordered_json side = ordered_json::array();
  for (const auto& [frame, away] : std::vector<std::pair<int, double>>{
           {0, 0}, {24, 0}, {30, 3 * kMm}, {36, 3 * kMm}, {42, 0}, {59, 0}}) {
    side.push_back({{"frame", frame},
                    {"position", vec_json({round_to(c + away, 1e7), 0, c})},
                    {"rpy", vec_json(side_rpy)}});
  }
  ordered_json sensors = {
      {{"name", "digit_below"}, {"sensor", "digit"}},
      {{"name", "digit_side"}, {"sensor", "digit"}, {"trajectory", {{"waypoints", side}}}}};
  const struct {
    int frame;
    Vector3d shift;  // from the start [m]
    Vector3d rpy;
  } keys[] = {{0, {0, 0, 0}, {0, 0, 0}},
              {20, {0.2 * kMm, 0, -0.1 * kMm}, {0.01, 0.02, 0.01}},
              {40, {0.1 * kMm, 0, -0.2 * kMm}, {-0.01, -0.01, 0.02}},
              {59, {-0.2 * kMm, 0, 0.1 * kMm}, {0, 0, 0}}};
  ordered_json waypoints = ordered_json::array();
  for (const auto& k : keys) {
    const Vector3d t = Vector3d(0, 0, c) + k.shift;
    waypoints.push_back(
        {{"frame", k.frame},
         {"position", vec_json({round_to(t.x(), 1e7), round_to(t.y(), 1e7), round_to(t.z(), 1e7)})},
         {"rpy", vec_json(k.rpy)}});
  }
  ordered_json object = {{"name", "cube"},
                         {"mesh", "../../meshes/cube.glb"},
                         {"trajectory", {{"waypoints", waypoints}}}};
  return scene_json(60, std::move(sensors), std::move(object), scene_seed("two_digits_regrasp"));
}

// The side sensor of two_digits_regrasp_json is clear of the cube from frame 30 to 36, in
// contact up to 24 and from 42 on.
Expect regrasp_expectation(const std::string& sensor, int frame) {
  if (sensor != "digit_side" || frame <= 24 || frame >= 42) return Expect::kContact;
  return frame >= 30 && frame <= 36 ? Expect::kNone : Expect::kEither;
}

ordered_json no_contact_json(const fs::path& root) {
  const Shape& s = shape(root / "meshes", "cube.glb");
  ordered_json object = {{"name", "cube"},
                         {"mesh", "../../meshes/cube.glb"},
                         {"pose", pressed_pose(s, Vector2d::Zero(), -5.0 * kMm)}};
  return scene_json(5, kOneDigit, std::move(object), scene_seed("no_contact"));
}

// Sensor 1 faces sensor 0 (turned 180 deg about x) 20 mm - 2 x 0.8 mm above it; the 20 mm cube
// between them presses 0.8 mm into each gel while sliding 2 mm along x.
ordered_json two_digits_pinch_json() {
  const double press = 0.8 * kMm, cube = 20.0 * kMm;
  ordered_json sensors = {
      {{"name", "digit_bottom"}, {"sensor", "digit"}},
      {{"name", "digit_top"},
       {"sensor", "digit"},
       {"pose", {{"position", vec_json({0, 0, round_to(cube - 2 * press, 1e7)})}, {"rpy", vec_json({kPi, 0, 0})}}}}};
  const double z = round_to(0.5 * cube - press, 1e7);
  ordered_json waypoints = {
      {{"frame", 0}, {"position", vec_json({-1 * kMm, 0, z})}, {"rpy", vec_json({0, 0, 0})}},
      {{"frame", 29}, {"position", vec_json({1 * kMm, 0, z})}, {"rpy", vec_json({0, 0, 0})}}};
  ordered_json object = {{"name", "cube"},
                         {"mesh", "../../meshes/cube.glb"},
                         {"trajectory", {{"waypoints", waypoints}}}};
  return scene_json(30, std::move(sensors), std::move(object), scene_seed("two_digits_pinch"));
}

// The demo's cube motion against the sensor, with the cube held by a sensor that swings by
// 20 mm and rocks by 0.5 rad about its z axis and 0.6 rad about x twice a second (a waypoint
// every 3 frames): in-hand manipulation with a moving hand ("held_by").
ordered_json held_in_hand_json(const fs::path& root) {
  SceneSpec spec = default_spec(root);
  spec.file = "scenes/examples/held_in_hand.json";
  spec.seed = scene_seed("held_in_hand");
  ordered_json j = sequence_json(spec, root);
  ordered_json waypoints = ordered_json::array();
  for (int f = 0; f <= spec.frames; f += 3) {
    const double w = 2 * kPi * f / 30.0;
    const Vector3d t(round_to(0.02 * std::sin(w), 1e7), round_to(0.01 * (1 - std::cos(w)), 1e7),
                     0.0);
    const Vector3d rpy(round_to(0.3 * (1 - std::cos(w)), 1e6), 0.0,
                       round_to(0.5 * std::sin(w), 1e6));
    waypoints.push_back({{"frame", f}, {"position", vec_json(t)}, {"rpy", vec_json(rpy)}});
  }
  j["sensors"][0]["trajectory"] = {{"waypoints", waypoints}};
  j["objects"][0]["held_by"] = j["sensors"][0]["name"];
  return j;
}

// ------------------------------------------------------------------------- learned-normals data

// The learned-normals training and validation sets (the paper's Table I, and the default
// model's extra training shapes): every frame an independent press of the object in a random
// orientation, its lowest point at a random place of the visible gel, 0.3-1.5 mm deep. Rendered
// on the elastic DIGIT gel with shadows and noise (scripts/train_normals.sh adds the real
// background for Table I), so the network sees the non-ideal effects of a real sensor.
ordered_json random_presses_json(const fs::path& root, const std::string& object,
                                 const std::string& mesh, const std::string& file, int frames) {
  const Shape& s = shape(root / "meshes", mesh);
  const std::string name = fs::path(file).stem().string();
  pg::RandomPressOptions options;
  options.frames = frames;
  options.target_half_m = Vector2d(4, 5) * kMm;
  options.contact_half_m = 0.9 * Vector2d(kVisibleX, kVisibleY);
  options.seed = scene_seed(name);
  ordered_json waypoints = ordered_json::array();
  for (const pg::Waypoint& w :
       pg::random_presses(s.points, pg::sensor_preset("digit").gel, options)) {
    waypoints.push_back(
        {{"frame", w.frame}, {"position", vec_json(w.position_m)}, {"rpy", vec_json(w.rpy_rad)}});
  }
  ordered_json object_json = {{"name", object},
                              {"mesh", relative_mesh(file, "meshes/" + mesh)},
                              {"trajectory", {{"waypoints", waypoints}}}};
  ordered_json scene = scene_json(frames, kOneDigit, std::move(object_json), scene_seed(name));
  scene["render"]["shadows"] = true;
  return scene;
}

// ------------------------------------------------------------------------- checking and writing

struct CheckSummary {
  double min_depth = std::numeric_limits<double>::infinity();
  double max_depth = -std::numeric_limits<double>::infinity();
  Vector2d max_abs_xy = Vector2d::Zero();
};

[[noreturn]] void fail(const std::string& file, int frame, const std::string& what) {
  throw std::runtime_error(file + ": frame " + std::to_string(frame) + ": " + what);
}

// Loads the scene text exactly as written (through the scene loader) and checks every frame in
// every sensor: contact 0.2-2.0 mm deep inside the visible gel, or none, as `expect` says.
CheckSummary check_scene(const std::string& file, const std::string& text, const fs::path& root,
                         const Expectation& expect) {
  const fs::path path = root / file;
  const pg::Scene scene = pg::scene_from_json(pg::parse_json_text(text, file), file,
                                              path.parent_path().string());
  CheckSummary sum;
  for (int f = 0; f < scene.frames; ++f) {
    for (const pg::SceneSensor& sensor : scene.sensors) {
      pg::PressContact c;
      for (const pg::SceneObject& o : scene.objects) {
        const Shape& s = shape(fs::path(o.mesh_path).parent_path(),
                               fs::path(o.mesh_path).filename().string());
        const pg::SE3 T_sensor_object = sensor.T_world_sensor.at(f).inverse() *
                                        o.T_world_object.at(f);
        const pg::PressContact oc = pg::measure_press(s.points, T_sensor_object, sensor.model.gel);
        c.depth_m = std::max(c.depth_m, oc.depth_m);
        c.max_abs_xy_m = c.max_abs_xy_m.cwiseMax(oc.max_abs_xy_m);
      }
      const std::string at = sensor.name + ": deepest point " + std::to_string(c.depth_m / kMm) +
                             " mm below the gel surface";
      const Expect e = expect(sensor.name, f);
      if (e == Expect::kNone && c.depth_m >= 0.0) fail(file, f, at + ", expected no contact");
      if (e == Expect::kContact && (c.depth_m < kMinDepth || c.depth_m > kMaxDepth)) {
        fail(file, f, at + " (allowed 0.2-2.0 mm)");
      }
      if (c.max_abs_xy_m.x() >= kVisibleX || c.max_abs_xy_m.y() >= kVisibleY) {
        fail(file, f,
             sensor.name + ": contact reaches |x| = " + std::to_string(c.max_abs_xy_m.x() / kMm) +
                 " mm, |y| = " + std::to_string(c.max_abs_xy_m.y() / kMm) +
                 " mm (visible: |x| < 8 mm, |y| < 10 mm)");
      }
      sum.min_depth = std::min(sum.min_depth, c.depth_m);
      sum.max_depth = std::max(sum.max_depth, c.depth_m);
      sum.max_abs_xy = sum.max_abs_xy.cwiseMax(c.max_abs_xy_m);
    }
  }
  return sum;
}

struct Output {
  std::string file;
  std::string text;
};

Output checked(const std::string& file, const ordered_json& j, const fs::path& root,
               const std::string& family, double depth,
               const Expectation& expect = always_contact) {
  const std::string text = pg::format_json(j) + "\n";
  const CheckSummary sum = check_scene(file, text, root, expect);
  std::printf("%-36s %-28s press %5.2f mm  depth %5.2f..%5.2f mm  contact |x| %4.1f |y| %4.1f mm\n",
              file.c_str(), family.c_str(), depth / kMm, sum.min_depth / kMm,
              sum.max_depth / kMm, sum.max_abs_xy.x() / kMm, sum.max_abs_xy.y() / kMm);
  return {file, text};
}

std::vector<Output> make_all(const fs::path& root) {
  std::vector<Output> outputs;
  for (const std::string object : {"sphere", "cube", "toy_brick", "toy_human"}) {
    for (int i = 0; i < 20; ++i) {
      const SceneSpec spec = benchmark_spec(object, i, root);
      outputs.push_back(checked(spec.file, sequence_json(spec, root), root, spec.family,
                                spec.depth));
    }
  }
  const SceneSpec demo = default_spec(root);
  outputs.push_back(checked(demo.file, sequence_json(demo, root), root, demo.family, demo.depth));
  outputs.push_back(checked("scenes/examples/sphere_press.json", sphere_press_json(root), root,
                            "static press", 1.0 * kMm));
  outputs.push_back(checked("scenes/examples/two_digits_pinch.json", two_digits_pinch_json(),
                            root, "pinch slide", 0.8 * kMm));
  outputs.push_back(checked("scenes/examples/two_digits_regrasp.json", two_digits_regrasp_json(),
                            root, "corner grasp, side regrasp", 0.6 * kMm, regrasp_expectation));
  outputs.push_back(checked("scenes/examples/no_contact.json", no_contact_json(root), root, "hover",
                            -5.0 * kMm, [](const std::string&, int) { return Expect::kNone; }));
  outputs.push_back(checked("scenes/examples/held_in_hand.json", held_in_hand_json(root), root,
                            "corner rock, swinging hand", demo.depth));
  struct NormalsSet {
    const char* object;
    const char* mesh;
    const char* split;
    int frames;
  };
  for (const NormalsSet& n : {NormalsSet{"sphere", "sphere_r6mm.glb", "train", 50},
                              NormalsSet{"cube", "cube.glb", "train", 50},
                              NormalsSet{"sphere", "sphere_r6mm.glb", "val", 20},
                              NormalsSet{"cube", "cube.glb", "val", 20},
                              NormalsSet{"toy_brick", "toy_brick.glb", "val", 20},
                              NormalsSet{"toy_human", "toy_human.glb", "val", 20},
                              // The default model's extra training shapes (never the toy brick or
                              // the toy human, the benchmark's unseen objects).
                              NormalsSet{"stud", "stud_r3mm.glb", "train", 50},
                              NormalsSet{"torus", "torus_r5mm.glb", "train", 50},
                              NormalsSet{"ellipsoid", "ellipsoid.glb", "train", 50},
                              NormalsSet{"plate", "rounded_plate.glb", "train", 50},
                              // Ball-bearing presses, the calibration a real sensor's labels
                              // come from (patchgraph label-ball; docs/learned_normals.md).
                              NormalsSet{"ball", "ball_bearing_0p5in.glb", "train", 50},
                              NormalsSet{"ball", "ball_bearing_0p5in.glb", "val", 20}}) {
    const std::string file = std::string("scenes/normals/") + n.object + "_" + n.split + ".json";
    outputs.push_back(checked(file, random_presses_json(root, n.object, n.mesh, file, n.frames),
                              root, "random presses", 0.0));
  }
  return outputs;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app(
      "Writes the repository's generated scenes (scenes/default.json, examples/, benchmark/, "
      "normals/) under REPO_ROOT/scenes, byte for byte; reads REPO_ROOT/meshes",
      "make_scenes");
  std::string root_arg;
  app.add_option("repo_root", root_arg, "The repository's root folder")->required();
  return pg::run_cli(app, argc, argv, [&] {
    const fs::path root = root_arg;
    // Everything is generated and checked before the first file is written.
    for (const Output& o : make_all(root)) {
      const fs::path path = root / o.file;
      fs::create_directories(path.parent_path());
      pg::write_text_file(path.string(), o.text);
    }
    return pg::kExitOk;
  });
}
