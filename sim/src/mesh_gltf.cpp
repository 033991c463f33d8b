// glTF 2.0 (.gltf/.glb) reading and GLB writing through tinygltf.
#include <tiny_gltf.h>

#include <Eigen/Geometry>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <exception>
#include <fstream>
#include <iostream>
#include <sstream>

#include "mesh_formats.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/json_fields.h"
#include "pg/core/se3.h"
#include "pg/sim/mesh.h"

namespace pg {
namespace mesh_formats {
namespace {

// Geometry only: leave images undecoded (and missing image files are only a tinygltf warning).
bool skip_image(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                const unsigned char*, int, void*) {
  return true;
}

// glTF buffers are little-endian; decode explicitly so the host's byte order does not matter.
std::uint32_t load_le(const unsigned char* p, int size) {
  std::uint32_t value = 0;
  for (int k = size - 1; k >= 0; --k) value = (value << 8) | p[k];
  return value;
}

// An accessor's elements, bounds-checked against its buffer view and buffer.
struct AccessorData {
  const unsigned char* first = nullptr;
  size_t stride = 0;
  size_t count = 0;
  int component_type = 0;
  int type = 0;
};

AccessorData accessor_data(const tinygltf::Model& model, int index, const std::string& what) {
  if (index < 0 || static_cast<size_t>(index) >= model.accessors.size()) {
    throw FormatError(what + ": accessor " + std::to_string(index) + " does not exist");
  }
  const tinygltf::Accessor& accessor = model.accessors[static_cast<size_t>(index)];
  if (accessor.sparse.isSparse) throw FormatError(what + ": sparse accessors are not supported");
  if (accessor.bufferView < 0 ||
      static_cast<size_t>(accessor.bufferView) >= model.bufferViews.size()) {
    throw FormatError(what + ": accessor " + std::to_string(index) + " has no buffer view");
  }
  const tinygltf::BufferView& view = model.bufferViews[static_cast<size_t>(accessor.bufferView)];
  if (view.buffer < 0 || static_cast<size_t>(view.buffer) >= model.buffers.size()) {
    throw FormatError(what + ": buffer view " + std::to_string(accessor.bufferView) +
                      " has no buffer");
  }
  const std::vector<unsigned char>& buffer = model.buffers[static_cast<size_t>(view.buffer)].data;
  const int stride = accessor.ByteStride(view);
  const int component_size =
      tinygltf::GetComponentSizeInBytes(static_cast<std::uint32_t>(accessor.componentType));
  const int components =
      tinygltf::GetNumComponentsInType(static_cast<std::uint32_t>(accessor.type));
  if (stride <= 0 || component_size <= 0 || components <= 0) {
    throw FormatError(what + ": accessor " + std::to_string(index) +
                      " has an invalid type, component type or stride");
  }
  if (accessor.count > buffer.size()) {  // also keeps the end computation below from overflowing
    throw FormatError(what + ": accessor " + std::to_string(index) + " reaches past its data");
  }
  const size_t begin = view.byteOffset + accessor.byteOffset;
  const size_t element_size = static_cast<size_t>(component_size * components);
  if (static_cast<size_t>(stride) < element_size) {  // elements overlapping: garbage vertices
    throw FormatError(what + ": accessor " + std::to_string(index) + "'s byteStride " +
                      std::to_string(stride) + " is smaller than one element (" +
                      std::to_string(element_size) + " bytes)");
  }
  const size_t end =
      accessor.count == 0
          ? begin
          : begin + static_cast<size_t>(stride) * (accessor.count - 1) + element_size;
  if (end > view.byteOffset + view.byteLength ||
      view.byteOffset + view.byteLength > buffer.size()) {
    throw FormatError(what + ": accessor " + std::to_string(index) + " reaches past its data");
  }
  return {buffer.data() + begin, static_cast<size_t>(stride), accessor.count,
          accessor.componentType, accessor.type};
}

std::int64_t read_index(const AccessorData& data, size_t i) {
  const unsigned char* p = data.first + i * data.stride;
  switch (data.component_type) {
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
      return p[0];
    case TINYGLTF_COMPONENT_TYPE_BYTE:
      return static_cast<std::int8_t>(p[0]);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
      return load_le(p, 2);
    case TINYGLTF_COMPONENT_TYPE_SHORT:
      return static_cast<std::int16_t>(load_le(p, 2));
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
      return load_le(p, 4);
    case TINYGLTF_COMPONENT_TYPE_INT:
      return static_cast<std::int32_t>(load_le(p, 4));
    default:
      return -1;  // not reached: checked by the caller
  }
}

// Node transform: `matrix` (column-major) if given, else T * R * S.
Eigen::Matrix4d local_transform(const tinygltf::Node& node, int index) {
  if (node.matrix.size() == 16) return Eigen::Map<const Eigen::Matrix4d>(node.matrix.data());
  Eigen::Affine3d transform = Eigen::Affine3d::Identity();
  if (node.translation.size() == 3) {
    transform.translate(
        Eigen::Vector3d(node.translation[0], node.translation[1], node.translation[2]));
  }
  if (node.rotation.size() == 4) {  // glTF stores (x, y, z, w)
    Eigen::Quaterniond q;
    if (!unit_quaternion(
            Eigen::Vector4d(node.rotation[0], node.rotation[1], node.rotation[2], node.rotation[3]),
            q)) {
      throw FormatError("node " + std::to_string(index) +
                        ": rotation must be a finite, non-zero quaternion");
    }
    transform.rotate(q);
  }
  if (node.scale.size() == 3) {
    transform.scale(Eigen::Vector3d(node.scale[0], node.scale[1], node.scale[2]));
  }
  return transform.matrix();
}

class GltfFlattener {
 public:
  explicit GltfFlattener(const tinygltf::Model& model)
      : model_(model), visited_(model.nodes.size(), false) {}

