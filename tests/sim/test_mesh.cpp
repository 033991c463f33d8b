// Mesh loading (every format, every rejected input), GLB writing, and the generated meshes in
// meshes/ (closed, outward, documented sizes).
#include <gtest/gtest.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <numeric>
#include <string>
#include <vector>

#include "pg/core/error.h"
#include "pg/core/numbers.h"
#include "pg/sim/mesh.h"
#include "pg/sim/mesh_sampling.h"

namespace pg {
namespace {

namespace fs = std::filesystem;

::testing::AssertionResult Contains(const std::string& text, const std::string& part) {
  if (text.find(part) != std::string::npos) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "'" << text << "' does not contain '" << part << "'";
}

std::string read_bytes(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(file), std::istreambuf_iterator<char>()};
}

// Little/big-endian byte writers for the binary formats.
void put_u32(std::string& out, std::uint32_t v, bool big_endian = false) {
  for (int k = 0; k < 4; ++k) out.push_back(char(v >> (8 * (big_endian ? 3 - k : k))));
}
void put_f32(std::string& out, float f, bool big_endian = false) {
  std::uint32_t bits;
  std::memcpy(&bits, &f, 4);
  put_u32(out, bits, big_endian);
}

std::string base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const size_t n = std::min<size_t>(3, bytes.size() - i);  // bytes in this group
    std::uint32_t group = 0;
    for (size_t k = 0; k < 3; ++k) {
      group = (group << 8) | (k < n ? static_cast<unsigned char>(bytes[i + k]) : 0u);
    }
    for (size_t k = 0; k < 4; ++k)
      out.push_back(k <= n ? kAlphabet[(group >> (18 - 6 * k)) & 63] : '=');
  }
  return out;
}

class MeshIoTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("pg_test_mesh_" + std::to_string(getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string write(const std::string& name, const std::string& content) {
    const std::string path = (dir_ / name).string();
    std::ofstream(path, std::ios::binary) << content;
    return path;
  }

  // The InputError message load_mesh() throws for `path` (a test failure if it does not throw).
  static std::string load_error(const std::string& path, double scale = 1.0) {
    try {
      load_mesh(path, scale);
    } catch (const InputError& e) {
      return e.what();
    }
    ADD_FAILURE() << "load_mesh(" << path << ") did not throw InputError";
    return "";
  }

  fs::path dir_;
};

void expect_vertex(const TriangleMesh& mesh, int i, const Eigen::Vector3f& expected) {
  ASSERT_LT(static_cast<size_t>(i), mesh.vertices.size());
  EXPECT_LT((mesh.vertices[static_cast<size_t>(i)] - expected).norm(), 1e-6f)
      << "vertex " << i << " is " << mesh.vertices[static_cast<size_t>(i)].transpose()
      << ", expected " << expected.transpose();
}

// ----------------------------------------------------------------------------------- formats

TEST_F(MeshIoTest, ObjReadsPolygonsIndexFormsAndNegativeIndices) {
  const std::string path = write("quad.obj",
                                 "# a quad and a triangle\n"
                                 "o thing\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\r\n"
                                 "vt 0 0\nvn 0 0 1\ns off\nusemtl x\n"
                                 "f 1/1/1 2/1/1 3/1/1 4/1/1\n"
                                 "f -5//1 -1//1 -4//1\n");
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 5u);
  ASSERT_EQ(mesh.triangles.size(), 3u);
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(0, 4, 1));
  expect_vertex(mesh, 2, {1, 1, 0});
  expect_vertex(mesh, 4, {0, 0, 1});
}

TEST_F(MeshIoTest, AsciiStlWeldsSharedCorners) {
  const std::string path = write("two.STL",
                                 "solid two\n"
                                 " facet normal 0 0 1\n  outer loop\n"
                                 "   vertex 0 0 0\n   vertex 1 0 0\n   vertex 1 1 0\n"
                                 "  endloop\n endfacet\n"
                                 " facet normal 0 0 1\n  outer loop\n"
                                 "   vertex 0 0 0\n   vertex 1 1 0\n   vertex -0 1.5e0 0\n"
                                 "  endloop\n endfacet\nendsolid two\n");
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  expect_vertex(mesh, 3, {0, 1.5f, 0});
  // Keywords in capitals, as some exporters write them (read as no vertices before).
  std::string upper = read_bytes(path);
  for (const char* word :
       {"solid", "facet", "normal", "outer", "loop", "vertex", "endloop", "endfacet", "endsolid"}) {
    const std::string w = word;
    std::string W = w;
    for (char& c : W) c = char(std::toupper(static_cast<unsigned char>(c)));
    for (std::size_t at; (at = upper.find(w + " ")) != std::string::npos ||
                         (at = upper.find(w + "\n")) != std::string::npos;)
      upper.replace(at, w.size(), W);
  }
  ASSERT_EQ(upper.find("vertex"), std::string::npos) << upper;
  const TriangleMesh capitals = load_mesh(write("upper.stl", upper));
  EXPECT_EQ(capitals.vertices, mesh.vertices);
  EXPECT_EQ(capitals.triangles, mesh.triangles);
}

std::string binary_stl(const std::vector<std::array<Eigen::Vector3f, 3>>& facets) {
  std::string out = "solid but actually binary";  // the size decides, not the header text
  out.resize(80, ' ');
  put_u32(out, static_cast<std::uint32_t>(facets.size()));
  for (const auto& facet : facets) {
    for (int k = 0; k < 3; ++k) put_f32(out, 0.0f);  // normal
    for (const auto& corner : facet) {
      for (int a = 0; a < 3; ++a) put_f32(out, corner[a]);
    }
    out += std::string(2, '\0');
  }
  return out;
}

TEST_F(MeshIoTest, BinaryStl) {
  const std::string path =
      write("two.stl",
            binary_stl({{{{0, 0, 0}, {2, 0, 0}, {2, 2, 0}}}, {{{0, 0, 0}, {2, 2, 0}, {0, 2, 0}}}}));
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  expect_vertex(mesh, 3, {0, 2, 0});
}

const char* kPlyHeader =
    "ply\nformat %s 1.0\ncomment made by hand\nelement vertex 4\nproperty float x\n"
    "property float y\nproperty double z\nproperty uchar red\nelement face 1\n"
    "property list uchar int vertex_indices\nproperty int flags\nelement edge 1\n"
    "property list ushort uint vertex_pair\nend_header\n";

std::string ply_header(const char* format) {
  char buffer[512];
  std::snprintf(buffer, sizeof buffer, kPlyHeader, format);
  return buffer;
}

TEST_F(MeshIoTest, AsciiPly) {
  const std::string path = write("quad.ply", ply_header("ascii") +
                                                 "0 0 0 255\n1 0 0 255\n1 1 0.5 255\n0 1 0 255\n"
                                                 "4 0 1 2 3 7\n2 0 1\n");
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 4u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
  expect_vertex(mesh, 2, {1, 1, 0.5f});
}

