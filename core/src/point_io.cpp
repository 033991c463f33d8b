#include "pg/core/point_io.h"

#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>

#include "pg/core/error.h"
#include "pg/core/file_io.h"

namespace pg {

void write_ply(const std::string& path, const std::vector<Eigen::Vector3f>& points,
               const std::vector<Eigen::Vector3f>* normals) {
  if (normals && normals->size() != points.size()) {
    throw std::invalid_argument("write_ply: one normal per point expected");
  }
  std::ostringstream out;
  out << "ply\nformat binary_little_endian 1.0\nelement vertex " << points.size()
      << "\nproperty float x\nproperty float y\nproperty float z\n";
  if (normals) out << "property float nx\nproperty float ny\nproperty float nz\n";
  out << "end_header\n";
  for (std::size_t i = 0; i < points.size(); ++i) {
    out.write(reinterpret_cast<const char*>(points[i].data()), 3 * sizeof(float));
    if (normals) out.write(reinterpret_cast<const char*>((*normals)[i].data()), 3 * sizeof(float));
  }
  // As the text outputs: a failed write leaves the earlier file.
  write_text_atomically(path, out.str());
}

std::vector<Eigen::Vector3f> read_ply(const std::string& path,
                                      std::vector<Eigen::Vector3f>* normals) {
  require_regular_file(path, "a PLY file");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot read the file (missing or not readable)");
  std::string line;
  long count = -1;
  int properties = 0;
  bool binary_le = false;
  if (!std::getline(in, line) || line != "ply") throw InputError(path + ": not a PLY file");
  while (std::getline(in, line) && line != "end_header") {
    std::istringstream ss(line);
    std::string word;
    ss >> word;
    if (word == "format") {
      std::string fmt;
      ss >> fmt;
      binary_le = fmt == "binary_little_endian";
    } else if (word == "element") {
      std::string name;
      ss >> name >> count;
      if (name != "vertex") throw InputError(path + ": expected only a vertex element");
    } else if (word == "property") {
      std::string type;
      ss >> type;
      if (type != "float") throw InputError(path + ": expected float properties");
      ++properties;
    }
  }
  if (line != "end_header" || !binary_le || count < 0 || (properties != 3 && properties != 6)) {
    throw InputError(path + ": expected a binary little-endian PLY of float x y z [nx ny nz]");
  }
  std::vector<float> data(std::size_t(count) * properties);
  in.read(reinterpret_cast<char*>(data.data()), std::streamsize(data.size() * sizeof(float)));
  if (in.gcount() != std::streamsize(data.size() * sizeof(float))) {
    throw InputError(path + ": truncated (" + std::to_string(count) + " points announced)");
  }
  std::vector<Eigen::Vector3f> points(count);
  if (normals) normals->assign(properties == 6 ? count : 0, Eigen::Vector3f::Zero());
  for (long i = 0; i < count; ++i) {
    const float* p = &data[std::size_t(i) * properties];
    points[i] = Eigen::Vector3f(p[0], p[1], p[2]);
    if (!points[i].allFinite()) {
      throw InputError(path + ": point " + std::to_string(i) + " is not finite");
    }
    if (normals && properties == 6) (*normals)[i] = Eigen::Vector3f(p[3], p[4], p[5]);
  }
  return points;
}

}  // namespace pg
