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
#include <sstream>
#include <unordered_map>

#include "mesh_formats.h"
#include "mesh_topology.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/json_fields.h"
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
  require_regular_file(path, "a mesh file");
  std::ifstream file(path, std::ios::binary);
  if (!file) throw InputError(path + ": cannot open for reading: " + std::strerror(errno));
  std::string bytes((std::istreambuf_iterator<char>(file)), std::istreambuf_iterator<char>());
  if (file.bad()) throw InputError(path + ": read error");
  return bytes;
}

RawMesh read_raw(const std::string& path) {
  const std::string bytes = read_file(path);  // first, so a missing file is reported as such
  const std::string ext = lowercase_extension(path);
  if (bytes.empty()) throw InputError(path + ": empty file, not a mesh");
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
  const auto squared_length = [&](int a, int b) {
    return (mesh.vertices[static_cast<size_t>(a)] - mesh.vertices[static_cast<size_t>(b)])
        .cast<double>()
        .squaredNorm();
  };
  for (const Eigen::Vector3i& t : mesh.triangles) {
    if (!is_degenerate(mesh, t)) {
      kept.push_back(t);
      continue;
    }
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) continue;
    int middle = 0;  // the corner opposite the longest edge
    double longest = -1.0;
    for (int k = 0; k < 3; ++k) {
      const double l = squared_length(t[(k + 1) % 3], t[(k + 2) % 3]);
      if (l > longest) longest = l, middle = k;
    }
    slivers.emplace_back(t[(middle + 2) % 3], t[middle], t[(middle + 1) % 3]);
  }
  const int dropped = static_cast<int>(mesh.triangles.size() - kept.size());
  // The longest first: a sliver whose long edge is part of a longer one's (several corners on
  // one line) finds its neighbour split by the longer one's repair.
  std::stable_sort(slivers.begin(), slivers.end(),
                   [&](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
                     return squared_length(a[0], a[2]) > squared_length(b[0], b[2]);
                   });
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
      const Eigen::Vector3i first(t[k], b, t[(k + 2) % 3]),
          second(b, t[(k + 1) % 3], t[(k + 2) % 3]);
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

// Drops triangles with the same three corners as an earlier one, in either order: a double-sided
// export, or a body listed twice, whose shared edges (four triangles each once welded) would make
// it no closed surface. Returns how many.
int drop_duplicate_triangles(TriangleMesh& mesh) {
  mesh_formats::PointIndex<int> corners;  // the kept triangles' corners, sorted
  std::vector<Eigen::Vector3i> kept;
  kept.reserve(mesh.triangles.size());
  for (const Eigen::Vector3i& t : mesh.triangles) {
    Eigen::Vector3i sorted = t;
    std::sort(sorted.data(), sorted.data() + 3);
    const auto next = static_cast<std::int64_t>(kept.size());
    if (corners.find_or_add(sorted, next) == next) kept.push_back(t);
  }
  const int dropped = static_cast<int>(mesh.triangles.size() - kept.size());
  mesh.triangles = std::move(kept);
  return dropped;
}

