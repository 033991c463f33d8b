// load_mesh(): picks the reader by extension, then validates every format's output the same way
// (see mesh_formats.h for the readers).
#include <Eigen/Geometry>
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <map>
#include <sstream>
#include <unordered_map>

#include "mesh_formats.h"
#include "pg/core/error.h"
#include "pg/sim/mesh.h"

namespace pg {
namespace {

using mesh_formats::RawMesh;

// A triangle is degenerate when two of its indices are equal or when
//   |e1 x e2| <= kDegenerateRelativeArea * (longest edge)^2,
// i.e. its height is below 1e-10 of its longest edge (equivalently |e1 x e2|^2 <= 1e-20 * l^4):
// collinear up to rounding. The test is scale-free and runs in double on the float vertices the
// renderer will see. Thin but honest slivers are kept; they are harmless to a ray caster.
constexpr double kDegenerateRelativeArea = 1e-10;

constexpr const char* kSupported = ".glb, .gltf, .obj, .stl, .ply, .off";

std::string lowercase_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

std::string read_file(const std::string& path) {
  std::error_code ec;
  const auto status = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(status)) throw InputError(path + ": file not found");
  if (std::filesystem::is_directory(status)) {
    throw InputError(path + ": is a directory, not a mesh file");
  }
  if (!std::filesystem::is_regular_file(status)) {  // a device or a pipe would never end
    throw InputError(path + ": is not a regular file (a device, pipe or socket), not a mesh file");
  }
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError(path + ": cannot open for reading: " + std::strerror(errno));
  std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (file.bad()) throw InputError(path + ": read error");
  return bytes;
}

RawMesh read_raw(const std::string& path) {
  const std::string bytes = read_file(path);  // first, so a missing file is reported as such
  const std::string ext = lowercase_extension(path);
  try {
    if (ext == ".glb" || ext == ".gltf") {
      // Trust the content over the name: a GLB starts with the magic "glTF".
      return mesh_formats::read_gltf(path, bytes.compare(0, 4, "glTF") == 0);
    }
    if (ext == ".obj") return mesh_formats::parse_obj(bytes);
    if (ext == ".off") return mesh_formats::parse_off(bytes);
    if (ext == ".stl") return mesh_formats::parse_stl(bytes);
    if (ext == ".ply") return mesh_formats::parse_ply(bytes);
  } catch (const mesh_formats::FormatError& e) {
    throw InputError(path + ": " + e.what());
  }
  throw InputError(path + ": unknown mesh file extension '" + ext + "' (supported: " + kSupported +
                   ")");
}

std::string counted_from(const RawMesh& raw) {
  return raw.index_base == 1 ? "counted from 1, as in the file" : "counted from 0";
}

std::string line_of(const RawMesh& raw, size_t triangle) {
  if (triangle >= raw.triangle_lines.size()) return "";
  return " (line " + std::to_string(raw.triangle_lines[triangle]) + ")";
}

std::string format_point(const Eigen::Vector3d& p) {
  std::ostringstream s;
  s << "(" << p.x() << ", " << p.y() << ", " << p.z() << ")";
  return s.str();
}

bool is_degenerate(const TriangleMesh& mesh, const Eigen::Vector3i& triangle) {
  if (triangle[0] == triangle[1] || triangle[1] == triangle[2] || triangle[0] == triangle[2]) {
    return true;
  }
  const Eigen::Vector3d a = mesh.vertices[static_cast<size_t>(triangle[0])].cast<double>();
  const Eigen::Vector3d b = mesh.vertices[static_cast<size_t>(triangle[1])].cast<double>();
  const Eigen::Vector3d c = mesh.vertices[static_cast<size_t>(triangle[2])].cast<double>();
  const double longest_squared =
      std::max({(b - a).squaredNorm(), (c - a).squaredNorm(), (c - b).squaredNorm()});
  return (b - a).cross(c - a).norm() <= kDegenerateRelativeArea * longest_squared;
}

std::uint64_t undirected_edge(int a, int b) {
  return (std::uint64_t(std::uint32_t(std::min(a, b))) << 32) | std::uint32_t(std::max(a, b));
}

// The triangles on each undirected edge.
using EdgeTriangles = std::unordered_map<std::uint64_t, std::vector<int>>;

EdgeTriangles triangles_by_edge(const std::vector<Eigen::Vector3i>& triangles) {
  EdgeTriangles by_edge;
  by_edge.reserve(triangles.size() * 3 / 2);
  for (int t = 0; t < static_cast<int>(triangles.size()); ++t) {
    for (int k = 0; k < 3; ++k) by_edge[undirected_edge(triangles[t][k], triangles[t][(k + 1) % 3])].push_back(t);
  }
  return by_edge;
}

// Gives vertices at bitwise-identical positions one index, as STL's reader does: exporters that
// give each face its own corners (flat shading, UV seams) would otherwise load a closed surface
// as an open one, and the renderer tells a closed mesh's inside from its shared edges. Returns how
// many vertices became another's (they stay in the list, unused).
int weld_vertices(TriangleMesh& mesh) {
  mesh_formats::PointIndex<float> points;
  std::vector<int> first(mesh.vertices.size());
  int welded = 0;
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    first[v] = static_cast<int>(points.find_or_add(mesh.vertices[v], std::int64_t(v)));
    welded += first[v] != static_cast<int>(v);
  }
  if (welded == 0) return 0;
  for (Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) t[k] = first[static_cast<size_t>(t[k])];
  }
  return welded;
}