  void add_node(int index, const Eigen::Matrix4d& T_parent, size_t depth, RawMesh& out) {
    if (index < 0 || static_cast<size_t>(index) >= model_.nodes.size()) {
      throw FormatError("node " + std::to_string(index) + " does not exist");
    }
    if (depth > model_.nodes.size()) throw FormatError("the node hierarchy has a cycle");
    // glTF's nodes form trees: a node reached twice (two parents, or a root that is also a
    // child) would be drawn twice, and a chain of such nodes 2^n times (no end in sight).
    if (visited_[static_cast<size_t>(index)]) {
      throw FormatError("node " + std::to_string(index) +
                        " is reached twice (glTF nodes form trees: one parent each)");
    }
    visited_[static_cast<size_t>(index)] = true;
    const tinygltf::Node& node = model_.nodes[static_cast<size_t>(index)];
    const Eigen::Matrix4d T = T_parent * local_transform(node, index);
    if (node.mesh >= 0) {
      if (static_cast<size_t>(node.mesh) >= model_.meshes.size()) {
        throw FormatError("node " + std::to_string(index) + " refers to missing mesh " +
                          std::to_string(node.mesh));
      }
      const auto& primitives = model_.meshes[static_cast<size_t>(node.mesh)].primitives;
      for (size_t p = 0; p < primitives.size(); ++p) {
        add_primitive(primitives[p], T,
                      "mesh " + std::to_string(node.mesh) + " primitive " + std::to_string(p), out);
      }
    }
    for (int child : node.children) add_node(child, T, depth + 1, out);
  }

  int skipped_primitives() const { return skipped_primitives_; }