// Whether the ray from `origin` along a fixed, oblique direction crosses the triangles `part` of
// `mesh` an odd number of times: `origin` lies inside that closed surface.
bool inside_closed_part(const TriangleMesh& mesh, const std::vector<int>& part,
                        const Eigen::Vector3d& origin) {
  const Eigen::Vector3d d = Eigen::Vector3d(0.5773502, 0.5773507, 0.5773497).normalized();
  bool inside = false;
  for (int t : part) {
    const Eigen::Vector3i& tri = mesh.triangles[static_cast<size_t>(t)];
    const Eigen::Vector3d a = mesh.vertices[static_cast<size_t>(tri[0])].cast<double>();
    const Eigen::Vector3d e1 = mesh.vertices[static_cast<size_t>(tri[1])].cast<double>() - a;
    const Eigen::Vector3d e2 = mesh.vertices[static_cast<size_t>(tri[2])].cast<double>() - a;
    const Eigen::Vector3d p = d.cross(e2);
    const double det = e1.dot(p);
    if (det == 0.0) continue;
    const Eigen::Vector3d s = origin - a;
    const double u = s.dot(p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = d.dot(q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    if (e2.dot(q) / det > 0.0) inside = !inside;
  }
  return inside;
}

// Boxes in a tree (median splits along the widest side), to find those that hold a given box
// without testing every one: orient_surfaces asks it of every part, and a mesh of many separate
// solids (a scanned pile of grains) has tens of thousands of parts.
class BoxTree {
 public:
  explicit BoxTree(const std::vector<Eigen::AlignedBox3d>& boxes) : boxes_(boxes) {
    items_.resize(boxes.size());
    for (std::size_t k = 0; k < items_.size(); ++k) items_[k] = int(k);
    if (!items_.empty()) build(0, int(items_.size()));
  }
  // The indices of the boxes that hold `box` (in no particular order) into `out`.
  void holding(const Eigen::AlignedBox3d& box, std::vector<int>& out) const {
    out.clear();
    if (nodes_.empty()) return;
    std::vector<int> stack{0};
    while (!stack.empty()) {
      const Node& node = nodes_[std::size_t(stack.back())];
      stack.pop_back();
      if (!node.box.contains(box)) continue;  // then none of its boxes holds it either
      if (node.left < 0) {
        for (int k = node.begin; k < node.end; ++k) {
          const int item = items_[std::size_t(k)];
          if (boxes_[std::size_t(item)].contains(box)) out.push_back(item);
        }
      } else {
        stack.push_back(node.left);
        stack.push_back(node.right);
      }
    }
  }

 private:
  struct Node {
    Eigen::AlignedBox3d box;
    int begin = 0, end = 0, left = -1, right = -1;
  };
  static constexpr int kLeafSize = 8;

  int build(int begin, int end) {
    Node node;
    node.begin = begin, node.end = end;
    for (int k = begin; k < end; ++k) node.box.extend(boxes_[std::size_t(items_[std::size_t(k)])]);
    const int id = int(nodes_.size());
    nodes_.push_back(node);
    if (end - begin > kLeafSize) {
      int axis = 0;
      node.box.sizes().maxCoeff(&axis);
      const int mid = begin + (end - begin) / 2;
      std::nth_element(
          items_.begin() + begin, items_.begin() + mid, items_.begin() + end, [&](int a, int b) {
            return boxes_[std::size_t(a)].center()[axis] < boxes_[std::size_t(b)].center()[axis];
          });
      const int left = build(begin, mid);
      const int right = build(mid, end);
      nodes_[std::size_t(id)].left = left;
      nodes_[std::size_t(id)].right = right;
    }
    return id;
  }

  const std::vector<Eigen::AlignedBox3d>& boxes_;
  std::vector<int> items_;
  std::vector<Node> nodes_;
};

// Orients each surface (triangles joined by shared edges; find_surfaces) as its triangles say:
// the triangles that face against most of their neighbours (neighbours on a consistently
// oriented surface run through their shared edge in opposite directions; edges of more than two
// triangles are not followed) are turned to match, and then a closed surface that faces inward
// (a negative signed volume: clockwise seen from outside, as a CAD export with flipped normals
// has it) is turned outward, since the renderer tells a closed surface's inside from the way its
// faces point; one wholly inside another closed surface (a hollow body's cavity, or a nested
// solid) keeps the direction the file gives it. A surface that cannot be oriented (a Moebius
// strip) stays as it is. Counts, against the file: the closed surfaces whose every triangle was
// turned, and the triangles turned on the others.
void orient_surfaces(TriangleMesh& mesh, MeshLoadReport& report) {
  const int n = static_cast<int>(mesh.triangles.size());
  const EdgeTriangles by_edge = triangles_by_edge(mesh.triangles);
  for (const auto& edge : by_edge) report.border_edges += edge.second.size() == 1;
  const Surfaces surfaces = find_surfaces(mesh.triangles, by_edge);
  std::vector<std::int8_t> flip(static_cast<size_t>(n), -1);  // -1: not reached yet
  // 1. Each surface's triangles, turned consistently (flip 1: against the seed's direction).
  struct Part {
    std::vector<int> triangles;
    bool orientable = true, closed = false;
    double volume = 0.0;  // signed, with the flips
    Eigen::AlignedBox3d box;
  };
  std::vector<Part> parts;
  std::vector<int> queue;
  for (int seed = 0; seed < n; ++seed) {
    if (flip[seed] >= 0) continue;
    Part part;
    queue.assign(1, seed);
    flip[seed] = 0;
    while (!queue.empty()) {
      const int t = queue.back();
      queue.pop_back();
      part.triangles.push_back(t);
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
          part.orientable = false;
        }
      }
    }
    // A closed surface (part is all of it when every edge has two triangles).
    part.closed = surfaces.closed[surfaces.of_triangle[part.triangles[0]]];
    ++report.surfaces;
    report.open_surfaces += !part.closed;
    for (int t : part.triangles) {
      const Eigen::Vector3i& tri = mesh.triangles[t];
      const Eigen::Vector3d a = mesh.vertices[static_cast<size_t>(tri[0])].cast<double>();
      const Eigen::Vector3d b = mesh.vertices[static_cast<size_t>(tri[1])].cast<double>();
      const Eigen::Vector3d c = mesh.vertices[static_cast<size_t>(tri[2])].cast<double>();
      part.volume += flip[t] == 1 ? -a.dot(b.cross(c)) : a.dot(b.cross(c));
      part.box.extend(a).extend(b).extend(c);
    }
    parts.push_back(std::move(part));
  }
  // 2. Which way each faces: the majority's direction; a closed surface outward, unless it lies
  // wholly inside another closed surface (a hollow body's cavity, facing into it, or a solid
  // nested in another): the file's direction then says which, and is kept. (Parts that merely
  // overlap, a toy brick's studs sunk into its body, face outward.)
  std::vector<Eigen::AlignedBox3d> closed_boxes;
  std::vector<int> closed_parts;
  for (std::size_t j = 0; j < parts.size(); ++j) {
    if (parts[j].closed) closed_parts.push_back(int(j)), closed_boxes.push_back(parts[j].box);
  }
  const BoxTree containers(closed_boxes);
  std::vector<int> corners, candidates;  // of the part being tested, each vertex once
  const auto nested = [&](std::size_t i) {
    const Part& part = parts[i];
    containers.holding(part.box, candidates);
    if (candidates.empty()) return false;
    corners.clear();
    for (int t : part.triangles) {
      for (int k = 0; k < 3; ++k) corners.push_back(mesh.triangles[t][k]);
    }
    std::sort(corners.begin(), corners.end());
    corners.erase(std::unique(corners.begin(), corners.end()), corners.end());
    for (const int c : candidates) {
      const std::size_t j = std::size_t(closed_parts[std::size_t(c)]);
      const Part& other = parts[j];
      if (j == i) continue;
      // Every corner of the part inside `other`.
      if (std::all_of(corners.begin(), corners.end(), [&](int v) {
            return inside_closed_part(mesh, other.triangles,
                                      mesh.vertices[static_cast<size_t>(v)].cast<double>());
          })) {
        return true;
      }
    }
    return false;
  };
  for (std::size_t i = 0; i < parts.size(); ++i) {
    const Part& part = parts[i];
    std::size_t flipped = 0;
    for (int t : part.triangles) flipped += flip[t] == 1;
    bool invert = 2 * flipped > part.triangles.size();
    if (part.orientable && part.closed && !nested(i)) invert = part.volume < 0.0;
    int turned = 0;
    for (int t : part.triangles) {
      const bool turn = part.orientable && ((flip[t] == 1) != invert);
      flip[t] = std::int8_t(turn);
      turned += turn;
    }
    if (turned == static_cast<int>(part.triangles.size()) && part.closed) {
      ++report.inside_out_parts_turned;
    } else {
      report.triangles_turned_to_match += turned;
    }
  }
  for (int t = 0; t < n; ++t) {
    if (flip[t] == 1) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
  }
}