TEST_F(MeshIoTest, BinaryPlyBothByteOrders) {
  for (bool big_endian : {false, true}) {
    std::string body;
    const float xyz[4][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5f}, {0, 1, 0}};
    for (const auto& p : xyz) {
      put_f32(body, p[0], big_endian);
      put_f32(body, p[1], big_endian);
      double z = p[2];
      std::uint64_t bits;
      std::memcpy(&bits, &z, 8);
      for (int k = 0; k < 8; ++k) body.push_back(char(bits >> (8 * (big_endian ? 7 - k : k))));
      body.push_back(char(200));  // red
    }
    body.push_back(4);
    for (std::uint32_t i : {0u, 1u, 2u, 3u}) put_u32(body, i, big_endian);
    put_u32(body, 7, big_endian);                                          // flags
    body += big_endian ? std::string("\0\2", 2) : std::string("\2\0", 2);  // ushort count 2
    put_u32(body, 0, big_endian);
    put_u32(body, 1, big_endian);
    const char* format = big_endian ? "binary_big_endian" : "binary_little_endian";
    const TriangleMesh mesh = load_mesh(write("quad.ply", ply_header(format) + body));
    ASSERT_EQ(mesh.vertices.size(), 4u) << format;
    ASSERT_EQ(mesh.triangles.size(), 2u) << format;
    EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3)) << format;
    expect_vertex(mesh, 2, {1, 1, 0.5f});
  }
}

TEST_F(MeshIoTest, OffWithCommentsColoursAndCountsOnHeaderLine) {
  const std::string path = write("quad.off",
                                 "COFF 5 2 0\n# vertices with colours\n"
                                 "0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n1 1 0 1 1 1 1\n"
                                 "0 1 0 1 1 1 1\n0 0 3 1 1 1 1\n\n"
                                 "4 0 1 2 3 255 0 0\n3 0 4 1\n");
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.vertices.size(), 5u);
  ASSERT_EQ(mesh.triangles.size(), 3u);
  EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(0, 4, 1));
  expect_vertex(mesh, 4, {0, 0, 3});

  const TriangleMesh plain =
      load_mesh(write("tri.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"));
  EXPECT_EQ(plain.triangles.size(), 1u);
}

TriangleMesh tetrahedron() {
  TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  return mesh;
}

TEST_F(MeshIoTest, GlbRoundTripIsExactAndExtensionIsCaseInsensitive) {
  TriangleMesh mesh = tetrahedron();
  mesh.vertices[3] = {0.1234567f, -2.5e-3f, 7.0f};
  const std::string path = (dir_ / "tet.GLB").string();
  save_glb(path, mesh);
  const TriangleMesh loaded = load_mesh(path);
  ASSERT_EQ(loaded.vertices.size(), mesh.vertices.size());
  ASSERT_EQ(loaded.triangles.size(), mesh.triangles.size());
  for (size_t i = 0; i < mesh.vertices.size(); ++i) EXPECT_EQ(loaded.vertices[i], mesh.vertices[i]);
  for (size_t t = 0; t < mesh.triangles.size(); ++t) {
    EXPECT_EQ(loaded.triangles[t], mesh.triangles[t]);
  }
}

TEST_F(MeshIoTest, SaveGlbIsDeterministicAndReportsUnwritablePaths) {
  const std::string a = (dir_ / "a.glb").string(), b = (dir_ / "b.glb").string();
  save_glb(a, tetrahedron());
  save_glb(b, tetrahedron());
  EXPECT_FALSE(read_bytes(a).empty());
  EXPECT_EQ(read_bytes(a), read_bytes(b));
  EXPECT_EQ(read_bytes(a).substr(0, 4), "glTF");

  const std::string bad = (dir_ / "no_such_dir" / "x.glb").string();
  try {
    save_glb(bad, tetrahedron());
    ADD_FAILURE() << "save_glb to a missing directory did not throw";
  } catch (const InputError& e) {
    EXPECT_TRUE(Contains(e.what(), bad));
  }
  EXPECT_THROW(save_glb((dir_ / "empty.glb").string(), TriangleMesh{}), InputError);
}

// A .gltf with an embedded (data URI) buffer: 3 float32 positions (0,0,0), (1,0,0), (0,1,0) and
// uint16 indices `i0 i1 i2`. `nodes` and `scenes` are JSON fragments.
std::string gltf_json(int i0, int i1, int i2, const std::string& nodes, const std::string& scenes) {
  std::string buffer;
  for (float v : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) put_f32(buffer, v);
  for (int i : {i0, i1, i2}) buffer += std::string{char(i & 255), char(i >> 8)};
  buffer += std::string(2, '\0');
  return R"({"asset": {"version": "2.0"},
  "buffers": [{"byteLength": 44, "uri": "data:application/octet-stream;base64,)" +
         base64(buffer) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 36},
                  {"buffer": 0, "byteOffset": 36, "byteLength": 6}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]},
                {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]},
             {"primitives": [{"attributes": {"POSITION": 0}},
                             {"attributes": {"POSITION": 0}, "mode": 1}]}],
  "nodes": )" +
         nodes + ",\n  " + scenes + "}\n";
}

TEST_F(MeshIoTest, GltfAppliesNodeTransformsDownTheDefaultScene) {
  // Scene 1 (the default): node 0 (translate x+1, rotate 90 deg about z) -> node 1 (scale 2,
  // mesh 0), and node 2 (matrix: translate z+5; mesh 1 = one non-indexed triangle + one LINES
  // primitive, skipped). Node 3 is in scene 0 only and must not load.
  const std::string nodes = R"([
    {"translation": [1, 0, 0], "rotation": [0, 0, 0.7071067811865476, 0.7071067811865476],
     "children": [1]},
    {"scale": [2, 2, 2], "mesh": 0},
    {"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,5,1], "mesh": 1},
    {"mesh": 0}])";
  const std::string path = write(
      "scene.gltf",
      gltf_json(0, 1, 2, nodes, R"("scenes": [{"nodes": [3]}, {"nodes": [0, 2]}], "scene": 1)"));
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(path);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_TRUE(Contains(err, "skipped 1 primitives"));
  ASSERT_EQ(mesh.vertices.size(), 6u);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  expect_vertex(mesh, 0, {1, 0, 0});
  expect_vertex(mesh, 1, {1, 2, 0});   // R * (2, 0, 0) + (1, 0, 0)
  expect_vertex(mesh, 2, {-1, 0, 0});  // R * (0, 2, 0) + (1, 0, 0)
  expect_vertex(mesh, 4, {1, 0, 5});
  EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(3, 4, 5));
}

