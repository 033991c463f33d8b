#include "pg/core/gel_rays.h"

#include <algorithm>
#include <cmath>

namespace pg {

namespace {

// The camera depth at which ray d (z = 1) meets the undeformed gel: the ray point at depth t is
// (d.x t, d.y t, t - distance) in S, on the gel when z = surface_z(x, y); iterates
// z <- surface_z(d (z + distance)).
double gel_depth(const Eigen::Vector3d& d, const CameraModel& camera, const GelModel& gel) {
  // The surface's z where the ray is at z (camera depth z + distance).
  const auto surface_at = [&](double z) {
    const double t = z + camera.distance_m;
    return gel.surface_z(d.x() * t, d.y() * t);
  };
  // The fixed point z = surface_at(z): converges where the gel's slope along the ray is below 1,
  // as on every preset.
  double z = 0.0;
  for (int it = 0; it < 50; ++it) {
    const double z_next = surface_at(z);
    const bool done = std::abs(z_next - z) < 1e-13;
    z = z_next;
    if (done) return z + camera.distance_m;
  }
  // A strongly curved gel seen at a grazing angle, where the iteration swings: the ray's first
  // crossing of the surface from the near plane on, bracketed on a grid and bisected. In front
  // of the surface surface_at(z) > z; the surface is never nearer than the near plane.
  const auto ahead = [&](double zz) { return surface_at(zz) > zz; };
  constexpr int kSteps = 1024;
  const double z_near = camera.near_m - camera.distance_m;
  double a = z_near;
  for (int k = 1; k <= kSteps; ++k) {
    double b = z_near * (1.0 - double(k) / kSteps);
    if (ahead(b)) {
      a = b;
      continue;
    }
    for (int it = 0; it < 80; ++it) {
      const double m = 0.5 * (a + b);
      (ahead(m) ? a : b) = m;
    }
    return 0.5 * (a + b) + camera.distance_m;
  }
  return z + camera.distance_m;
}

}  // namespace

GelRays make_gel_rays(const CameraModel& camera, const GelModel& gel) {
  GelRays rays;
  rays.width = camera.width;
  rays.height = camera.height;
  rays.fx = camera.fx;
  rays.fy = camera.fy;
  rays.px_per_m = camera.px_per_m_at_gel();
  rays.origin_sensor = Eigen::Vector3f(0.0f, 0.0f, float(-camera.distance_m));
  const std::size_t n = std::size_t(camera.width) * camera.height;
  rays.dir_sensor.resize(n);
  rays.t_gel.resize(n);
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector3d d = camera.ray(x, y);
      const int i = rays.index(x, y);
      rays.dir_sensor[i] = d.cast<float>();
      rays.t_gel[i] = float(gel_depth(d, camera, gel));
    }
  }
  return rays;
}

Eigen::Vector3d undeformed_gel_point(const CameraModel& camera, const GelModel& gel, double x,
                                     double y) {
  const Eigen::Vector3d d = camera.ray(x, y);
  return d * gel_depth(d, camera, gel) - Eigen::Vector3d(0, 0, camera.distance_m);
}

Eigen::Vector2d view_beyond_gel(const CameraModel& camera, const GelModel& gel) {
  Eigen::Vector2d beyond = Eigen::Vector2d::Zero();
  const double half_w = 0.5 * gel.width_m, half_h = 0.5 * gel.height_m;
  const auto reach = [&](int x, int y) {
    // Where the ray meets the gel's surface, continued past its edges at the edge's height: the
    // dome's formula beyond the gel is no surface (a wide camera's corner rays met it hundreds of
    // millimetres out). z <- surface_z(the ray's point at z, held to the gel's rectangle).
    const Eigen::Vector3d d = camera.ray(x, y);
    double z = 0.0;
    for (int it = 0; it < 100; ++it) {
      const double t = z + camera.distance_m;
      const double z_next = gel.surface_z(std::clamp(d.x() * t, -half_w, half_w),
                                          std::clamp(d.y() * t, -half_h, half_h));
      const bool done = std::abs(z_next - z) < 1e-13;
      z = z_next;
      if (done) break;
    }
    const double t = z + camera.distance_m;
    beyond.x() = std::max(beyond.x(), std::abs(d.x() * t) - half_w);
    beyond.y() = std::max(beyond.y(), std::abs(d.y() * t) - half_h);
  };
  // The ray's x grows with the column and its y with the row: the image's border reaches
  // farthest.
  for (int x = 0; x < camera.width; ++x) reach(x, 0), reach(x, camera.height - 1);
  for (int y = 0; y < camera.height; ++y) reach(0, y), reach(camera.width - 1, y);
  return beyond;
}

ImageF sphere_indentation(const GelRays& rays, const Eigen::Vector3d& centre, double radius) {
  ImageF u(rays.width, rays.height, 1, 0.0f);
  const Eigen::Vector3d oc = rays.origin_sensor.cast<double>() - centre;
  for (int i = 0; i < rays.width * rays.height; ++i) {
    // |o + d t - c|^2 = r^2: a t^2 + 2 b t + c = 0, the near root.
    const Eigen::Vector3d d = rays.dir_sensor[std::size_t(i)].cast<double>();
    const double a = d.squaredNorm(), b = d.dot(oc), c = oc.squaredNorm() - radius * radius;
    const double disc = b * b - a * c;
    if (disc <= 0) continue;
    const double t = (-b - std::sqrt(disc)) / a;
    u.data[std::size_t(i)] = float(std::max(0.0, double(rays.t_gel[std::size_t(i)]) - t));
  }
  return u;
}

ImageF gel_normals(const GelRays& rays, const ImageF& indentation) {
  ImageF normals(rays.width, rays.height, 3, 0.0f);
  const auto point = [&](int x, int y) {
    const int i = rays.index(x, y);
    return rays.point(i, indentation.data[std::size_t(i)]);
  };
  for (int y = 0; y < rays.height; ++y) {
    const int ym = std::max(y - 1, 0), yp = std::min(y + 1, rays.height - 1);
    for (int x = 0; x < rays.width; ++x) {
      const int xm = std::max(x - 1, 0), xp = std::min(x + 1, rays.width - 1);
      const Eigen::Vector3f n =
          (point(xp, y) - point(xm, y)).cross(point(x, yp) - point(x, ym)).normalized();
      for (int c = 0; c < 3; ++c) normals.at(x, y, c) = n[c];
    }
  }
  return normals;
}

ImageF undeformed_gel_normals(const GelRays& rays) {
  return gel_normals(rays, ImageF(rays.width, rays.height, 1, 0.0f));
}

}  // namespace pg