// Checks the reader's output, applies `scale`, welds identical vertices, drops degenerate and
// duplicate triangles, and orients each surface (orient_surfaces).
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
    const Eigen::Vector3d p = scale * raw.vertices[v];
    // Beyond a kilometre (as for a scene's positions) the mesh is mis-scaled or damaged, and the
    // renderer's sums over its bounding box would leave the float range.
    const bool finite = raw.vertices[v].allFinite();
    if (!finite || !(p.cwiseAbs().maxCoeff() <= kMaxPositionM)) {
      std::ostringstream msg;
      msg << path << ": vertex " << v + raw.index_base << " (" << counted_from(raw) << ") ";
      if (!finite) {
        msg << "is not finite";
      } else {
        msg << "lies beyond +-" << kMaxPositionM << " m at scale " << scale
            << " (meshes are in metres: is the scale right?)";
      }
      std::string where = format_point(raw.vertices[v]);
      // At another scale the file's coordinates are not where the bound applies: both are said.
      if (finite && scale != 1) where += " in the file, " + format_point(p) + " m scaled";
      throw InputError(msg.str() + ": " + where);
    }
    mesh.vertices.push_back(p.cast<float>());
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
  report.vertices_welded = weld_vertices(mesh);
  const int dropped = drop_degenerate_triangles(mesh);
  if (mesh.triangles.empty()) {
    throw InputError(path + ": empty mesh: all " + std::to_string(dropped) +
                     " triangles are degenerate");
  }
  report.degenerate_triangles_dropped = dropped;
  if (dropped > 0) {
    std::cerr << "warning: " << path << ": dropped " << dropped << " degenerate triangles\n";
  }
  report.duplicate_triangles_dropped = drop_duplicate_triangles(mesh);
  if (report.duplicate_triangles_dropped > 0) {
    std::cerr << "warning: " << path << ": dropped " << report.duplicate_triangles_dropped
              << " triangle(s) with the same three corners as another (a double-sided or "
                 "repeated surface)\n";
  }
  orient_surfaces(mesh, report);
  if (report.triangles_turned_to_match > 0) {
    std::cerr << "warning: " << path << ": " << report.triangles_turned_to_match
              << " triangle(s) faced against the rest of their surface (corners in the other "
                 "order); turned them to match\n";
  }
  if (report.inside_out_parts_turned > 0) {
    std::cerr << "warning: " << path << ": " << report.inside_out_parts_turned
              << " closed part(s) had every triangle facing inward (clockwise seen from "
                 "outside); turned them outward\n";
  }
  if (report.border_edges > 0) {
    std::cerr << "warning: " << path << ": " << report.open_surfaces << " of its "
              << report.surfaces << " surface(s) open, " << report.border_edges
              << " edge(s) of a single triangle (a hole, a missing face): an open surface "
                 "presses the gel only where it crosses it, so a solid with a hole presses part "
                 "of its imprint, or none; a watertight mesh renders as a solid\n";
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