// A node rotation of any finite scale is a rotation; squared, 1e200 overflowed the norm and
// normalised the quaternion to zero.
TEST_F(MeshIoTest, GltfNodeRotationOfAnyScaleIsNormalised) {
  const std::string scenes = R"("scenes": [{"nodes": [0]}])";
  const TriangleMesh mesh = load_mesh(
      write("huge.gltf",
            gltf_json(0, 1, 2, R"([{"rotation": [0, 0, 1e200, 1e200], "mesh": 0}])", scenes)));
  expect_vertex(mesh, 1, {0, 1, 0});  // (1, 0, 0) turned 90 deg about z
  const std::string message = load_error(
      write("zero.gltf", gltf_json(0, 1, 2, R"([{"rotation": [0, 0, 0, 0], "mesh": 0}])", scenes)));
  EXPECT_TRUE(Contains(message, "node 0: rotation must be a finite, non-zero quaternion"));
}

// glTF nodes form trees. A chain of nodes each listing the next child twice had been walked 2^n
// times (here 2^40: no end in sight), copying the leaf's mesh each time; a node with two parents
// is refused, naming it.
TEST_F(MeshIoTest, GltfNodesReachedTwiceAreRefused) {
  std::string nodes = "[";
  for (int n = 0; n < 40; ++n) {
    nodes += "{\"children\": [" + std::to_string(n + 1) + ", " + std::to_string(n + 1) + "]}, ";
  }
  nodes += "{\"mesh\": 0}]";
  const std::string message =
      load_error(write("dag.gltf", gltf_json(0, 1, 2, nodes, R"("scenes": [{"nodes": [0]}])")));
  EXPECT_TRUE(Contains(message, "node 40 is reached twice (glTF nodes form trees")) << message;
}

TEST_F(MeshIoTest, GltfMirroringTransformKeepsTrianglesCounterClockwise) {
  const std::string path = write("mirror.gltf", gltf_json(0, 1, 2, R"([{"scale": [-1, 1, 1],
    "mesh": 0}])",
                                                          R"("scenes": [{"nodes": [0]}])"));
  const TriangleMesh mesh = load_mesh(path);
  ASSERT_EQ(mesh.triangles.size(), 1u);
  const Eigen::Vector3i& t = mesh.triangles[0];
  const Eigen::Vector3f normal =
      (mesh.vertices[t[1]] - mesh.vertices[t[0]]).cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
  EXPECT_GT(normal.z(), 0.0f) << "the mirrored triangle's winding was not flipped back";
}

// A square of 4 vertices as one glTF primitive of `mode` (non-indexed), its positions read with
// `stride` bytes between them (0: packed).
std::string gltf_square(int mode, const std::array<std::array<float, 2>, 4>& corners,
                        int stride = 0) {
  std::string buffer;
  for (const auto& c : corners) {
    for (float v : {c[0], c[1], 0.f}) put_f32(buffer, v);
  }
  return R"({"asset": {"version": "2.0"},
  "buffers": [{"byteLength": 48, "uri": "data:application/octet-stream;base64,)" +
         base64(buffer) + R"("}],
  "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": 48)" +
         (stride ? ", \"byteStride\": " + std::to_string(stride) : std::string()) + R"(}],
  "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                 "min": [0, 0, 0], "max": [1, 1, 0]}],
  "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": )" +
         std::to_string(mode) + R"(}]}],
  "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]})";
}

// Triangle strips and fans (modes 5 and 6) are read as their triangles, each counter-clockwise
// as the first: they had been skipped, and a mesh of them refused as "empty mesh".
TEST_F(MeshIoTest, GltfStripsAndFansAreTriangles) {
  for (const auto& [mode, corners] :
       {std::pair<int, std::array<std::array<float, 2>, 4>>{5, {{{0, 0}, {1, 0}, {0, 1}, {1, 1}}}},
        {6, {{{0, 0}, {1, 0}, {1, 1}, {0, 1}}}}}) {
    SCOPED_TRACE("mode " + std::to_string(mode));
    ::testing::internal::CaptureStderr();
    const TriangleMesh mesh = load_mesh(write("square.gltf", gltf_square(mode, corners)));
    ::testing::internal::GetCapturedStderr();
    ASSERT_EQ(mesh.triangles.size(), 2u);
    float area = 0;
    for (const Eigen::Vector3i& t : mesh.triangles) {
      const Eigen::Vector3f normal = (mesh.vertices[t[1]] - mesh.vertices[t[0]])
                                         .cross(mesh.vertices[t[2]] - mesh.vertices[t[0]]);
      EXPECT_GT(normal.z(), 0.0f);  // counter-clockwise
      area += 0.5f * normal.norm();
    }
    EXPECT_NEAR(area, 1.0f, 1e-6f);  // the square, once
  }
  // A byteStride shorter than a position (12 bytes) read overlapping garbage vertices.
  const std::string path =
      write("stride.gltf", gltf_square(4, {{{0, 0}, {1, 0}, {0, 1}, {1, 1}}}, 4));
  const std::string message = load_error(path);
  EXPECT_TRUE(Contains(message, "byteStride 4 is smaller than one element (12 bytes)")) << message;
}

TEST_F(MeshIoTest, ScaleIsAppliedAndMustBeFinitePositive) {
  const std::string path = write("tri.obj", "v 1 2 3\nv 4 5 6\nv 7 8 10\nf 1 2 3\n");
  const TriangleMesh mesh = load_mesh(path, 1e-3);
  expect_vertex(mesh, 0, {1e-3f, 2e-3f, 3e-3f});
  expect_vertex(mesh, 2, {7e-3f, 8e-3f, 10e-3f});
  for (double scale : {0.0, -1.0, std::nan(""), HUGE_VAL}) {
    const std::string message = load_error(path, scale);
    EXPECT_TRUE(Contains(message, path));
    EXPECT_TRUE(Contains(message, "scale"));
  }
}

// ------------------------------------------------------------------------------ bad inputs

TEST_F(MeshIoTest, MissingFileNamesThePath) {
  const std::string path = (dir_ / "does_not_exist.obj").string();
  const std::string message = load_error(path);
  EXPECT_TRUE(Contains(message, path));
  EXPECT_TRUE(Contains(message, "not found"));
}

TEST_F(MeshIoTest, UnknownExtensionListsSupportedOnes) {
  const std::string path = write("mesh.xyz", "v 0 0 0\n");
  const std::string message = load_error(path);
  EXPECT_TRUE(Contains(message, path));
  EXPECT_TRUE(Contains(message, "'.xyz'"));
  EXPECT_TRUE(Contains(message, ".glb, .gltf, .obj, .stl, .ply, .off"));
}

TEST_F(MeshIoTest, EmptyMeshes) {
  // An empty file of any format is said to be one, its path once (tinygltf's own message had
  // named it three times).
  for (const char* name : {"empty.obj", "empty.glb", "empty.stl"}) {
    const std::string message = load_error(write(name, ""));
    EXPECT_TRUE(Contains(message, "empty file, not a mesh")) << message;
    EXPECT_EQ(message.find(name), message.rfind(name)) << message;
  }
  EXPECT_TRUE(Contains(load_error(write("blank.obj", "\n")), "no vertices"));
  EXPECT_TRUE(Contains(load_error(write("points.obj", "v 0 0 0\nv 1 0 0\n")), "no triangles"));
  EXPECT_TRUE(Contains(load_error(write("empty.off", "OFF\n0 0 0\n")), "no vertices"));
  EXPECT_TRUE(Contains(load_error(write("empty.stl", "solid x\nendsolid x\n")), "no vertices"));
}

