#include "pg/tracker/contact_cloud.h"

#include <cmath>

namespace pg {

int back_project_contact(const GelRays& rays, const ImageF& depth, const ImageU8& mask,
                         const PixelRect& box, const ImageF& normals, PointCloud& cloud_sensor) {
  cloud_sensor.clear();
  const PixelRect b = box.clipped(rays.width, rays.height);
  int rejected = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::uint8_t* m = &mask.at(0, y);
    const float* u = &depth.at(0, y);
    for (int x = b.x0; x < b.x1; ++x) {
      if (m[x] == 0) continue;
      const float* n = &normals.at(x, y, 0);
      const Eigen::Vector3f n_gel(n[0], n[1], n[2]);
      const float len = n_gel.norm();
      if (!std::isfinite(len) || len < 0.5f || len > 1.5f || n_gel.z() <= 0.0f) {
        ++rejected;
        continue;
      }
      const int i = rays.index(x, y);
      cloud_sensor.push_back(rays.point(i, u[x]), n_gel / -len);
    }
  }
  return rejected;
}

ContactCloudBuilder::ContactCloudBuilder(const SensorModel& sensor,
                                         const ContactCloudOptions& options,
                                         const ImageF& reference_normals)
    : options_(options), depth_(sensor, options.depth, reference_normals) {}

void ContactCloudBuilder::build(const ImageF& normals, ContactFrame& frame) {
  depth_.compute(normals, frame.depth);
  frame.rejected_normals = frame.depth.invalid_normals;
  contact_mask(frame.depth.depth, frame.depth.window, options_.mask, rays().pixel_area_m2(),
               frame.mask);
  frame.cloud_sensor.clear();
  frame.status = ContactStatus::kNoContact;
  if (!frame.mask.contact) return;
  back_project_contact(rays(), frame.depth.depth, frame.mask.mask, frame.mask.box, normals,
                       frame.cloud_sensor);
  if (!frame.cloud_sensor.empty()) frame.status = ContactStatus::kContact;
}

ContactFrame ContactCloudBuilder::build(const ImageF& normals) {
  ContactFrame frame;
  build(normals, frame);
  return frame;
}

}  // namespace pg
