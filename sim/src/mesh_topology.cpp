#include "mesh_topology.h"

#include <algorithm>
#include <numeric>

namespace pg {

std::uint64_t undirected_edge(int a, int b) {
  return (std::uint64_t(std::uint32_t(std::min(a, b))) << 32) | std::uint32_t(std::max(a, b));
}

EdgeTriangles triangles_by_edge(const std::vector<Eigen::Vector3i>& triangles) {
  EdgeTriangles by_edge;
  by_edge.reserve(triangles.size() * 3 / 2);
  for (int t = 0; t < int(triangles.size()); ++t) {
    for (int k = 0; k < 3; ++k) {
      by_edge[undirected_edge(triangles[t][k], triangles[t][(k + 1) % 3])].push_back(t);
    }
  }
  return by_edge;
}

namespace {

int find_root(std::vector<int>& parent, int i) {
  while (parent[i] != i) i = parent[i] = parent[parent[i]];
  return i;
}

}  // namespace

Surfaces find_surfaces(const std::vector<Eigen::Vector3i>& triangles,
                       const EdgeTriangles& by_edge) {
  std::vector<int> parent(triangles.size());
  std::iota(parent.begin(), parent.end(), 0);
  for (const auto& [edge, on] : by_edge) {
    for (std::size_t k = 1; k < on.size(); ++k)
      parent[find_root(parent, on[k])] = find_root(parent, on[0]);
  }
  Surfaces s;
  s.of_triangle.assign(triangles.size(), -1);
  std::vector<int> index(triangles.size(), -1);  // root -> surface
  for (int t = 0; t < int(triangles.size()); ++t) {
    const int root = find_root(parent, t);
    if (index[root] < 0) {
      index[root] = int(s.closed.size());
      s.closed.push_back(1);
    }
    s.of_triangle[t] = index[root];
  }
  for (const auto& [edge, on] : by_edge) {
    if (on.size() != 2) s.closed[s.of_triangle[on[0]]] = 0;
  }
  return s;
}

}  // namespace pg