 private:
  void add_primitive(const tinygltf::Primitive& primitive, const Eigen::Matrix4d& T,
                     const std::string& what, RawMesh& out) {
    const bool strip = primitive.mode == TINYGLTF_MODE_TRIANGLE_STRIP;
    const bool fan = primitive.mode == TINYGLTF_MODE_TRIANGLE_FAN;
    if (primitive.mode != TINYGLTF_MODE_TRIANGLES && primitive.mode != -1 && !strip && !fan) {
      ++skipped_primitives_;  // points, lines
      return;
    }
    const auto position = primitive.attributes.find("POSITION");
    if (position == primitive.attributes.end()) {
      throw FormatError(what + ": no POSITION attribute");
    }
    const AccessorData positions = accessor_data(model_, position->second, what + " POSITION");
    if (positions.component_type != TINYGLTF_COMPONENT_TYPE_FLOAT ||
        positions.type != TINYGLTF_TYPE_VEC3) {
      throw FormatError(what + ": POSITION must be float32 VEC3");
    }
    const auto base = static_cast<std::int64_t>(out.vertices.size());
    const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
    for (size_t i = 0; i < positions.count; ++i) {
      Eigen::Vector3d p;
      for (int a = 0; a < 3; ++a) {
        const std::uint32_t bits = load_le(positions.first + i * positions.stride + 4 * a, 4);
        float value;
        std::memcpy(&value, &bits, sizeof value);
        p[a] = value;
      }
      out.vertices.push_back(R * p + T.topRightCorner<3, 1>());
    }

    AccessorData indices;
    if (primitive.indices >= 0) {
      indices = accessor_data(model_, primitive.indices, what + " indices");
      if (indices.type != TINYGLTF_TYPE_SCALAR)
        throw FormatError(what + ": indices must be scalars");
      if (indices.component_type < TINYGLTF_COMPONENT_TYPE_BYTE ||
          indices.component_type > TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) {
        throw FormatError(what + ": indices must have an integer component type");
      }
    }
    const size_t count = primitive.indices >= 0 ? indices.count : positions.count;
    if (!strip && !fan && count % 3 != 0) {
      throw FormatError(what + ": " + std::to_string(count) +
                        " indices is not a multiple of 3 (TRIANGLES)");
    }
    // Triangle t's corner c as a place in the primitive's list (glTF spec 3.7.2.1): strips
    // alternate their winding so that every triangle keeps the first one's, fans share corner 0.
    const size_t triangles = strip || fan ? (count < 3 ? 0 : count - 2) : count / 3;
    const auto corner = [&](size_t t, size_t c) -> size_t {
      if (strip) return t + (c == 0 ? 0 : c == 1 ? 1 + t % 2 : 2 - t % 2);
      if (fan) return c == 2 ? 0 : t + 1 + c;
      return 3 * t + c;
    };
    // A mirroring transform turns counter-clockwise triangles clockwise: undo it (glTF spec 3.7.4).
    const bool mirrored = R.determinant() < 0.0;
    for (size_t t = 0; t < triangles; ++t) {
      std::array<std::int64_t, 3> triangle;
      for (size_t c = 0; c < 3; ++c) {
        const size_t k = corner(t, c);
        const std::int64_t index =
            primitive.indices >= 0 ? read_index(indices, k) : static_cast<std::int64_t>(k);
        if (index < 0 || static_cast<size_t>(index) >= positions.count) {
          throw FormatError(what + ": triangle " + std::to_string(t) + " has vertex index " +
                            std::to_string(index) + ", but the primitive has " +
                            std::to_string(positions.count) + " vertices");
        }
        triangle[c] = base + index;
      }
      if (mirrored) std::swap(triangle[1], triangle[2]);
      out.triangles.push_back(triangle);
    }
  }

  const tinygltf::Model& model_;
  std::vector<bool> visited_;  // nodes reached so far
  int skipped_primitives_ = 0;
};

}  // namespace

RawMesh read_gltf(const std::string& path, bool binary) {
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(&skip_image, nullptr);
  tinygltf::Model model;
  std::string error, warning;
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromFile(&model, &error, &warning, path)
                : loader.LoadASCIIFromFile(&model, &error, &warning, path);
  } catch (const std::exception&) {
    // tinygltf indexes some arrays by the file's own counts, unchecked: a buffer of byteLength 0
    // beside a BIN chunk escapes as std::out_of_range, whose words mean nothing to a user.
    throw FormatError(
        "glTF parse error: a field whose type or count does not match the rest of the file (an "
        "index past the end of an array it declares)");
  }
  if (!ok) {
    std::string what = without_json_tag(error.empty() ? warning : error);
    while (!what.empty() && (what.back() == '\n' || what.back() == ' ')) what.pop_back();
    throw FormatError("glTF parse error: " + what);
  }

  std::vector<int> roots;
  if (!model.scenes.empty()) {
    const int scene = model.defaultScene >= 0 ? model.defaultScene : 0;
    if (static_cast<size_t>(scene) >= model.scenes.size()) {
      throw FormatError("default scene " + std::to_string(scene) + " does not exist");
    }
    roots = model.scenes[static_cast<size_t>(scene)].nodes;
  } else {  // no scene: take every node that is no other node's child
    std::vector<bool> is_child(model.nodes.size(), false);
    for (const auto& node : model.nodes) {
      for (int child : node.children) {
        if (child >= 0 && static_cast<size_t>(child) < is_child.size()) is_child[child] = true;
      }
    }
    for (size_t n = 0; n < model.nodes.size(); ++n) {
      if (!is_child[n]) roots.push_back(static_cast<int>(n));
    }
  }

  RawMesh mesh;
  GltfFlattener flattener(model);
  for (int root : roots) flattener.add_node(root, Eigen::Matrix4d::Identity(), 0, mesh);
  if (flattener.skipped_primitives() > 0) {
    std::cerr << "warning: " << path << ": skipped " << flattener.skipped_primitives()
              << " primitives of points or lines (no surface)\n";
  }
  return mesh;
}

}  // namespace mesh_formats