TEST_F(MeshIoTest, NonFiniteVerticesAreErrorsInEveryFormat) {
  const std::string tri = "\nf 1 2 3\n";
  std::string message = load_error(write("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0" + tri));
  EXPECT_TRUE(Contains(message, "vertex 2 (counted from 1"));
  EXPECT_TRUE(Contains(message, "not finite"));
  EXPECT_TRUE(Contains(load_error(write("inf.obj", "v 0 0 0\nv 1 0 0\nv 0 inf 0" + tri)),
                       "vertex 3 (counted from 1"));
  EXPECT_TRUE(
      Contains(load_error(write("big.obj", "v 0 0 0\nv 1e400 0 0\nv 0 1 0" + tri)), "not finite"));
  // Beyond a kilometre after scaling: a damaged or mis-scaled mesh (a glTF's float vertices of
  // 1e38 m had overflowed the renderer's image bounds, found by tests/fuzz/fuzz_inputs.py).
  EXPECT_TRUE(Contains(load_error(write("huge.obj", "v 0 0 0\nv 1e300 0 0\nv 0 1 0" + tri)),
                       "lies beyond +-1000 m at scale 1 (meshes are in metres"));
  const std::string km = write("km.obj", "v 0 0 0\nv 2000 0 0\nv 0 1 0" + tri);
  EXPECT_TRUE(Contains(load_error(km), "lies beyond +-1000 m"));
  EXPECT_EQ(load_mesh(km, 1e-3).vertices.size(), 3u) << "2 m at scale 0.001";
  // At a scale that puts it there, both the file's coordinates and the scaled ones are said.
  message = load_error(write("mm.obj", "v 0 0 0\nv 2 0 0\nv 0 1 0" + tri), 1e6);
  EXPECT_TRUE(Contains(
      message, "vertex 2 (counted from 1, as in the file) lies beyond +-1000 m at scale 1e+06"))
      << message;
  EXPECT_TRUE(Contains(message, "(2, 0, 0) in the file, (2e+06, 0, 0) m scaled")) << message;
  EXPECT_TRUE(Contains(
      load_error(write("nan.ply", ply_header("ascii") + "0 0 0 1\nnan 0 0 1\n1 1 0 1\n0 1 0 1\n"
                                                        "3 0 1 2 0\n2 0 1\n")),
      "vertex 1 (counted from 0)"));
  const std::string nan_stl = binary_stl({{{{0, 0, 0}, {NAN, 0, 0}, {0, 1, 0}}}});
  EXPECT_TRUE(Contains(load_error(write("nan.stl", nan_stl)), "not finite"));
  EXPECT_TRUE(
      Contains(load_error(write("inf.off", "OFF\n3 1 0\n0 0 0\n-inf 0 0\n0 1 0\n3 0 1 2\n")),
               "vertex 1 (counted from 0)"));
}

