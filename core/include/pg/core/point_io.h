#pragma once
// Point clouds in PLY files (binary little-endian, float x y z, optional float nx ny nz).
#include <Eigen/Core>
#include <string>
#include <vector>

namespace pg {

// Writes points (and normals when given, one per point). Throws InputError naming the path.
void write_ply(const std::string& path, const std::vector<Eigen::Vector3f>& points,
               const std::vector<Eigen::Vector3f>* normals = nullptr);
// Reads the x y z of a PLY written by write_ply (normals, if any, into *normals). Throws
// InputError naming the path for a missing, truncated or foreign file, or NaN coordinates.
std::vector<Eigen::Vector3f> read_ply(const std::string& path,
                                      std::vector<Eigen::Vector3f>* normals = nullptr);

}  // namespace pg
