#include "pg/sim/presses.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "pg/core/error.h"
#include "pg/core/gel_rays.h"
#include "pg/core/json_fields.h"
#include "pg/core/random.h"
#include "pg/core/se3.h"
#include "pg/sim/mesh_sampling.h"

namespace pg {
namespace {

// A triangle's grid divisions: each edge in pieces of at most `spacing`.
int grid_divisions(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                   double spacing) {
  const double longest = std::max({(b - a).norm(), (c - b).norm(), (a - c).norm()});
  return std::max(1, int(std::ceil(longest / spacing)));
}

}  // namespace

std::size_t surface_grid_size(const TriangleMesh& mesh, double spacing_m) {
  check_sample_spacing(spacing_m, "surface_grid_size");
  std::size_t count = 0;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const std::size_t n = std::size_t(
        grid_divisions(mesh.vertices[t[0]].cast<double>(), mesh.vertices[t[1]].cast<double>(),
                       mesh.vertices[t[2]].cast<double>(), spacing_m));
    count += (n + 1) * (n + 2) / 2;
  }
  return count;
}

std::vector<Eigen::Vector3d> surface_grid(const TriangleMesh& mesh, double spacing_m) {
  check_sample_spacing(spacing_m, "surface_grid");
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[t[2]].cast<double>();
    const int n = grid_divisions(a, b, c, spacing_m);
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; i + j <= n; ++j) points.push_back(a + (b - a) * i / n + (c - a) * j / n);
    }
  }
  return points;
}

PressContact measure_press(const std::vector<Eigen::Vector3d>& p_object, const SE3& T_sensor_object,
                           const GelModel& gel) {
  PressContact contact;
  for (const Eigen::Vector3d& p : p_object) {
    const Eigen::Vector3d p_sensor = T_sensor_object * p;
    // surface_z <= 0, so -z bounds the penetration: skip points that can neither penetrate nor
    // be the deepest.
    if (-p_sensor.z() <= std::min(contact.depth_m, 0.0)) continue;
    const double depth = gel.surface_z(p_sensor.x(), p_sensor.y()) - p_sensor.z();
    contact.depth_m = std::max(contact.depth_m, depth);
    if (depth > 0.0) {
      contact.max_abs_xy_m = contact.max_abs_xy_m.cwiseMax(p_sensor.head<2>().cwiseAbs());
      contact.min_xy_m = contact.min_xy_m.cwiseMin(p_sensor.head<2>());
      contact.max_xy_m = contact.max_xy_m.cwiseMax(p_sensor.head<2>());
    }
  }
  return contact;
}

Eigen::Vector3d extreme_centroid(const std::vector<Eigen::Vector3d>& points,
                                 const Eigen::Vector3d& direction, double z_lo, double z_hi) {
  double best = -std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& p : points) {
    if (p.z() >= z_lo && p.z() <= z_hi) best = std::max(best, p.dot(direction));
  }
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int count = 0;
  for (const Eigen::Vector3d& p : points) {
    if (p.z() >= z_lo && p.z() <= z_hi && p.dot(direction) > best - 1e-4) {
      sum += p;
      ++count;
    }
  }
  if (count == 0) throw std::runtime_error("extreme_centroid: no points in the z band");
  return sum / count;
}