TEST_F(MeshIoTest, OutOfRangeIndicesNameTheTriangleAndIndex) {
  std::string message =
      load_error(write("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n"));
  EXPECT_TRUE(Contains(message, "triangle 1 (line 5)"));
  EXPECT_TRUE(Contains(message, "vertex index 9 (counted from 1"));
  EXPECT_TRUE(Contains(message, "3 vertices"));
  EXPECT_TRUE(Contains(load_error(write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")),
                       "vertex index 0"));
  // A negative index counts back from the last vertex read; one reaching before the first is
  // quoted as the file gives it (it had been quoted resolved: -9 as -5).
  message = load_error(write("neg.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -9\n"));
  EXPECT_TRUE(Contains(message,
                       "neg.obj: line 4: face vertex index -9 counts back from the last "
                       "vertex read, but 3 have been read"))
      << message;
  EXPECT_TRUE(Contains(load_error(write("neg4.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n")),
                       "index -4 counts back"));

  message = load_error(write("bad.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n3 0 1 7\n"));
  EXPECT_TRUE(Contains(message, "triangle 1 (line 7)"));
  EXPECT_TRUE(Contains(message, "vertex index 7 (counted from 0)"));

  message = load_error(write(
      "bad.ply", ply_header("ascii") + "0 0 0 1\n1 0 0 1\n1 1 0 1\n0 1 0 1\n3 0 1 4 0\n2 0 1\n"));
  EXPECT_TRUE(Contains(message, "vertex index 4"));

  const std::string path =
      write("bad.gltf", gltf_json(0, 1, 5, R"([{"mesh": 0}])", R"("scenes": [{"nodes": [0]}])"));
  message = load_error(path);
  EXPECT_TRUE(Contains(message, path));
  EXPECT_TRUE(Contains(message, "triangle 0 has vertex index 5"));
}

TEST_F(MeshIoTest, ParseErrorsNameTheFileAndLine) {
  std::string message = load_error(write("bad.obj", "v 0 0 0\nv 1 zero 0\n"));
  EXPECT_TRUE(Contains(message, "line 2"));
  EXPECT_TRUE(Contains(message, "'zero'"));
  EXPECT_TRUE(Contains(load_error(write("short.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n")), "declares 3"));
  EXPECT_TRUE(Contains(load_error(write("cut.ply", ply_header("binary_little_endian") + "abc")),
                       "ends early"));
  EXPECT_TRUE(Contains(load_error(write("junk.stl", std::string(100, 'x'))), "neither binary STL"));
  EXPECT_TRUE(Contains(load_error(write("junk.glb", "not a glb at all")), "glTF"));
  // A .gltf that is not JSON: the JSON parser's message, without its internal tag.
  message = load_error(write("junk.gltf", "solid not json"));
  EXPECT_TRUE(Contains(message, "junk.gltf: glTF parse error: ")) << message;
  EXPECT_FALSE(Contains(message, "[json.exception")) << message;
}

// A GLB whose JSON gives a field of the wrong type or count: tinygltf indexes its arrays by the
// file's own counts and throws std::out_of_range, which reached the user as "vector::
// _M_range_check" without the file's name (a fuzz case: a buffer of byteLength 0 beside a BIN
// chunk).
TEST_F(MeshIoTest, AGlbWithFieldsOfTheWrongCountNamesTheFile) {
  const auto u32 = [](uint32_t v) { return std::string(reinterpret_cast<const char*>(&v), 4); };
  std::string json = R"({"asset": {"version": "2.0"}, "buffers": [{"byteLength": 0}]})";
  json.append((4 - json.size() % 4) % 4, ' ');
  const std::string bin(8, '\0');
  const std::string chunks = u32(static_cast<uint32_t>(json.size())) + u32(0x4E4F534Au) + json +
                             u32(static_cast<uint32_t>(bin.size())) + u32(0x004E4942u) + bin;
  const std::string path =
      write("wrong_count.glb",
            u32(0x46546C67u) + u32(2u) + u32(static_cast<uint32_t>(12 + chunks.size())) + chunks);
  const std::string message = load_error(path);
  EXPECT_TRUE(Contains(message, path + ": glTF parse error: ")) << message;
  EXPECT_FALSE(Contains(message, "vector::")) << message;
}

// A garbage file's "word" is quoted back in the message: cut short and made printable, not echoed
// whole (a 2 MB first line used to give a 2 MB message, raw bytes and all).
TEST_F(MeshIoTest, GarbageIsQuotedShortAndPrintable) {
  const std::string path = write("long.off", std::string(2'000'000, 'X') + "\n");
  std::string message = load_error(path);
  EXPECT_TRUE(Contains(message, path));
  EXPECT_TRUE(Contains(message, "expected an OFF header, found 'XXXX"));
  EXPECT_TRUE(Contains(message, "X...'"));
  EXPECT_LT(message.size(), path.size() + 200) << message.size() << " characters";
  message = load_error(write("binary.off", std::string("\x88\xe8\xc5Jrf\x01", 7) + "\n3 1 0\n"));
  EXPECT_TRUE(Contains(message, "found '\\x88\\xe8\\xc5Jrf\\x01'"));
  message = load_error(write("long.obj", "v 0 0 " + std::string(100'000, 'z') + "\n"));
  EXPECT_TRUE(Contains(message, "line 1: expected a number for vertex z, found 'zzzz"));
  EXPECT_LT(message.size(), 300u) << message.size() << " characters";
}

TEST_F(MeshIoTest, DegenerateTrianglesAreDroppedCountedAndWarned) {
  const std::string path = write("degenerate.obj",
                                 "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0.5 -1e-7 0\n"
                                 "f 1 2 3\n"    // fine
                                 "f 1 1 2\n"    // repeated index
                                 "f 1 2 4\n"    // collinear: zero area
                                 "f 2 1 5\n");  // thin (height 1e-7 of its length) but valid
  MeshLoadReport report;
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(path, 1.0, &report);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.degenerate_triangles_dropped, 2);
  ASSERT_EQ(mesh.triangles.size(), 2u);
  EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(1, 0, 4));
  // (Then it is an open sheet, said too.)
  EXPECT_EQ(err.substr(0, err.find('\n') + 1),
            "warning: " + path + ": dropped 2 degenerate triangles\n");

  const std::string all = write("all.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 1 2\n");
  ::testing::internal::CaptureStderr();
  EXPECT_TRUE(Contains(load_error(all), "all 2 triangles are degenerate"));
  ::testing::internal::GetCapturedStderr();
}

// The unit cube's 12 outward (counter-clockwise) triangles, 1-based as in an OBJ file.
const std::vector<std::array<int, 3>> kCubeFaces = {{1, 3, 2}, {1, 4, 3}, {5, 6, 7}, {5, 7, 8},
                                                    {1, 2, 6}, {1, 6, 5}, {2, 3, 7}, {2, 7, 6},
                                                    {3, 4, 8}, {3, 8, 7}, {4, 1, 5}, {4, 5, 8}};
const char* kCubeVertices =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";

std::string obj_face(int a, int b, int c) {
  return "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(c) + "\n";
}

// Directed edges that do not pair with exactly one reverse edge: 0 for a closed, consistently
// oriented mesh (as the renderer needs it to tell a closed part's inside).
int unpaired_edges(const TriangleMesh& mesh) {
  std::map<std::pair<int, int>, int> directed;
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
  }
  int unpaired = 0;
  for (const auto& [edge, count] : directed) {
    const auto reverse = directed.find({edge.second, edge.first});
    unpaired += count != 1 || reverse == directed.end() || reverse->second != 1;
  }
  return unpaired;
}

double signed_volume(const TriangleMesh& m) {
  double v = 0;
  for (const auto& t : m.triangles) {
    v += m.vertices[t[0]].cast<double>().dot(
             m.vertices[t[1]].cast<double>().cross(m.vertices[t[2]].cast<double>())) /
         6.0;
  }
  return v;
}

// A closed cube exported with every triangle clockwise seen from outside (CAD's flipped normals)
// is turned outward: the renderer tells inside from outside by the faces' direction, and rendered
// it inside-out as no contact at all. An open or inconsistently oriented part stays as it was.
TEST_F(MeshIoTest, AnInsideOutClosedPartIsTurnedOutwardAndWarned) {
  // Outward (counter-clockwise) faces; the inside-out file lists each with two corners swapped.
  std::string outward = kCubeVertices, inward = kCubeVertices;
  for (const auto& f : kCubeFaces) {
    outward += obj_face(f[0], f[1], f[2]);
    inward += obj_face(f[0], f[2], f[1]);
  }
  MeshLoadReport report;
  ::testing::internal::CaptureStderr();
  const TriangleMesh good = load_mesh(write("outward.obj", outward), 1.0, &report);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_NEAR(signed_volume(good), 1.0, 1e-9);

  const std::string path = write("inward.obj", inward);
  ::testing::internal::CaptureStderr();
  const TriangleMesh turned = load_mesh(path, 1.0, &report);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.inside_out_parts_turned, 1);
  EXPECT_NEAR(signed_volume(turned), 1.0, 1e-9);
  EXPECT_TRUE(Contains(err, path + ": 1 closed part(s) had every triangle facing inward")) << err;

  EXPECT_EQ(report.border_edges, 0);
  EXPECT_EQ(report.open_surfaces, 0);
  EXPECT_EQ(report.surfaces, 1);

  // Without its last triangle the cube is open: nothing to turn; the hole is said (a solid with a
  // hole rendered a partial imprint without a word).
  const std::string open = inward.substr(0, inward.rfind("f "));
  ::testing::internal::CaptureStderr();
  const TriangleMesh kept = load_mesh(write("open.obj", open), 1.0, &report);
  const std::string open_err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_EQ(kept.triangles[0], Eigen::Vector3i(0, 1, 2));
  EXPECT_EQ(report.border_edges, 3);
  EXPECT_EQ(report.open_surfaces, 1);
  EXPECT_TRUE(Contains(open_err,
                       "open.obj: 1 of its 1 surface(s) open, 3 edge(s) of a single "
                       "triangle (a hole, a missing face)"))
      << open_err;
}

