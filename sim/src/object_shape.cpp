#include <embree3/rtcore.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cstdint>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "mesh_topology.h"
#include "pg/core/error.h"
#include "rasterize.h"
#include "raycast.h"

namespace pg {

namespace {

// One Embree device for the process, created on first use and released with the last shape.
std::shared_ptr<RTCDeviceTy> shared_device() {
  static std::mutex mutex;
  static std::weak_ptr<RTCDeviceTy> weak;
  std::lock_guard<std::mutex> lock(mutex);
  auto device = weak.lock();
  if (!device) {
    RTCDevice raw = rtcNewDevice(nullptr);
    if (!raw) throw std::runtime_error("Embree: cannot create a device");
    device = std::shared_ptr<RTCDeviceTy>(raw, [](RTCDevice d) { rtcReleaseDevice(d); });
    weak = device;
  }
  return device;
}

}  // namespace

struct ObjectShape::Impl {
  std::shared_ptr<RTCDeviceTy> device;
  // One BVH of every triangle; for a mesh of closed and open surfaces, `scene` holds the closed
  // surfaces' and `open_scene` the open ones' (a ray needs the closed surfaces to any depth, to
  // tell whether it starts inside, and the open ones only to the gel).
  RTCScene scene = nullptr, open_scene = nullptr;
  std::vector<unsigned> scene_triangles, open_triangles;  // BVH primitive -> mesh triangle
  std::vector<Eigen::Vector3f> face_normals;  // (v1 - v0) x (v2 - v0): outward for CCW
  std::vector<std::uint8_t> closed_part;      // per triangle: its surface is closed
  TriangleClusters clusters;                  // for rasterizing the triangles near the gel
  ~Impl() {
    if (scene) rtcReleaseScene(scene);
    if (open_scene) rtcReleaseScene(open_scene);
  }
};

namespace {

// A BVH of the mesh's triangles `triangles`.
RTCScene make_scene(RTCDevice device, const TriangleMesh& mesh,
                    const std::vector<unsigned>& triangles) {
  RTCGeometry geom = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* vb = static_cast<float*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh.vertices.size()));
  auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
      geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), triangles.size()));
  for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
    for (int k = 0; k < 3; ++k) vb[3 * i + k] = mesh.vertices[i][k];
  }
  for (std::size_t i = 0; i < triangles.size(); ++i) {
    for (int k = 0; k < 3; ++k) ib[3 * i + k] = unsigned(mesh.triangles[triangles[i]][k]);
  }
  rtcCommitGeometry(geom);
  RTCScene scene = rtcNewScene(device);
  rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
  // Watertight: a ray through a vertex or an edge shared by many triangles never slips through.
  rtcSetSceneFlags(scene, RTC_SCENE_FLAG_ROBUST);
  rtcAttachGeometry(scene, geom);
  rtcReleaseGeometry(geom);
  rtcCommitScene(scene);
  return scene;
}

// A closed surface whose triangles all run clockwise seen from outside (a negative signed volume)
// tells its inside from its outside the wrong way round, and presses nothing: load_mesh turns a
// file's outward, a mesh built in C++ is refused. A cavity faces inward by design; one whose box
// lies within another closed surface's box is taken for one (a solid nested in another's box is
// not checked).
void check_closed_surfaces_face_outward(const TriangleMesh& mesh, const Surfaces& surfaces) {
  const std::size_t count = surfaces.closed.size();
  std::vector<double> volume(count, 0.0);
  std::vector<Eigen::AlignedBox3d> box(count);
  std::vector<std::size_t> first(count, mesh.triangles.size()), size(count, 0);
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const std::size_t s = std::size_t(surfaces.of_triangle[t]);
    if (!surfaces.closed[s]) continue;
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d a = mesh.vertices[std::size_t(tri[0])].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[std::size_t(tri[1])].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[std::size_t(tri[2])].cast<double>();
    volume[s] += a.dot(b.cross(c)) / 6.0;
    box[s].extend(a).extend(b).extend(c);
    first[s] = std::min(first[s], t);
    ++size[s];
  }
  for (std::size_t s = 0; s < count; ++s) {
    if (!surfaces.closed[s] || !(volume[s] < 0.0)) continue;
    bool cavity = false;
    for (std::size_t o = 0; o < count && !cavity; ++o) {
      cavity = o != s && surfaces.closed[o] && box[o].contains(box[s]);
    }
    if (cavity) continue;
    std::ostringstream msg;
    msg << "ObjectShape: the closed surface of " << size[s] << " triangle(s) from triangle "
        << first[s] << " faces inward (signed volume " << volume[s]
        << " m^3): a triangle's corners must run counter-clockwise seen from outside, or the "
           "surface presses nothing (load_mesh turns a file's surfaces outward)";
    throw InputError(msg.str());
  }
}

}  // namespace

