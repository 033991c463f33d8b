// make_meshes OUT_DIR: writes the paper's objects (sim: spheres, cube, toy brick, toy human;
// real: 1/2 inch ball bearing, pyramid) and the extra training shapes of the default normals model
// (a stud-like cylinder, a torus, an ellipsoid, a rounded plate) as GLB files into OUT_DIR. Deterministic: the same build
// writes the same bytes. Units metres; origin at the centre of each object's bounding box; +z up.
//
// Every part is a closed, outward-oriented (counter-clockwise seen from outside) triangle mesh;
// composite objects are unions of such parts, which may overlap (fine for ray casting).
#include <CLI/CLI.hpp>
#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "common/cli_main.h"
#include "pg/core/error.h"
#include "pg/core/se3.h"
#include "pg/sim/mesh.h"

namespace {

constexpr double kMm = 1e-3;
constexpr double kInch = 25.4e-3;

using Eigen::Vector3d;
using pg::kPi;

// A mesh under construction, in double precision.
struct Part {
  std::vector<Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;

  int add(const Vector3d& p) {
    vertices.push_back(p);
    return static_cast<int>(vertices.size()) - 1;
  }
  void triangle(int a, int b, int c) { triangles.emplace_back(a, b, c); }
  void quad(int a, int b, int c, int d) {  // a-b-c-d counter-clockwise seen from outside
    triangle(a, b, c);
    triangle(a, c, d);
  }
  // Adds `part` moved by T (a rigid motion, so orientation is kept) as a separate piece.
  void append(const Part& part, const Eigen::Isometry3d& T = Eigen::Isometry3d::Identity()) {
    const int base = static_cast<int>(vertices.size());
    for (const Vector3d& v : part.vertices) vertices.push_back(T * v);
    for (const Eigen::Vector3i& t : part.triangles)
      triangles.push_back((t.array() + base).matrix());
  }
};

// Icosahedron subdivided `levels` times, projected onto the sphere: 20 * 4^levels triangles.
Part icosphere(double radius, int levels) {
  const double phi = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vector3d> unit = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                                {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                                {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
  for (Vector3d& v : unit) v.normalize();
  std::vector<Eigen::Vector3i> faces = {
      {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoints;  // edge (low, high) -> new vertex
    auto midpoint = [&](int a, int b) {
      const std::pair<int, int> key = std::minmax(a, b);
      const auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      unit.push_back((unit[a] + unit[b]).normalized());
      return midpoints[key] = static_cast<int>(unit.size()) - 1;
    };
    std::vector<Eigen::Vector3i> finer;
    for (const Eigen::Vector3i& f : faces) {
      const int ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]), ca = midpoint(f[2], f[0]);
      finer.insert(finer.end(), {{f[0], ab, ca}, {f[1], bc, ab}, {f[2], ca, bc}, {ab, bc, ca}});
    }
    faces = std::move(finer);
  }
  Part part;
  for (const Vector3d& v : unit) part.add(radius * v);
  part.triangles = faces;
  return part;
}

// Box with half extents `half` whose edges and corners are rounded with radius `r` (> 0): flat
// faces, quarter-cylinder edges, sphere-octant corners. Built on the surface of an integer
// lattice, so vertices shared by neighbouring faces are computed once and the mesh is closed.
// Along each axis the lattice has `round_segments` steps per 45 degrees of rounding at each end
// and flat steps of about `flat_step` in between.
Part rounded_box(const Vector3d& half, double r, int round_segments, double flat_step) {
  // Per axis: lattice index -> (inner-box coordinate c, normal-cone slope t). A surface point is
  // c + r * normalize(t); on a face of the lattice cube the slope is +-1, i.e. 45 degrees, which
  // is where neighbouring faces of the lattice meet on the rounded edge.
  struct Sample {
    double c, t;
  };
  std::vector<Sample> samples[3];
  for (int a = 0; a < 3; ++a) {
    const double inner = half[a] - r;
    const int k = round_segments;
    const int flat = std::max(1, static_cast<int>(std::ceil(2.0 * inner / flat_step)));
    for (int i = 0; i <= k; ++i) {
      samples[a].push_back({-inner, i == 0 ? -1.0 : -std::tan(kPi / 4 * (k - i) / k)});
    }
    for (int i = 1; i < flat; ++i) samples[a].push_back({-inner + 2.0 * inner * i / flat, 0.0});
    for (int i = 0; i <= k; ++i) {
      samples[a].push_back({inner, i == k ? 1.0 : std::tan(kPi / 4 * i / k)});
    }
  }
  Part part;
  std::map<std::array<int, 3>, int> lattice;  // lattice index -> vertex
  auto vertex = [&](const std::array<int, 3>& index) {
    const auto it = lattice.find(index);
    if (it != lattice.end()) return it->second;
    Vector3d c, t;
    for (int a = 0; a < 3; ++a) {
      c[a] = samples[a][index[a]].c;
      t[a] = samples[a][index[a]].t;
    }
    return lattice[index] = part.add(c + r * t.normalized());
  };
  for (int a = 0; a < 3; ++a) {
    const int b = (a + 1) % 3, c = (a + 2) % 3;  // (b, c, a) right-handed: e_b x e_c = e_a
    const int nb = static_cast<int>(samples[b].size()) - 1;
    const int nc = static_cast<int>(samples[c].size()) - 1;
    for (int side : {0, static_cast<int>(samples[a].size()) - 1}) {
      for (int u = 0; u < nb; ++u) {
        for (int v = 0; v < nc; ++v) {
          int q[4];
          const int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
          for (int m = 0; m < 4; ++m) {
            std::array<int, 3> index;
            index[a] = side;
            index[b] = u + du[m];
            index[c] = v + dv[m];
            q[m] = vertex(index);
          }
          if (side > 0) {
            part.quad(q[0], q[1], q[2], q[3]);
          } else {
            part.quad(q[0], q[3], q[2], q[1]);
          }
        }
      }
    }
  }
  return part;
}

// Surface of revolution about +z of a profile of (radius, z) points. An open profile must start
// and end on the axis (radius 0: the poles) and run bottom to top on the outside; a closed
// profile (a loop that stays off the axis, e.g. a torus) must run counter-clockwise in the
// (radius, z) plane. Both give outward-facing triangles.
Part revolve(const std::vector<Eigen::Vector2d>& profile, int segments, bool closed_loop = false) {
  Part part;
  std::vector<std::vector<int>> rings;
  for (const Eigen::Vector2d& rz : profile) {
    std::vector<int> ring;
    if (!closed_loop && rz.x() == 0.0) {
      ring.assign(static_cast<size_t>(segments), part.add({0.0, 0.0, rz.y()}));  // pole
    } else {
      for (int j = 0; j < segments; ++j) {
        const double angle = 2.0 * kPi * j / segments;
        ring.push_back(part.add({rz.x() * std::cos(angle), rz.x() * std::sin(angle), rz.y()}));
      }
    }
    rings.push_back(ring);
  }
  const size_t bands = closed_loop ? rings.size() : rings.size() - 1;
  for (size_t i = 0; i < bands; ++i) {
    const std::vector<int>& lo = rings[i];
    const std::vector<int>& hi = rings[(i + 1) % rings.size()];
    for (int j = 0; j < segments; ++j) {
      const int j1 = (j + 1) % segments;
      if (lo[j] == lo[j1]) {
        part.triangle(lo[j], hi[j1], hi[j]);  // bottom pole
      } else if (hi[j] == hi[j1]) {
        part.triangle(lo[j], lo[j1], hi[j]);  // top pole
      } else {
        part.quad(lo[j], lo[j1], hi[j1], hi[j]);
      }
    }
  }
  return part;
}

// Appends a quarter-circle arc around `centre` from angle a0 to a1 (radians, in the (r, z)
// plane), excluding the start point.
void arc(std::vector<Eigen::Vector2d>& profile, const Eigen::Vector2d& centre, double radius,
         double a0, double a1, int segments) {
  for (int i = 1; i <= segments; ++i) {
    const double a = a0 + (a1 - a0) * i / segments;
    profile.push_back(centre + radius * Eigen::Vector2d(std::cos(a), std::sin(a)));
  }
}

// Closed cylinder of radius R over [z0, z1] along +z; the top and bottom rims are rounded with
// radii `top_fillet` and `bottom_fillet` (0 = sharp).
Part cylinder(double R, double z0, double z1, double bottom_fillet, double top_fillet,
              int segments) {
  const int arc_segments = 6;
  std::vector<Eigen::Vector2d> profile = {{0.0, z0}, {0.5 * (R - bottom_fillet), z0}};
  profile.emplace_back(R - bottom_fillet, z0);
  if (bottom_fillet > 0.0) {
    arc(profile, {R - bottom_fillet, z0 + bottom_fillet}, bottom_fillet, -kPi / 2, 0.0,
        arc_segments);
  }
  profile.emplace_back(R, z1 - top_fillet);
  if (top_fillet > 0.0) {
    arc(profile, {R - top_fillet, z1 - top_fillet}, top_fillet, 0.0, kPi / 2, arc_segments);
  }
  profile.emplace_back(0.5 * (R - top_fillet), z1);
  profile.emplace_back(0.0, z1);
  return revolve(profile, segments);
}

// Cylinder with hemispherical ends; the straight part spans [-length/2, length/2] along +z.
Part capsule(double radius, double length, int segments) {
  std::vector<Eigen::Vector2d> profile = {{0.0, -0.5 * length - radius}};
  arc(profile, {0.0, -0.5 * length}, radius, -kPi / 2, 0.0, 8);
  profile.emplace_back(radius, 0.5 * length);
  arc(profile, {0.0, 0.5 * length}, radius, 0.0, kPi / 2, 8);
  profile.back().x() = 0.0;  // exactly on the axis: the top pole
  return revolve(profile, segments);
}

Part torus(double major_radius, double minor_radius, int segments, int tube_segments) {
  std::vector<Eigen::Vector2d> profile;
  for (int i = 0; i < tube_segments; ++i) {
    const double a = 2.0 * kPi * i / tube_segments;
    profile.emplace_back(major_radius + minor_radius * std::cos(a), minor_radius * std::sin(a));
  }
  return revolve(profile, segments, /*closed_loop=*/true);
}

// Rigid motion taking +z to `axis` and the origin to `origin`.
Eigen::Isometry3d along(const Vector3d& origin, const Vector3d& axis) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond::FromTwoVectors(Vector3d::UnitZ(), axis).toRotationMatrix();
  T.translation() = origin;
  return T;
}

Part square_pyramid(double base, double height) {
  Part part;
  const double a = 0.5 * base;
  const int v0 = part.add({-a, -a, 0}), v1 = part.add({a, -a, 0}), v2 = part.add({a, a, 0}),
            v3 = part.add({-a, a, 0}), apex = part.add({0, 0, height});
  part.triangle(v0, v1, apex);
  part.triangle(v1, v2, apex);
  part.triangle(v2, v3, apex);
  part.triangle(v3, v0, apex);
  part.quad(v0, v3, v2, v1);  // base, seen from below
  return part;
}

// LEGO-style 2x4 brick: solid body (the real brick is hollow underneath) and 8 studs that sink
// 0.1 mm into it.
Part toy_brick() {
  const Vector3d body_half = Vector3d(31.8, 15.8, 9.6) * (0.5 * kMm);
  Part brick = rounded_box(body_half, 0.2 * kMm, 3, 1.0 * kMm);
  const Part stud = cylinder(2.4 * kMm, -0.1 * kMm, 1.7 * kMm, 0.0, 0.2 * kMm, 96);
  for (double x : {-12.0, -4.0, 4.0, 12.0}) {
    for (double y : {-4.0, 4.0}) {
      brick.append(stud, along(Vector3d(x * kMm, y * kMm, body_half.z()), Vector3d::UnitZ()));
    }
  }
  return brick;
}

// Minifigure-like figure, about 40 mm tall, facing +y; built with its feet at z = 0.
Part toy_human() {
  Part human;
  const auto at = [](double x, double y, double z) {
    return along(Vector3d(x, y, z) * kMm, Vector3d::UnitZ());
  };
  const Part leg = rounded_box(Vector3d(3.5, 4.0, 6.0) * kMm, 0.5 * kMm, 3, 1.0 * kMm);
  human.append(leg, at(-3.7, 0.0, 6.0));
  human.append(leg, at(3.7, 0.0, 6.0));
  human.append(rounded_box(Vector3d(7.7, 3.8, 1.6) * kMm, 0.5 * kMm, 3, 1.0 * kMm),
               at(0.0, 0.0, 13.2));  // hips, z 11.6-14.8
  // Torso: a rounded box over z 14.6-27.4 narrowed linearly to 75% of its width at the top.
  Part torso = rounded_box(Vector3d(7.7, 3.8, 6.4) * kMm, 0.6 * kMm, 3, 1.0 * kMm);
  for (Vector3d& v : torso.vertices) {
    v.z() += 21.0 * kMm;
    v.x() *= 1.0 - 0.25 * (v.z() - 14.6 * kMm) / (12.8 * kMm);
  }
  human.append(torso);
  human.append(cylinder(2.2 * kMm, 27.2 * kMm, 28.6 * kMm, 0.0, 0.0, 48));              // neck
  human.append(cylinder(4.8 * kMm, 28.4 * kMm, 37.6 * kMm, 1.6 * kMm, 1.6 * kMm, 96));  // head
  human.append(cylinder(2.0 * kMm, 37.5 * kMm, 39.3 * kMm, 0.0, 0.2 * kMm, 64));        // head stud
  for (double side : {-1.0, 1.0}) {
    // Arm: capsule from the shoulder, hanging down, slightly outward and forward.
    const Vector3d shoulder = Vector3d(side * 6.6, 0.0, 25.4) * kMm;
    const Vector3d down = Vector3d(side * 0.18, 0.25, -1.0).normalized();
    const double arm_length = 8.0 * kMm, arm_radius = 1.9 * kMm;
    human.append(capsule(arm_radius, arm_length, 48),
                 along(shoulder + 0.5 * arm_length * down, down));
    // Hand: a torus (the minifigure's C-shaped clip, closed) on a short wrist.
    const Vector3d wrist = shoulder + arm_length * down;
    const double ring_radius = 1.5 * kMm, tube_radius = 0.7 * kMm;
    const Vector3d hand = wrist + 4.9 * kMm * down;
    const Vector3d forward = (Vector3d::UnitY() - Vector3d::UnitY().dot(down) * down).normalized();
    human.append(cylinder(0.9 * kMm, 0.0, 3.4 * kMm, 0.0, 0.0, 24), along(wrist, down));
    human.append(torus(ring_radius, tube_radius, 48, 16), along(hand, forward));
  }
  return human;
}

// Ellipsoid with semi-axes `semi_axes`: an icosphere scaled per axis (a diagonal scaling with
// positive factors keeps the triangles' orientation).
Part ellipsoid(const Vector3d& semi_axes, int levels) {
  Part part = icosphere(1.0, levels);
  for (Vector3d& v : part.vertices) v = v.cwiseProduct(semi_axes);
  return part;
}

// Moves the bounding-box centre to the origin and converts to the float mesh.
pg::TriangleMesh centred(const Part& part) {
  Vector3d lo = Vector3d::Constant(INFINITY), hi = Vector3d::Constant(-INFINITY);
  for (const Vector3d& v : part.vertices) {
    lo = lo.cwiseMin(v);
    hi = hi.cwiseMax(v);
  }
  const Vector3d centre = 0.5 * (lo + hi);
  pg::TriangleMesh mesh;
  for (const Vector3d& v : part.vertices) mesh.vertices.push_back((v - centre).cast<float>());
  mesh.triangles = part.triangles;
  return mesh;
}

int write_meshes(const std::filesystem::path& out_dir) {
  const int sphere_levels = 5;  // 20480 triangles; r = 8 mm: 0.33 mm edges, facets within 2.3 um
  const std::vector<std::pair<std::string, std::function<Part()>>> objects = {
      {"sphere_r4mm.glb", [&] { return icosphere(4.0 * kMm, sphere_levels); }},
      {"sphere_r6mm.glb", [&] { return icosphere(6.0 * kMm, sphere_levels); }},
      {"sphere_r8mm.glb", [&] { return icosphere(8.0 * kMm, sphere_levels); }},
      {"ball_bearing_0p5in.glb", [&] { return icosphere(0.25 * kInch, sphere_levels); }},
      {"cube.glb",
       [] { return rounded_box(Vector3d::Constant(10.0 * kMm), 1.0 * kMm, 8, 1.0 * kMm); }},
      {"toy_brick.glb", toy_brick},
      {"toy_human.glb", toy_human},
      {"pyramid.glb", [] { return square_pyramid(1.75 * kInch, 0.5 * kInch); }},
      // Training shapes for the default normals model: the local features of the unseen toy brick
      // and toy human (flat tops with sharp or slightly rounded rims, tubes, varied curvature,
      // flat faces with narrow rounded edges) without being either object.
      {"stud_r3mm.glb",
       [] { return cylinder(3.0 * kMm, 0.0, 4.0 * kMm, 0.0, 0.2 * kMm, 128); }},
      {"torus_r5mm.glb", [] { return torus(5.0 * kMm, 2.0 * kMm, 128, 48); }},
      {"ellipsoid.glb",
       [&] { return ellipsoid(Vector3d(7.0, 4.5, 3.0) * kMm, sphere_levels); }},
      {"rounded_plate.glb",
       [] { return rounded_box(Vector3d(7.0, 5.0, 2.0) * kMm, 0.3 * kMm, 4, 0.5 * kMm); }},
  };
  std::filesystem::create_directories(out_dir);
  for (const auto& [name, make] : objects) {
    const pg::TriangleMesh mesh = centred(make());
    const std::string path = (out_dir / name).string();
    pg::save_glb(path, mesh);
    const pg::Bounds3 b = pg::mesh_bounds(mesh);
    const Eigen::Vector3f size = (b.max - b.min) / kMm;
    std::printf("%-24s %6zu vertices %6zu triangles  size %.3f x %.3f x %.3f mm\n", name.c_str(),
                mesh.vertices.size(), mesh.triangles.size(), size.x(), size.y(), size.z());
  }
  return pg::kExitOk;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Writes the repository's object meshes (meshes/*.glb) into OUT_DIR, byte for byte",
               "make_meshes");
  std::string out_arg;
  app.add_option("out_dir", out_arg, "Output folder (the repository's meshes/)")->required();
  return pg::run_cli(app, argc, argv, [&] { return write_meshes(out_arg); });
}