// Drops the degenerate triangles; returns how many. A sliver (three distinct corners on a line)
// inside a surface borders, across its longest edge, a triangle whose edge its middle corner
// lies on: that triangle is split at the corner, so that the surface stays closed without the
// sliver (left alone, the edge would belong to one triangle and the sliver's two short edges to
// one each, and a closed mesh would render as an open one).
int drop_degenerate_triangles(TriangleMesh& mesh) {
  std::vector<Eigen::Vector3i> kept;
  kept.reserve(mesh.triangles.size());
  std::vector<Eigen::Vector3i> slivers;  // (a, b, c): b the middle corner
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (!is_degenerate(mesh, t)) {
      kept.push_back(t);
      continue;
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    int middle = 0;  // the corner opposite the longest edge
    double longest = -1.0;
    for (int k = 0; k < 3; ++k) {
      const double l = (mesh.vertices[static_cast<size_t>(t[(k + 1) % 3])] -
                        mesh.vertices[static_cast<size_t>(t[(k + 2) % 3])])
                           .cast<double>()
                           .squaredNorm();
      if (l > longest) longest = l, middle = k;
    }
    slivers.emplace_back(t[(middle + 2) % 3], t[middle], t[(middle + 1) % 3]);
  }
  const int dropped = static_cast<int>(mesh.triangles.size() - kept.size());
  if (!slivers.empty()) {
    EdgeTriangles by_edge = triangles_by_edge(kept);
    const auto edges_of = [&](int t, bool add) {
      for (int k = 0; k < 3; ++k) {
        std::vector<int>& on = by_edge[undirected_edge(kept[t][k], kept[t][(k + 1) % 3])];
        if (add) {
          on.push_back(t);
        } else {
          on.erase(std::remove(on.begin(), on.end(), t), on.end());
        }
      }
    };
    for (const Eigen::Vector3i& sliver : slivers) {
      const auto across = by_edge.find(undirected_edge(sliver[0], sliver[2]));
      if (across == by_edge.end() || across->second.size() != 1) continue;
      const int u = across->second[0];
      const Eigen::Vector3i t = kept[u];
      int k = 0;
      while (undirected_edge(t[k], t[(k + 1) % 3]) != undirected_edge(sliver[0], sliver[2])) ++k;
      const int b = sliver[1];
      const Eigen::Vector3i first(t[k], b, t[(k + 2) % 3]), second(b, t[(k + 1) % 3], t[(k + 2) % 3]);
      if (is_degenerate(mesh, first) || is_degenerate(mesh, second)) continue;
      edges_of(u, false);
      kept[u] = first;
      kept.push_back(second);
      edges_of(u, true);
      edges_of(static_cast<int>(kept.size()) - 1, true);
    }
  }
  mesh.triangles = std::move(kept);
  return dropped;
}

