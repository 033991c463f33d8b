#pragma once
// Triangle meshes of the touched objects: loading (glTF/GLB, OBJ, STL, PLY, OFF) with validation,
// and GLB writing for the generated objects in meshes/.
#include <Eigen/Core>
#include <string>
#include <vector>

namespace pg {

struct TriangleMesh {
  std::vector<Eigen::Vector3f> vertices;   // object frame O [m]
  std::vector<Eigen::Vector3i> triangles;  // vertex indices, counter-clockwise seen from outside
};

struct MeshLoadReport {
  int vertices_welded = 0;               // at the position of an earlier vertex (not warned)
  int degenerate_triangles_dropped = 0;  // zero-area or repeated-index triangles
  int duplicate_triangles_dropped = 0;   // the same three corners as an earlier triangle
  int triangles_turned_to_match = 0;     // faced against the rest of their surface
  int inside_out_parts_turned = 0;       // closed surfaces whose triangles all faced inward
  int border_edges = 0;                  // edges of a single triangle: a hole, a missing face
  int open_surfaces = 0;                 // surfaces with border edges
  int surfaces = 0;                      // surfaces (triangles joined by shared edges)
};

// Loads a mesh and multiplies its vertices by `scale`. Throws pg::InputError naming the file for:
// a missing/unreadable file, an unknown extension, an empty mesh, NaN/inf vertices, out-of-range
// indices, a path that is not a regular file. Vertices at identical positions become one (the
// split vertices of flat-shaded exports; counted, not warned); degenerate triangles are dropped (a
// sliver's neighbour split at its middle corner, so that a closed surface stays closed), and so
// are triangles repeating an earlier one's corners; each surface (triangles joined by edges) is
// oriented: triangles facing against the rest of it are turned to match, and a closed surface
// facing inward is turned outward. Each of these is counted in `report`, and a warning is printed
// to stderr when it changed anything. An open surface (a hole, a missing face) is counted and
// warned about too: the renderer counts it only where it crosses the gel, so a solid with a hole
// presses a partial imprint.
TriangleMesh load_mesh(const std::string& path, double scale = 1.0,
                       MeshLoadReport* report = nullptr);

// Writes a binary glTF (GLB) with one mesh of one primitive (positions + indices).
void save_glb(const std::string& path, const TriangleMesh& mesh);

// Axis-aligned bounds of the vertices [m]; an empty mesh gives min = +inf, max = -inf.
struct Bounds3 {
  Eigen::Vector3f min, max;
};
Bounds3 mesh_bounds(const TriangleMesh& mesh);

}  // namespace pg
