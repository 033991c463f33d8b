#pragma once
// Private to pg_sim: a triangle mesh's surfaces (triangles joined by shared edges) and which of
// them are closed. The loader orients each surface; the renderer tells a closed one's inside.
#include <Eigen/Core>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace pg {

// The key of the undirected edge a-b.
std::uint64_t undirected_edge(int a, int b);

// The triangles on each undirected edge.
using EdgeTriangles = std::unordered_map<std::uint64_t, std::vector<int>>;
EdgeTriangles triangles_by_edge(const std::vector<Eigen::Vector3i>& triangles);

struct Surfaces {
  std::vector<int> of_triangle;      // each triangle's surface, 0 .. closed.size() - 1
  std::vector<std::uint8_t> closed;  // per surface: every edge of it shared by exactly two
                                     // triangles (a stray triangle touching it at a corner
                                     // is a surface of its own and leaves it closed)
};
// `by_edge`: triangles_by_edge(triangles).
Surfaces find_surfaces(const std::vector<Eigen::Vector3i>& triangles, const EdgeTriangles& by_edge);

}  // namespace pg
