#include "tracker_test_util.h"

#include <algorithm>
#include <map>

#include "pg/sim/mesh.h"

namespace pg::test {

double gel_depth(const SensorModel& sensor, int x, int y) {
  const auto& cam = sensor.camera;
  const Eigen::Vector3d d = cam.ray(x, y);
  auto f = [&](double t) { return t - cam.distance_m - sensor.gel.surface_z(d.x() * t, d.y() * t); };
  double lo = cam.distance_m - 2 * sensor.gel.sag_m - 1e-3, hi = cam.distance_m + 1e-3;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) < 0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Eigen::Vector3d gel_normal(const SensorModel& sensor, int x, int y) {
  const double t = gel_depth(sensor, x, y);
  const Eigen::Vector3d p = sensor.camera.ray(x, y) * t;
  const double h = 1e-6;
  const auto& g = sensor.gel;
  const double zx = (g.surface_z(p.x() + h, p.y()) - g.surface_z(p.x() - h, p.y())) / (2 * h);
  const double zy = (g.surface_z(p.x(), p.y() + h) - g.surface_z(p.x(), p.y() - h)) / (2 * h);
  return Eigen::Vector3d(-zx, -zy, 1.0).normalized();
}

AnalyticFrame analytic_sphere_frame(const SensorModel& sensor, const Eigen::Vector3d& c_sensor,
                                    double radius_m) {
  const auto& cam = sensor.camera;
  AnalyticFrame f;
  f.normal = ImageF(cam.width, cam.height, 3);
  f.reference = ImageF(cam.width, cam.height, 3);
  f.depth = ImageF(cam.width, cam.height, 1, 0.0f);
  const Eigen::Vector3d o(0, 0, -cam.distance_m);
  for (int y = 0; y < cam.height; ++y) {
    for (int x = 0; x < cam.width; ++x) {
      const Eigen::Vector3d d = cam.ray(x, y);
      const double t_gel = gel_depth(sensor, x, y);
      const Eigen::Vector3d n_gel = gel_normal(sensor, x, y);
      Eigen::Vector3d n = n_gel;
      // First intersection of o + d t with the sphere.
      const Eigen::Vector3d oc = o - c_sensor;
      const double a = d.squaredNorm(), b = 2 * d.dot(oc), c = oc.squaredNorm() - radius_m * radius_m;
      const double disc = b * b - 4 * a * c;
      if (disc > 0) {
        const double t = (-b - std::sqrt(disc)) / (2 * a);
        if (t < t_gel) {
          const Eigen::Vector3d p = o + d * t;
          n = (c_sensor - p).normalized();  // out of the gel = into the sphere
          f.depth.at(x, y) = float(t_gel - t);
        }
      }
      for (int k = 0; k < 3; ++k) {
        f.normal.at(x, y, k) = float(n[k]);
        f.reference.at(x, y, k) = float(n_gel[k]);
      }
    }
  }
  return f;
}

RenderCase make_render_case(const std::string& preset, std::shared_ptr<const ObjectShape> shape) {
  return make_render_case(sensor_preset(preset), std::move(shape));
}

RenderCase make_render_case(const SensorModel& sensor, std::shared_ptr<const ObjectShape> shape) {
  RenderCase rc;
  rc.sensor = sensor;
  rc.sensor.gel.elastic.enabled = false;
  rc.sensor.gel.max_indentation_m = 0.004;
  rc.shape = shape;
  RenderSettings s;
  s.noise = false;
  s.color = false;
  rc.renderer = std::make_unique<SensorRenderer>(rc.sensor, std::vector{shape}, s);
  return rc;
}

RenderedFrame render(const RenderCase& rc, const SE3& T_sensor_object) {
  return rc.renderer->render({T_sensor_object}, 0);
}

std::shared_ptr<const ObjectShape> mesh_shape(const std::string& file_in_meshes) {
  static std::map<std::string, std::shared_ptr<const ObjectShape>> cache;
  auto& s = cache[file_in_meshes];
  if (!s) s = std::make_shared<ObjectShape>(load_mesh(std::string(PG_SOURCE_DIR) + "/meshes/" + file_in_meshes));
  return s;
}

SE3 press_pose(const Eigen::Vector3d& tip_object, const Eigen::Vector3d& direction_object,
               double press_m, double roll_rad) {
  // Rotate the tip direction onto -z of S (into the gel, toward the camera), then roll about z.
  const Eigen::Quaterniond q_align =
      Eigen::Quaterniond::FromTwoVectors(direction_object.normalized(), Eigen::Vector3d(0, 0, -1));
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(Eigen::AngleAxisd(roll_rad, Eigen::Vector3d::UnitZ())) * q_align;
  const Eigen::Vector3d tip_sensor(0, 0, -press_m);
  return SE3(q, tip_sensor - q * tip_object);
}

namespace {

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + ab * (d1 / (d1 - d3));
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + ac * (d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
  }
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

}  // namespace

std::vector<double> distances_to_mesh(const TriangleMesh& mesh,
                                      const std::vector<Eigen::Vector3f>& points_object) {
  std::vector<double> out;
  if (points_object.empty()) return out;
  Eigen::Vector3f lo = points_object[0], hi = points_object[0];
  for (const auto& p : points_object) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const float pad = 0.5e-3f;
  lo.array() -= pad;
  hi.array() += pad;
  std::vector<Eigen::Vector3i> near;
  for (const auto& t : mesh.triangles) {
    Eigen::Vector3f tlo = mesh.vertices[t[0]], thi = tlo;
    for (int k = 1; k < 3; ++k) {
      tlo = tlo.cwiseMin(mesh.vertices[t[k]]);
      thi = thi.cwiseMax(mesh.vertices[t[k]]);
    }
    if ((tlo.array() <= hi.array()).all() && (thi.array() >= lo.array()).all()) near.push_back(t);
  }
  out.reserve(points_object.size());
  for (const auto& pf : points_object) {
    const Eigen::Vector3d p = pf.cast<double>();
    double best = INFINITY;
    for (const auto& t : near) {
      const Eigen::Vector3d q = closest_on_triangle(p, mesh.vertices[t[0]].cast<double>(),
                                                    mesh.vertices[t[1]].cast<double>(),
                                                    mesh.vertices[t[2]].cast<double>());
      best = std::min(best, (p - q).squaredNorm());
    }
    out.push_back(std::sqrt(best));
  }
  return out;
}

double rms(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return v.empty() ? 0.0 : std::sqrt(s / v.size());
}

}  // namespace pg::test