// Exporters that give every face its own corners (flat shading, UV seams; GLB and PLY as often
// as OBJ) load closed: vertices at identical positions are welded, as STL's always were. The
// renderer had taken such a cube for an open sheet (a deep press rendered a hole).
TEST_F(MeshIoTest, SplitVerticesAreWeldedSoAClosedSurfaceLoadsClosed) {
  const double v[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                          {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
  std::string split;
  int next = 1;
  for (const auto& f : kCubeFaces) {
    for (int c : f) {
      split += "v " + std::to_string(v[c - 1][0]) + " " + std::to_string(v[c - 1][1]) + " " +
               std::to_string(v[c - 1][2]) + "\n";
    }
    split += obj_face(next, next + 1, next + 2);
    next += 3;
  }
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(write("split.obj", split));
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");  // a repair nobody needs to hear of
  ASSERT_EQ(mesh.triangles.size(), 12u);
  EXPECT_EQ(unpaired_edges(mesh), 0);
  EXPECT_NEAR(signed_volume(mesh), 1.0, 1e-9);
}

// A closed mesh with some triangles listed clockwise (the cube's bottom face here) is turned to
// match the rest of its surface, with a warning: the renderer had skipped those faces as turned
// away and found no contact at all. A surface that cannot be oriented stays as it is.
// A hollow body: a 1 m cube with a 0.5 m cavity, the cavity's faces turned into it, as a modeller
// writes it. Each closed surface had been turned to a positive volume on its own, the cavity
// too, and the renderer then took a ray starting in the wall for one outside. Now a surface
// wholly inside another keeps the file's direction: the cavity stays a cavity, and a nested
// solid (the inner cube facing outward) stays a solid; an inside-out outer surface is still
// turned.
TEST_F(MeshIoTest, AHollowBodysCavityFacesIntoIt) {
  const auto body = [](bool cavity_inward) {
    std::string obj = kCubeVertices;
    for (const char* v :
         {"v 0.25 0.25 0.25\n", "v 0.75 0.25 0.25\n", "v 0.75 0.75 0.25\n", "v 0.25 0.75 0.25\n",
          "v 0.25 0.25 0.75\n", "v 0.75 0.25 0.75\n", "v 0.75 0.75 0.75\n", "v 0.25 0.75 0.75\n"})
      obj += v;
    for (const auto& f : kCubeFaces) obj += obj_face(f[0], f[1], f[2]);
    for (const auto& f : kCubeFaces) {
      obj += cavity_inward ? obj_face(f[0] + 8, f[2] + 8, f[1] + 8)
                           : obj_face(f[0] + 8, f[1] + 8, f[2] + 8);
    }
    return obj;
  };
  MeshLoadReport report;
  ::testing::internal::CaptureStderr();
  const TriangleMesh hollow = load_mesh(write("hollow.obj", body(true)), 1.0, &report);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_NEAR(signed_volume(hollow), 1.0 - 0.125, 1e-9);  // the wall's volume
  ::testing::internal::CaptureStderr();
  const TriangleMesh solid = load_mesh(write("nested.obj", body(false)), 1.0, &report);
  EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_NEAR(signed_volume(solid), 1.0 + 0.125, 1e-9);
  // The outer surface inside out, the cavity as the modeller wrote it: only the outer is turned.
  std::string inside_out = body(true);
  for (std::size_t i = 0; i < kCubeFaces.size(); ++i) {
    const auto& f = kCubeFaces[i];
    const std::string face = obj_face(f[0], f[1], f[2]);
    inside_out.replace(inside_out.find(face), face.size(), obj_face(f[0], f[2], f[1]));
  }
  const std::string path = write("inside_out.obj", inside_out);
  ::testing::internal::CaptureStderr();
  const TriangleMesh turned = load_mesh(path, 1.0, &report);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.inside_out_parts_turned, 1);
  EXPECT_NEAR(signed_volume(turned), 1.0 - 0.125, 1e-9);
  EXPECT_TRUE(Contains(err, path + ": 1 closed part(s)")) << err;
}

// Many bodies, each its own pair of closed surfaces: 100 hollow cubes on a grid, a third of them
// with their outer surface inside out. The surfaces that may hold each part are looked up in a
// tree of their boxes (a file of tens of thousands of separate solids had taken minutes to load,
// every part tested against every other); each cavity is still found inside its own body only.
TEST_F(MeshIoTest, ManyHollowBodiesEachKeepTheirCavity) {
  std::string obj;
  int turned_outer = 0;
  for (int body = 0; body < 100; ++body) {
    const double x = 2.0 * (body % 10), y = 2.0 * (body / 10), z = 0.1 * (body % 7);
    for (const double size : {1.0, 0.5}) {
      const double o = (1.0 - size) / 2.0;
      for (const auto& c : {std::array<int, 3>{0, 0, 0},
                            {1, 0, 0},
                            {1, 1, 0},
                            {0, 1, 0},
                            {0, 0, 1},
                            {1, 0, 1},
                            {1, 1, 1},
                            {0, 1, 1}}) {
        obj += "v " + std::to_string(x + o + size * c[0]) + " " +
               std::to_string(y + o + size * c[1]) + " " + std::to_string(z + o + size * c[2]) +
               "\n";
      }
    }
    const int first = 16 * body;
    const bool inside_out = body % 3 == 0;
    turned_outer += inside_out;
    for (const auto& f : kCubeFaces) {
      obj += inside_out ? obj_face(first + f[0], first + f[2], first + f[1])
                        : obj_face(first + f[0], first + f[1], first + f[2]);
    }
    for (const auto& f : kCubeFaces)
      obj += obj_face(first + f[0] + 8, first + f[2] + 8, first + f[1] + 8);
  }
  MeshLoadReport report;
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(write("hollow_grid.obj", obj), 1.0, &report);
  ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.inside_out_parts_turned, turned_outer);
  EXPECT_EQ(unpaired_edges(mesh), 0);
  EXPECT_NEAR(signed_volume(mesh), 100 * (1.0 - 0.125), 1e-6);  // 112.5 with cavities turned out
}