ObjectShape::ObjectShape(TriangleMesh mesh)
    : mesh_(std::move(mesh)), impl_(std::make_unique<Impl>()) {
  if (mesh_.vertices.empty() || mesh_.triangles.empty()) {
    throw InputError("ObjectShape: empty mesh");
  }
  // What load_mesh checks of a file's mesh, for one built in C++: an index past the vertices had
  // been read out of bounds (by the BVH too), a non-finite vertex bent the imprint.
  for (std::size_t v = 0; v < mesh_.vertices.size(); ++v) {
    if (!mesh_.vertices[v].allFinite()) {
      throw InputError("ObjectShape: vertex " + std::to_string(v) + " is not finite");
    }
  }
  const int n = int(std::min<std::size_t>(mesh_.vertices.size(), INT32_MAX));
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    const Eigen::Vector3i& tri = mesh_.triangles[t];
    if (tri.minCoeff() < 0 || tri.maxCoeff() >= n) {
      throw InputError("ObjectShape: triangle " + std::to_string(t) + " has vertex index " +
                       std::to_string(tri.minCoeff() < 0 ? tri.minCoeff() : tri.maxCoeff()) +
                       ", but the mesh has " + std::to_string(mesh_.vertices.size()) + " vertices");
    }
  }
  bounds_ = mesh_bounds(mesh_);
  const Surfaces surfaces = find_surfaces(mesh_.triangles, triangles_by_edge(mesh_.triangles));
  impl_->closed_part.resize(mesh_.triangles.size());
  for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
    impl_->closed_part[t] = surfaces.closed[surfaces.of_triangle[t]];
  }
  closed_ = std::all_of(impl_->closed_part.begin(), impl_->closed_part.end(),
                        [](std::uint8_t c) { return c != 0; });
  any_closed_ = std::any_of(impl_->closed_part.begin(), impl_->closed_part.end(),
                            [](std::uint8_t c) { return c != 0; });
  check_closed_surfaces_face_outward(mesh_, surfaces);
  impl_->face_normals.reserve(mesh_.triangles.size());
  for (const auto& t : mesh_.triangles) {
    const auto& v0 = mesh_.vertices[t[0]];
    impl_->face_normals.push_back((mesh_.vertices[t[1]] - v0).cross(mesh_.vertices[t[2]] - v0));
  }
  impl_->clusters = make_clusters(mesh_);
  impl_->device = shared_device();
  const bool mixed = any_closed_ && !closed_;
  for (unsigned t = 0; t < unsigned(mesh_.triangles.size()); ++t) {
    (mixed && !impl_->closed_part[t] ? impl_->open_triangles : impl_->scene_triangles).push_back(t);
  }
  impl_->scene = make_scene(impl_->device.get(), mesh_, impl_->scene_triangles);
  if (mixed) impl_->open_scene = make_scene(impl_->device.get(), mesh_, impl_->open_triangles);
}

ObjectShape::~ObjectShape() = default;

const TriangleClusters& triangle_clusters(const ObjectShape& shape) {
  return shape.impl().clusters;
}

void intersect(const ObjectShape& shape, const SE3& T_sensor_object, const RayPacket& rays,
               PacketHits& hits) {
  // Instead of an Embree instance, move the rays into the object frame: the BVH stays shared
  // and read-only, so any number of threads and sensors can cast at once.
  const SE3 T_object_sensor = T_sensor_object.inverse();
  const Eigen::Matrix3f R = T_object_sensor.rotation_matrix().cast<float>();
  const Eigen::Vector3f origin =
      (T_object_sensor * rays.origin_sensor.cast<double>()).cast<float>();

  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid[kPacket];
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = i < rays.count ? -1 : 0;
    const Eigen::Vector3f d =
        i < rays.count ? Eigen::Vector3f(R * rays.dir_sensor[i]) : Eigen::Vector3f(0, 0, 1);
    rh.ray.org_x[i] = origin.x();
    rh.ray.org_y[i] = origin.y();
    rh.ray.org_z[i] = origin.z();
    rh.ray.dir_x[i] = d.x();
    rh.ray.dir_y[i] = d.y();
    rh.ray.dir_z[i] = d.z();
    rh.ray.tnear[i] = i < rays.count ? rays.tnear[i] : 0.0f;
    rh.ray.tfar[i] = i < rays.count ? rays.tfar[i] : 0.0f;
    rh.ray.time[i] = 0.0f;
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.ray.id[i] = unsigned(i);
    rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  RTCIntersectContext context;
  rtcInitIntersectContext(&context);
  context.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  const ObjectShape::Impl& impl = shape.impl();
  rtcIntersect16(valid, impl.scene, &context, &rh);
  const auto& normals = impl.face_normals;
  const auto& closed = impl.closed_part;
  for (int i = 0; i < rays.count; ++i) {
    if (rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) {
      hits.t[i] = std::numeric_limits<float>::infinity();
      hits.inside[i] = false;
      continue;
    }
    hits.t[i] = rh.ray.tfar[i];
    const Eigen::Vector3f d(rh.ray.dir_x[i], rh.ray.dir_y[i], rh.ray.dir_z[i]);
    const unsigned triangle = impl.scene_triangles[rh.hit.primID[i]];
    hits.inside[i] = closed[triangle] && normals[triangle].dot(d) > 0.0f;
  }
  if (!impl.open_scene) return;
  // The open surfaces, to the gel and not past a closed surface's hit; a ray that starts inside
  // a closed surface stays inside whatever open one it crosses on the way out.
  for (int i = 0; i < kPacket; ++i) {
    valid[i] = i < rays.count && !hits.inside[i] ? -1 : 0;
    rh.ray.tfar[i] = i < rays.count ? std::min(rays.tfar_open[i], hits.t[i]) : 0.0f;
    rh.ray.mask[i] = 0xFFFFFFFFu;
    rh.ray.flags[i] = 0;
    rh.hit.geomID[i] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][i] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid, impl.open_scene, &context, &rh);
  for (int i = 0; i < rays.count; ++i) {
    if (valid[i] == 0 || rh.hit.geomID[i] == RTC_INVALID_GEOMETRY_ID) continue;
    hits.t[i] = rh.ray.tfar[i];
    hits.inside[i] = false;
  }
}

}  // namespace pg