// Turns the triangles of each surface (triangles joined by edges of two) that face against most
// of their neighbours: neighbours on a consistently oriented surface run through their shared
// edge in opposite directions. A surface that cannot be oriented (a Moebius strip) stays as it
// is. Returns how many triangles it turned.
int orient_surfaces_consistently(TriangleMesh& mesh) {
  const int n = static_cast<int>(mesh.triangles.size());
  const EdgeTriangles by_edge = triangles_by_edge(mesh.triangles);
  std::vector<std::int8_t> flip(static_cast<size_t>(n), -1);  // -1: not reached yet
  std::vector<int> surface, queue;
  int turned = 0;
  for (int seed = 0; seed < n; ++seed) {
    if (flip[seed] >= 0) continue;
    surface.clear();
    queue.assign(1, seed);
    flip[seed] = 0;
    bool orientable = true;
    while (!queue.empty()) {
      const int t = queue.back();
      queue.pop_back();
      surface.push_back(t);
      const Eigen::Vector3i& tri = mesh.triangles[t];
      for (int k = 0; k < 3; ++k) {
        const int a = tri[k], b = tri[(k + 1) % 3];
        const std::vector<int>& on = by_edge.at(undirected_edge(a, b));
        if (on.size() != 2) continue;  // a border, or an edge of more than two triangles
        const int u = on[0] == t ? on[1] : on[0];
        const Eigen::Vector3i& other = mesh.triangles[u];
        bool same_direction = false;  // u also runs a -> b
        for (int j = 0; j < 3; ++j) same_direction |= other[j] == a && other[(j + 1) % 3] == b;
        const std::int8_t want = std::int8_t(flip[t] ^ std::int8_t(same_direction));
        if (flip[u] < 0) {
          flip[u] = want;
          queue.push_back(u);
        } else if (flip[u] != want) {
          orientable = false;
        }
      }
    }
    std::size_t flipped = 0;
    for (int t : surface) flipped += flip[t] == 1;
    const bool invert = 2 * flipped > surface.size();  // keep the majority's direction
    for (int t : surface) {
      const bool turn = orientable && ((flip[t] == 1) != invert);
      flip[t] = std::int8_t(turn);
      turned += turn;
    }
  }
  for (int t = 0; t < n; ++t) {
    if (flip[t] == 1) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
  }
  return turned;
}

int find_part(std::vector<int>& parent, int v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}