TEST_F(MeshIoTest, TrianglesFacingAgainstTheirNeighboursAreTurnedToMatch) {
  std::string good = kCubeVertices, flipped = kCubeVertices;
  for (std::size_t i = 0; i < kCubeFaces.size(); ++i) {
    const auto& f = kCubeFaces[i];
    good += obj_face(f[0], f[1], f[2]);
    flipped += i < 2 ? obj_face(f[0], f[2], f[1]) : obj_face(f[0], f[1], f[2]);
  }
  const TriangleMesh expected = load_mesh(write("good.obj", good));
  MeshLoadReport report;
  const std::string path = write("flipped.obj", flipped);
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(path, 1.0, &report);
  const std::string err = ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.triangles_turned_to_match, 2);
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_EQ(err, "warning: " + path +
                     ": 2 triangle(s) faced against the rest of their surface (corners in the "
                     "other order); turned them to match\n");
  EXPECT_EQ(unpaired_edges(mesh), 0);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const Eigen::Vector3i& a = mesh.triangles[t];
    const Eigen::Vector3i& b = expected.triangles[t];
    EXPECT_TRUE(a == b || a == Eigen::Vector3i(b[1], b[2], b[0]) ||
                a == Eigen::Vector3i(b[2], b[0], b[1]))
        << "triangle " << t << ": " << a.transpose() << " against " << b.transpose();
  }
  // Most triangles flipped: a closed surface faces outward, so the many wrong ones are turned
  // (counted against the file), not the few right ones.
  std::string mostly = kCubeVertices;
  for (std::size_t i = 0; i < kCubeFaces.size(); ++i) {
    const auto& f = kCubeFaces[i];
    mostly += i < 3 ? obj_face(f[0], f[1], f[2]) : obj_face(f[0], f[2], f[1]);
  }
  ::testing::internal::CaptureStderr();
  const TriangleMesh turned = load_mesh(write("mostly.obj", mostly), 1.0, &report);
  ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.triangles_turned_to_match, 9);
  EXPECT_EQ(report.inside_out_parts_turned, 0);
  EXPECT_NEAR(signed_volume(turned), 1.0, 1e-9);
  // A Moebius strip of four quads has no consistent orientation: left as it was.
  std::string strip;  // rung i: its two ends, the rung turned by half of i's angle
  for (int i = 0; i < 4; ++i) {
    const double a = i * kPi / 2;
    for (double end : {0.3, -0.3}) {
      const double r = 1 + end * std::sin(a / 2);
      strip += "v " + std::to_string(r * std::cos(a)) + " " + std::to_string(r * std::sin(a)) +
               " " + std::to_string(end * std::cos(a / 2)) + "\n";
    }
  }
  // Quad i joins rungs i and i + 1; the last joins rung 3 to rung 0 with its ends swapped.
  std::string strip_faces;
  for (int i = 0; i < 4; ++i) {
    const int a = 2 * i + 1, b = a + 1;
    const int c = i < 3 ? a + 2 : 2, d = i < 3 ? a + 3 : 1;
    strip_faces += obj_face(a, b, d) + obj_face(a, d, c);
  }
  ::testing::internal::CaptureStderr();
  const TriangleMesh moebius = load_mesh(write("moebius.obj", strip + strip_faces), 1.0, &report);
  ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.triangles_turned_to_match, 0);
  EXPECT_EQ(moebius.triangles[0], Eigen::Vector3i(0, 1, 3));
}

// A double-sided export (every face again, reversed) or a body listed twice loads as one closed
// surface: the repeated triangles are dropped with a warning (welded, every edge had four
// triangles: no closed surface, so a deep press rendered a hole).
TEST_F(MeshIoTest, RepeatedTrianglesAreDroppedSoTheSurfaceStaysClosed) {
  std::string twice = kCubeVertices, doubled = kCubeVertices;
  for (const auto& f : kCubeFaces) twice += obj_face(f[0], f[1], f[2]);
  for (const auto& f : kCubeFaces) twice += obj_face(f[1], f[2], f[0]);  // the same, rotated
  for (const auto& f : kCubeFaces)
    doubled += obj_face(f[0], f[2], f[1]) + obj_face(f[0], f[1], f[2]);
  for (const auto& [name, text] :
       {std::pair<std::string, std::string>{"twice.obj", twice}, {"doubled.obj", doubled}}) {
    MeshLoadReport report;
    const std::string path = write(name, text);
    ::testing::internal::CaptureStderr();
    const TriangleMesh mesh = load_mesh(path, 1.0, &report);
    const std::string err = ::testing::internal::GetCapturedStderr();
    EXPECT_EQ(report.duplicate_triangles_dropped, 12) << name;
    EXPECT_TRUE(Contains(err, path + ": dropped 12 triangle(s) with the same three corners as "
                                     "another"))
        << err;
    EXPECT_EQ(mesh.triangles.size(), 12u) << name;
    EXPECT_EQ(unpaired_edges(mesh), 0) << name;
    EXPECT_NEAR(signed_volume(mesh), 1.0, 1e-9) << name;  // the doubled file's inward copy first
  }
}

// A zero-area sliver that closes a T-junction (a CAD export's way of splitting an edge) is
// dropped, and the triangle across its long edge is split at its middle corner, so that the
// surface stays closed (dropping it alone had opened the mesh).
TEST_F(MeshIoTest, ASliversNeighbourIsSplitSoTheSurfaceStaysClosed) {
  // The bottom face's first triangle (1 3 2) split at m, the middle of its diagonal 1-3; the
  // sliver (3 m 1) closes the diagonal against the second triangle (1 4 3).
  std::string cube = std::string(kCubeVertices) + "v 0.5 0.5 0\n";  // m = 9
  cube += obj_face(1, 9, 2) + obj_face(9, 3, 2) + obj_face(3, 9, 1);
  for (std::size_t i = 1; i < kCubeFaces.size(); ++i) {
    cube += obj_face(kCubeFaces[i][0], kCubeFaces[i][1], kCubeFaces[i][2]);
  }
  MeshLoadReport report;
  ::testing::internal::CaptureStderr();
  const TriangleMesh mesh = load_mesh(write("sliver.obj", cube), 1.0, &report);
  ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.degenerate_triangles_dropped, 1);
  EXPECT_EQ(mesh.triangles.size(), 14u);  // 15 - the sliver + one more half
  EXPECT_EQ(unpaired_edges(mesh), 0);
  EXPECT_NEAR(signed_volume(mesh), 1.0, 1e-9);
  // Two corners on the diagonal (p at a quarter, m at half), two chained slivers, the shorter
  // listed first: (3 m p) closes m-3 against p, (3 p 1) closes 1-3 against the second triangle.
  std::string chained = std::string(kCubeVertices) + "v 0.5 0.5 0\nv 0.75 0.75 0\n";  // m, p
  chained += obj_face(1, 9, 2) + obj_face(9, 10, 2) + obj_face(10, 3, 2) + obj_face(3, 10, 9) +
             obj_face(3, 9, 1);
  for (std::size_t i = 1; i < kCubeFaces.size(); ++i) {
    chained += obj_face(kCubeFaces[i][0], kCubeFaces[i][1], kCubeFaces[i][2]);
  }
  ::testing::internal::CaptureStderr();
  const TriangleMesh two = load_mesh(write("chained.obj", chained), 1.0, &report);
  ::testing::internal::GetCapturedStderr();
  EXPECT_EQ(report.degenerate_triangles_dropped, 2);
  EXPECT_EQ(unpaired_edges(two), 0);
  EXPECT_NEAR(signed_volume(two), 1.0, 1e-9);
}

TEST_F(MeshIoTest, AFileThatIsNotARegularFileIsRefused) {
  EXPECT_TRUE(Contains(load_error("/dev/zero.obj"), "file not found"));
  const std::string link = (dir_ / "zero.obj").string();
  fs::create_symlink("/dev/zero", link);
  EXPECT_TRUE(Contains(load_error(link), "is not a regular file")) << load_error(link);
}

// --------------------------------------------------------------------- generated meshes/*.glb

struct GeneratedObject {
  const char* file;
  Eigen::Vector3d size_mm;        // documented bounding-box size (meshes/README.md)
  int parts = 1;                  // separate closed pieces
  double sphere_radius_mm = 0.0;  // > 0: every vertex lies on this sphere
};