namespace {

void append_le32(std::vector<unsigned char>& bytes, std::uint32_t value) {
  for (int k = 0; k < 4; ++k) bytes.push_back(static_cast<unsigned char>(value >> (8 * k)));
}

}  // namespace

void save_glb(const std::string& path, const TriangleMesh& mesh) {
  if (mesh.vertices.empty() || mesh.triangles.empty()) {
    throw InputError(path + ": cannot write an empty mesh (" +
                     std::to_string(mesh.vertices.size()) + " vertices, " +
                     std::to_string(mesh.triangles.size()) + " triangles)");
  }
  const auto num_vertices = static_cast<int>(mesh.vertices.size());
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& triangle = mesh.triangles[t];
    if ((triangle.array() < 0).any() || (triangle.array() >= num_vertices).any()) {
      throw InputError(path + ": cannot write triangle " + std::to_string(t) +
                       ": vertex index out of range");
    }
  }
  for (size_t v = 0; v < mesh.vertices.size(); ++v) {
    if (!mesh.vertices[v].allFinite()) {
      throw InputError(path + ": cannot write vertex " + std::to_string(v) + ": not finite");
    }
  }
  const Bounds3 bounds = mesh_bounds(mesh);

  // One buffer: float32 positions, then uint32 indices (both 4-byte aligned).
  tinygltf::Buffer buffer;
  buffer.data.reserve(12 * (mesh.vertices.size() + mesh.triangles.size()));
  for (const Eigen::Vector3f& v : mesh.vertices) {
    for (int a = 0; a < 3; ++a) {
      std::uint32_t bits;
      std::memcpy(&bits, &v[a], sizeof bits);
      append_le32(buffer.data, bits);
    }
  }
  const size_t positions_size = buffer.data.size();
  for (const Eigen::Vector3i& triangle : mesh.triangles) {
    for (int c = 0; c < 3; ++c) append_le32(buffer.data, static_cast<std::uint32_t>(triangle[c]));
  }

  tinygltf::Model model;
  model.asset.version = "2.0";
  model.asset.generator = "patchgraph pg::save_glb";
  model.buffers.push_back(buffer);

  tinygltf::BufferView positions_view;
  positions_view.buffer = 0;
  positions_view.byteOffset = 0;
  positions_view.byteLength = positions_size;
  positions_view.target = TINYGLTF_TARGET_ARRAY_BUFFER;
  tinygltf::BufferView indices_view;
  indices_view.buffer = 0;
  indices_view.byteOffset = positions_size;
  indices_view.byteLength = buffer.data.size() - positions_size;
  indices_view.target = TINYGLTF_TARGET_ELEMENT_ARRAY_BUFFER;
  model.bufferViews = {positions_view, indices_view};

  tinygltf::Accessor positions;
  positions.bufferView = 0;
  positions.componentType = TINYGLTF_COMPONENT_TYPE_FLOAT;
  positions.type = TINYGLTF_TYPE_VEC3;
  positions.count = mesh.vertices.size();
  positions.minValues = {bounds.min.x(), bounds.min.y(), bounds.min.z()};  // required for POSITION
  positions.maxValues = {bounds.max.x(), bounds.max.y(), bounds.max.z()};
  tinygltf::Accessor indices;
  indices.bufferView = 1;
  indices.componentType = TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT;
  indices.type = TINYGLTF_TYPE_SCALAR;
  indices.count = 3 * mesh.triangles.size();
  model.accessors = {positions, indices};

  tinygltf::Primitive primitive;
  primitive.attributes["POSITION"] = 0;
  primitive.indices = 1;
  primitive.mode = TINYGLTF_MODE_TRIANGLES;
  tinygltf::Mesh gltf_mesh;
  gltf_mesh.primitives.push_back(primitive);
  model.meshes.push_back(gltf_mesh);
  tinygltf::Node node;
  node.mesh = 0;
  model.nodes.push_back(node);
  tinygltf::Scene scene;
  scene.nodes.push_back(0);
  model.scenes.push_back(scene);
  model.defaultScene = 0;

  // Serialise to memory, then write: tinygltf's file writer does not report a failed open.
  std::ostringstream glb(std::ios::binary);
  tinygltf::TinyGLTF writer;
  if (!writer.WriteGltfSceneToStream(&model, glb, /*prettyPrint=*/false, /*writeBinary=*/true)) {
    throw InputError(path + ": tinygltf failed to serialise the mesh");
  }
  write_text_file(path, glb.str());
}

}  // namespace pg