// Turns every closed part whose triangles all face inward (clockwise seen from outside: a
// negative signed volume) outward, as a CAD export with flipped normals has them; the renderer
// tells inside from outside by which way a closed mesh's faces point. Returns how many parts it
// turned. A part that is open or not consistently oriented (some directed edge used twice, or
// without its reverse) has no inside to speak of and is left as it is.
int orient_closed_parts_outward(TriangleMesh& mesh) {
  const int n = static_cast<int>(mesh.vertices.size());
  std::vector<int> parent(static_cast<size_t>(n));
  for (int v = 0; v < n; ++v) parent[static_cast<size_t>(v)] = v;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    parent[static_cast<size_t>(find_part(parent, t[1]))] = find_part(parent, t[0]);
    parent[static_cast<size_t>(find_part(parent, t[2]))] = find_part(parent, t[0]);
  }
  const auto edge_key = [](int from, int to) {
    return (std::uint64_t(std::uint32_t(from)) << 32) | std::uint32_t(to);
  };
  std::unordered_map<std::uint64_t, int> directed_edges;
  std::map<int, double> volume;  // part root -> signed volume
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++directed_edges[edge_key(t[k], t[(k + 1) % 3])];
    const Eigen::Vector3d a = mesh.vertices[static_cast<size_t>(t[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[static_cast<size_t>(t[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[static_cast<size_t>(t[2])].cast<double>();
    volume[find_part(parent, t[0])] += a.dot(b.cross(c));
  }
  std::map<int, bool> oriented;  // part root -> closed and consistently oriented
  for (const auto& [root, v] : volume) oriented[root] = true;
  for (const auto& [edge, count] : directed_edges) {
    const int from = int(edge >> 32), to = int(edge & 0xffffffffu);
    const auto reverse = directed_edges.find(edge_key(to, from));
    if (count != 1 || reverse == directed_edges.end() || reverse->second != 1) {
      oriented[find_part(parent, from)] = false;
    }
  }
  int turned = 0;
  for (const auto& [root, v] : volume) turned += oriented[root] && v < 0.0;
  if (turned == 0) return 0;
  for (Eigen::Vector3i& t : mesh.triangles) {
    const int root = find_part(parent, t[0]);
    if (oriented[root] && volume[root] < 0.0) std::swap(t[1], t[2]);
  }
  return turned;
}

// Checks the reader's output, applies `scale`, welds identical vertices, drops degenerate
// triangles, orients each surface consistently and turns inside-out closed parts outward.
TriangleMesh validate(const std::string& path, const RawMesh& raw, double scale,
                      MeshLoadReport& report) {
  if (raw.vertices.empty()) throw InputError(path + ": empty mesh: no vertices");
  if (raw.triangles.empty()) throw InputError(path + ": empty mesh: no triangles");
  if (raw.vertices.size() > static_cast<size_t>(INT_MAX)) {
    throw InputError(path + ": too many vertices (" + std::to_string(raw.vertices.size()) + ")");
  }
  const auto num_vertices = static_cast<std::int64_t>(raw.vertices.size());

  TriangleMesh mesh;
  mesh.vertices.reserve(raw.vertices.size());
  for (size_t v = 0; v < raw.vertices.size(); ++v) {
    const Eigen::Vector3f p = (scale * raw.vertices[v]).cast<float>();
    if (!p.allFinite()) {
      const std::string reason =
          raw.vertices[v].allFinite() ? "exceeds the float range after scaling" : "is not finite";
      throw InputError(path + ": vertex " + std::to_string(v + raw.index_base) + " (" +
                       counted_from(raw) + ") " + reason + ": " + format_point(raw.vertices[v]));
    }
    mesh.vertices.push_back(p);
  }

  mesh.triangles.reserve(raw.triangles.size());
  for (size_t t = 0; t < raw.triangles.size(); ++t) {
    Eigen::Vector3i triangle;
    for (int c = 0; c < 3; ++c) {
      const std::int64_t index = raw.triangles[t][static_cast<size_t>(c)];
      if (index < 0 || index >= num_vertices) {
        throw InputError(path + ": triangle " + std::to_string(t) + line_of(raw, t) +
                         " has vertex index " + std::to_string(index + raw.index_base) + " (" +
                         counted_from(raw) + "), but the mesh has " + std::to_string(num_vertices) +
                         " vertices");
      }
      triangle[c] = static_cast<int>(index);
    }
    mesh.triangles.push_back(triangle);
  }
  weld_vertices(mesh);
  const int dropped = drop_degenerate_triangles(mesh);
  if (mesh.triangles.empty()) {
    throw InputError(path + ": empty mesh: all " + std::to_string(dropped) +
                     " triangles are degenerate");
  }
  report.degenerate_triangles_dropped = dropped;
  if (dropped > 0) {
    std::cerr << "warning: " << path << ": dropped " << dropped << " degenerate triangles\n";
  }
  report.triangles_turned_to_match = orient_surfaces_consistently(mesh);
  if (report.triangles_turned_to_match > 0) {
    std::cerr << "warning: " << path << ": " << report.triangles_turned_to_match
              << " triangle(s) faced against their neighbours (corners in the other order); "
                 "turned them to match\n";
  }
  report.inside_out_parts_turned = orient_closed_parts_outward(mesh);
  if (report.inside_out_parts_turned > 0) {
    std::cerr << "warning: " << path << ": " << report.inside_out_parts_turned
              << " closed part(s) had every triangle facing inward (clockwise seen from "
                 "outside); turned them outward\n";
  }
  return mesh;
}

}  // namespace

TriangleMesh load_mesh(const std::string& path, double scale, MeshLoadReport* report) {
  if (!std::isfinite(scale) || scale <= 0.0) {
    std::ostringstream s;
    s << path << ": mesh scale must be finite and > 0, got " << scale;
    throw InputError(s.str());
  }
  MeshLoadReport local_report;
  TriangleMesh mesh = validate(path, read_raw(path), scale, local_report);
  if (report != nullptr) *report = local_report;
  return mesh;
}

Bounds3 mesh_bounds(const TriangleMesh& mesh) {
  Bounds3 bounds{Eigen::Vector3f::Constant(INFINITY), Eigen::Vector3f::Constant(-INFINITY)};
  for (const Eigen::Vector3f& v : mesh.vertices) {
    bounds.min = bounds.min.cwiseMin(v);
    bounds.max = bounds.max.cwiseMax(v);
  }
  return bounds;
}

}  // namespace pg