void PrintTo(const GeneratedObject& object, std::ostream* os) { *os << object.file; }

class GeneratedMeshTest : public ::testing::TestWithParam<GeneratedObject> {};

int find_root(std::vector<int>& parent, int v) {
  while (parent[v] != v) v = parent[v] = parent[parent[v]];
  return v;
}

TEST_P(GeneratedMeshTest, IsClosedOutwardAndHasTheDocumentedSize) {
  const GeneratedObject& object = GetParam();
  const std::string path = std::string(PG_SOURCE_DIR) + "/meshes/" + object.file;
  ASSERT_TRUE(fs::exists(path)) << path << " missing: run build/tools/make_meshes meshes/";
  EXPECT_LT(fs::file_size(path), 1u << 20);
  MeshLoadReport report;
  const TriangleMesh mesh = load_mesh(path, 1.0, &report);
  // The file itself is clean: the loader's repairs would hide a generator that winds its
  // triangles inward or repeats them, so the checks below on the loaded mesh need none of them.
  EXPECT_EQ(report.degenerate_triangles_dropped, 0);
  EXPECT_EQ(report.duplicate_triangles_dropped, 0);
  EXPECT_EQ(report.triangles_turned_to_match, 0);
  EXPECT_EQ(report.inside_out_parts_turned, 0);

  const Bounds3 bounds = mesh_bounds(mesh);
  const Eigen::Vector3d size_mm = (bounds.max - bounds.min).cast<double>() * 1e3;
  const Eigen::Vector3d centre_mm = 0.5 * (bounds.max + bounds.min).cast<double>() * 1e3;
  EXPECT_LT((size_mm - object.size_mm).cwiseAbs().maxCoeff(), 0.05)
      << "size " << size_mm.transpose() << " mm, documented " << object.size_mm.transpose();
  EXPECT_LT(centre_mm.norm(), 1e-3) << "bounding-box centre " << centre_mm.transpose() << " mm";

  // Connected parts (triangles sharing vertices).
  const int n = static_cast<int>(mesh.vertices.size());
  std::vector<int> parent(static_cast<size_t>(n));
  std::iota(parent.begin(), parent.end(), 0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    parent[find_root(parent, t[1])] = find_root(parent, t[0]);
    parent[find_root(parent, t[2])] = find_root(parent, t[0]);
  }
  // Per part: each directed edge once and its reverse once (closed, consistently oriented),
  // and a positive signed volume (outward).
  std::map<std::pair<int, int>, int> directed_edges;
  std::map<int, double> volume;  // part root -> signed volume [m^3]
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k) ++directed_edges[{t[k], t[(k + 1) % 3]}];
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[t[2]].cast<double>();
    volume[find_root(parent, t[0])] += a.dot(b.cross(c)) / 6.0;
  }
  std::map<int, int> bad_edges;  // part root -> edges that are open, non-manifold or flipped
  for (const auto& [edge, count] : directed_edges) {
    const auto reverse = directed_edges.find({edge.second, edge.first});
    if (count != 1 || reverse == directed_edges.end() || reverse->second != 1) {
      ++bad_edges[find_root(parent, edge.first)];
    }
  }
  EXPECT_EQ(static_cast<int>(volume.size()), object.parts);
  for (const auto& [part, part_volume] : volume) {
    EXPECT_EQ(bad_edges[part], 0) << "part of vertex " << part << " is not closed and oriented";
    EXPECT_GT(part_volume, 0.0) << "part of vertex " << part << " faces inward";
  }

  if (object.sphere_radius_mm > 0) {
    const double radius = object.sphere_radius_mm * 1e-3;
    double worst = 0.0;
    for (const Eigen::Vector3f& v : mesh.vertices) {
      worst = std::max(worst, std::abs(v.cast<double>().norm() - radius) / radius);
    }
    EXPECT_LT(worst, 1e-6) << "worst relative radius error " << worst;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Meshes, GeneratedMeshTest,
    ::testing::Values(GeneratedObject{"sphere_r4mm.glb", {8, 8, 8}, 1, 4},
                      GeneratedObject{"sphere_r6mm.glb", {12, 12, 12}, 1, 6},
                      GeneratedObject{"sphere_r8mm.glb", {16, 16, 16}, 1, 8},
                      GeneratedObject{"ball_bearing_0p5in.glb", {12.7, 12.7, 12.7}, 1, 6.35},
                      GeneratedObject{"cube.glb", {20, 20, 20}},
                      GeneratedObject{"toy_brick.glb", {31.8, 15.8, 11.3}, 9},   // body + 8 studs
                      GeneratedObject{"toy_human.glb", {22.03, 9.6, 39.3}, 13},  // see README
                      GeneratedObject{"pyramid.glb", {44.45, 44.45, 12.7}},
                      // The default normals model's extra training shapes.
                      GeneratedObject{"stud_r3mm.glb", {6, 6, 4}},
                      GeneratedObject{"torus_r5mm.glb", {14, 14, 4}},
                      GeneratedObject{"ellipsoid.glb", {14, 9, 6}},
                      GeneratedObject{"rounded_plate.glb", {14, 10, 4}}),
    [](const ::testing::TestParamInfo<GeneratedObject>& info) {
      std::string name = info.param.file;
      return name.substr(0, name.find('.'));
    });

// A run of triangles smaller than a sample's share (each still gets one) before a large square:
// the square gets its density's worth. The samples the small ones took had been charged to the
// triangles after them: the square had come out with a sample per triangle.
TEST(SurfaceSampling, SmallTrianglesDoNotStarveTheLargeOnesAfterThem) {
  TriangleMesh mesh;
  for (int k = 0; k < 2000; ++k) {  // 2000 triangles of 0.5e-10 m^2, far apart from the square
    const float x = 0.1f + 1e-4f * float(k);
    const int i = int(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), {{x, 0, 0}, {x + 1e-5f, 0, 0}, {x, 1e-5f, 0}});
    mesh.triangles.emplace_back(i, i + 1, i + 2);
  }
  const int i = int(mesh.vertices.size());  // a 1 cm square
  mesh.vertices.insert(mesh.vertices.end(),
                       {{0, 0, 0}, {0.01f, 0, 0}, {0.01f, 0.01f, 0}, {0, 0.01f, 0}});
  mesh.triangles.emplace_back(i, i + 1, i + 2);
  mesh.triangles.emplace_back(i, i + 2, i + 3);
  const SurfaceSamples s = sample_surface(mesh, 1e-4);  // 10 000 a square centimetre
  const long on_square = std::count_if(s.points.begin(), s.points.end(),
                                       [](const Eigen::Vector3f& p) { return p.x() <= 0.01f; });
  EXPECT_NEAR(double(on_square), 10000.0, 2.0);
  EXPECT_EQ(long(s.points.size()) - on_square, 2000);
}

}  // namespace
}  // namespace pg