std::vector<Waypoint> random_presses(const std::vector<Eigen::Vector3d>& p_object,
                                     const GelModel& gel, const RandomPressOptions& options,
                                     const std::function<void(int done)>& on_frame) {
  if (p_object.empty()) throw InputError("random presses: the object has no surface points");
  // Options the command line could not give: no attempt at all had searched for ever, a NaN
  // centre had passed every test and placed the press at x = NaN.
  const bool finite = options.centre_m.allFinite() && options.target_half_m.allFinite() &&
                      options.contact_half_m.allFinite() && std::isfinite(options.min_depth_m) &&
                      std::isfinite(options.max_depth_m);
  if (!finite || options.attempts < 1 || options.frames < 0 || !(options.min_depth_m > 0) ||
      options.min_depth_m > options.max_depth_m || options.target_half_m.minCoeff() < 0 ||
      options.contact_half_m.minCoeff() <= 0) {
    throw InputError(
        "random presses: options out of range (attempts at least 1, frames not negative, depths "
        "finite with 0 < min_depth_m <= max_depth_m, the areas' half sizes finite, target_half_m "
        "not negative and contact_half_m positive)");
  }
  const double inf = std::numeric_limits<double>::infinity();
  Random rng(options.seed);
  std::vector<Waypoint> presses;
  for (int f = 0; f < options.frames; ++f) {
    for (int attempt = 0;; ++attempt) {
      if (attempt == options.attempts) {
        char text[256];
        std::snprintf(text, sizeof text,
                      "frame %d: no press of the object stays inside |x| < %.2f mm, |y| < %.2f "
                      "mm (the visible gel) in %d random orientations: is it too large for the "
                      "sensor, or its scale wrong?",
                      f, 1e3 * options.contact_half_m.x(), 1e3 * options.contact_half_m.y(),
                      options.attempts);
        throw InputError(text);
      }
      // Uniform random rotation (Shoemake), rounded as the file stores it.
      const double u1 = rng.uniform(0, 1), u2 = rng.uniform(0, 2 * kPi);
      const double u3 = rng.uniform(0, 2 * kPi);
      const Eigen::Quaterniond q_random(
          std::sqrt(u1) * std::cos(u3), std::sqrt(1 - u1) * std::sin(u2),
          std::sqrt(1 - u1) * std::cos(u2), std::sqrt(u1) * std::sin(u3));
      Eigen::Vector3d rpy = rpy_from_quaternion(q_random.normalized());
      for (int i = 0; i < 3; ++i) rpy[i] = round_to(rpy[i], 1e6);
      const Eigen::Quaterniond q = quaternion_from_rpy(rpy);
      const Eigen::Vector2d target(
          options.centre_m.x() + rng.uniform(-options.target_half_m.x(), options.target_half_m.x()),
          options.centre_m.y() +
              rng.uniform(-options.target_half_m.y(), options.target_half_m.y()));
      const double depth = rng.uniform(options.min_depth_m, options.max_depth_m);
      const Eigen::Vector3d lowest =
          extreme_centroid(p_object, q.inverse() * -Eigen::Vector3d::UnitZ(), -inf, inf);
      Eigen::Vector3d t;
      t.head<2>() = target - (q * lowest).head<2>();
      t.z() = 0.0;
      t.z() = measure_press(p_object, SE3(q, t), gel).depth_m - depth;
      for (int i = 0; i < 3; ++i) t[i] = round_to(t[i], 1e7);
      const PressContact c = measure_press(p_object, SE3(q, t), gel);
      const Eigen::Vector2d reach =
          (c.max_xy_m - options.centre_m).cwiseMax(options.centre_m - c.min_xy_m);
      if (std::abs(c.depth_m - depth) > 5e-5 || reach.x() > options.contact_half_m.x() ||
          reach.y() > options.contact_half_m.y()) {
        continue;
      }
      presses.push_back({f, t, rpy});
      break;
    }
    if (on_frame) on_frame(f + 1);
  }
  return presses;
}

GelArea visible_gel_area(const SensorModel& sensor) {
  // fx = 0 had read the whole gel as seen.
  check_sensor_model(sensor, "visible_gel_area: sensor " + sensor.name);
  const int w = sensor.camera.width, h = sensor.camera.height;
  const auto p = [&](int x, int y) {
    return undeformed_gel_point(sensor.camera, sensor.gel, x, y);
  };
  // Inside every row's first and last pixel, and every column's.
  Eigen::Vector2d lo(-0.5 * sensor.gel.width_m, -0.5 * sensor.gel.height_m), hi = -lo;
  for (int y = 0; y < h; ++y) {
    const double a = p(0, y).x(), b = p(w - 1, y).x();
    lo.x() = std::max(lo.x(), std::min(a, b));
    hi.x() = std::min(hi.x(), std::max(a, b));
  }
  for (int x = 0; x < w; ++x) {
    const double a = p(x, 0).y(), b = p(x, h - 1).y();
    lo.y() = std::max(lo.y(), std::min(a, b));
    hi.y() = std::min(hi.y(), std::max(a, b));
  }
  if (!(hi.x() > lo.x() && hi.y() > lo.y())) {
    throw InputError("sensor " + sensor.name +
                     ": its camera sees none of its gel (is the principal point cx, cy inside "
                     "the image?)");
  }
  return {0.5 * (lo + hi), 0.5 * (hi - lo)};
}

}  // namespace pg
