#pragma once
// Ray casting against one object's Embree BVH, 16 rays at a time. Internal to pg_sim: the Embree
// headers stay out of the public ones.
#include <Eigen/Core>
#include <cstdint>

#include "pg/sim/renderer.h"

namespace pg {

constexpr int kPacket = 16;

// A packet of rays sharing one origin (the camera centre), given in the sensor frame.
struct RayPacket {
  int count = 0;  // rays in use, at most kPacket
  Eigen::Vector3f origin_sensor;
  Eigen::Vector3f dir_sensor[kPacket];  // not normalised: t is the camera depth
  float tnear[kPacket];
  float tfar[kPacket];       // for a shape's closed surfaces (those alone, in a shape of both)
  float tfar_open[kPacket];  // for the open surfaces of a shape of both closed and open ones
};

struct PacketHits {
  float t[kPacket];           // +inf where no hit
  // The hit is a face of a closed surface turned away from the ray: the ray started inside it.
  bool inside[kPacket];
};

struct TriangleClusters;
const TriangleClusters& triangle_clusters(const ObjectShape& shape);

// Intersects the packet with `shape` at pose T_sensor_object, filling `hits`.
void intersect(const ObjectShape& shape, const SE3& T_sensor_object, const RayPacket& rays,
               PacketHits& hits);

}  // namespace pg
