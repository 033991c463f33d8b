#include "pg/tracker/contact_cloud.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <utility>

#include "pg/tracker/degeneracy.h"
#include "pg/tracker/tracker_config.h"

namespace pg {

namespace {

// A core of fewer points is not worth trusting over the whole contact (the registrations need 20
// at the least; a few dozen of a noisy reconstruction pin a pose poorly).
constexpr int kMinCorePoints = 50;

}  // namespace

int back_project_contact(const GelRays& rays, const ImageF& depth, const ImageU8& mask,
                         const PixelRect& box, const ImageF& normals, PointCloud& cloud_sensor,
                         float min_indentation_m) {
  cloud_sensor.clear();
  const PixelRect b = box.clipped(rays.width, rays.height);
  int rejected = 0;
  for (int y = b.y0; y < b.y1; ++y) {
    const std::uint8_t* m = &mask.at(0, y);
    const float* u = &depth.at(0, y);
    for (int x = b.x0; x < b.x1; ++x) {
      if (m[x] == 0 || !(u[x] > min_indentation_m)) continue;
      const float* n = &normals.at(x, y, 0);
      const Eigen::Vector3f n_gel(n[0], n[1], n[2]);
      const float len = n_gel.norm();
      if (!std::isfinite(len) || len < kMinNormalLength || len > kMaxNormalLength ||
          n_gel.z() <= 0.0f) {
        ++rejected;
        continue;
      }
      const int i = rays.index(x, y);
      cloud_sensor.push_back(rays.point(i, u[x]), n_gel / -len);
    }
  }
  return rejected;
}

namespace {

// The options as a config file's would be checked (a NaN threshold had read every press as no
// contact).
const ContactCloudOptions& checked(const ContactCloudOptions& o) {
  TrackerConfig config;
  config.depth = o.depth;
  config.mask = o.mask;
  config.icp.min_eigenvalue_ratio = o.min_eigenvalue_ratio;
  check_tracker_config(config, "ContactCloudOptions");
  return o;
}

}  // namespace

ContactCloudBuilder::ContactCloudBuilder(const SensorModel& sensor,
                                         const ContactCloudOptions& options,
                                         const ImageF& reference_normals)
    : options_(checked(options)), depth_(sensor, options.depth, reference_normals) {}

void ContactCloudBuilder::build(const ImageF& normals, ContactFrame& frame) {
  depth_.compute(normals, frame.depth);
  frame.rejected_normals = frame.depth.invalid_normals;
  if (2 * std::int64_t(frame.rejected_normals) > std::int64_t(rays().width) * rays().height) {
    // Most normals unusable (a normal image left in a PNG's encoding, say): what the few usable
    // ones show is no contact to trust.
    set_without_normals(frame, ContactStatus::kUnreadable, frame.rejected_normals);
    return;
  }
  contact_mask(frame.depth.depth, frame.depth.window, options_.mask, rays().pixel_area_m2(),
               frame.mask);
  // A contact that reaches the image's edge: integrated again with the image mirrored across
  // those edges (DepthFromNormals::compute), and masked again. Not from the disturbed pixels
  // alone: a network's normals differ from the reference a little everywhere, and mirrored
  // across every edge their error is held by none (the default scene from learned normals
  // 0.72 -> 3.47 mm RMSE).
  const PixelRect& b = frame.mask.box;
  const std::array<bool, 4> edges = {b.x0 == 0, b.y0 == 0, b.x1 == rays().width,
                                     b.y1 == rays().height};
  if (frame.mask.contact && std::find(edges.begin(), edges.end(), true) != edges.end()) {
    depth_.compute(normals, frame.depth, edges);
    contact_mask(frame.depth.depth, frame.depth.window, options_.mask, rays().pixel_area_m2(),
                 frame.mask);
  }
  frame.cloud_sensor.clear();
  frame.status = ContactStatus::kNoContact;
  frame.core = false;
  if (!frame.mask.contact) {
    const double rejected_m2 = double(frame.rejected_normals) * rays().pixel_area_m2();
    if (rejected_m2 >= options_.mask.min_area_m2) frame.status = ContactStatus::kUnreadable;
    return;
  }
  back_project_contact(rays(), frame.depth.depth, frame.mask.mask, frame.mask.box, normals,
                       frame.cloud_sensor);
  keep_core_if_as_constrained(normals, frame);
  // A contact whose every pixel has an unusable normal (its depth filled in from the row's
  // neighbours) cannot be read; it is no sign that the object let go.
  frame.status = frame.cloud_sensor.empty() ? ContactStatus::kUnreadable : ContactStatus::kContact;
}

void ContactCloudBuilder::set_without_normals(ContactFrame& frame, ContactStatus status,
                                              int rejected) {
  frame.rejected_normals = rejected;
  frame.mask.contact = false;
  frame.cloud_sensor.clear();
  frame.core = false;
  frame.status = status;
}

void ContactCloudBuilder::build_unreadable(ContactFrame& frame) const {
  set_without_normals(frame, ContactStatus::kUnreadable, rays().width * rays().height);
}

void ContactCloudBuilder::build_untouched(ContactFrame& frame) const {
  set_without_normals(frame, ContactStatus::kNoContact, 0);
}

int min_contact_pixels(const GelRays& rays, const MaskOptions& mask) {
  return std::max(1, int(std::ceil(mask.min_area_m2 / rays.pixel_area_m2())));
}

int ContactCloudBuilder::min_contact_pixels() const {
  return pg::min_contact_pixels(rays(), options_.mask);
}

void ContactCloudBuilder::keep_core_if_as_constrained(const ImageF& normals, ContactFrame& frame) {
  const MaskOptions& m = options_.mask;
  const float deepest = frame.mask.deepest_m;
  const float whole = indentation_threshold(m, m.relative_depth, deepest);
  const float core = indentation_threshold(m, m.core_relative_depth, deepest);
  if (!(core > whole) || frame.cloud_sensor.empty()) return;
  back_project_contact(rays(), frame.depth.depth, frame.mask.mask, frame.mask.box, normals,
                       core_cloud_, core);
  if (int(core_cloud_.size()) < kMinCorePoints || core_cloud_.size() == frame.cloud_sensor.size()) {
    return;
  }
  const double ratio = options_.min_eigenvalue_ratio;
  if (analyse_cloud_degeneracy(core_cloud_, ratio).unconstrained >
      analyse_cloud_degeneracy(frame.cloud_sensor, ratio).unconstrained) {
    return;
  }
  std::swap(frame.cloud_sensor, core_cloud_);
  frame.core = true;
}

ContactFrame ContactCloudBuilder::build(const ImageF& normals) {
  ContactFrame frame;
  build(normals, frame);
  return frame;
}

}  // namespace pg
