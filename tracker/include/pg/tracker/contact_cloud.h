#pragma once
// One tactile frame's normals -> indentation -> contact mask -> point cloud in the sensor frame
// (paper section IV-B). The cloud is what the registrations of eq. 5 and eq. 6 align.
#include "pg/core/image.h"
#include "pg/core/sensor.h"
#include "pg/tracker/contact_mask.h"
#include "pg/tracker/depth_from_normals.h"
#include "pg/tracker/point_cloud.h"

namespace pg {

struct ContactCloudOptions {
  DepthOptions depth;
  MaskOptions mask;
  // Below this fraction of the largest eigenvalue a direction counts as unconstrained when the
  // contact's core is compared with the whole contact (MaskOptions::core_relative_depth); the
  // registrations' IcpOptions::min_eigenvalue_ratio.
  double min_eigenvalue_ratio = 5e-3;
};

enum class ContactStatus {
  kContact,    // cloud_sensor holds the contact's points
  kNoContact,  // nothing deformed, or less contact than mask.min_area_m2: the cloud is empty
  // No contact was found, but at least mask.min_area_m2 of the image held unusable normals
  // (rejected_normals), or more than half the image did whatever the rest shows (a normal image
  // in another encoding), or there was no usable image at all (build_unreadable): a contact may
  // hide there, so whether the object touches is unknown. The cloud is empty; a tracker should
  // treat the frame as missing, not as the contact's end.
  kUnreadable,
};

struct ContactFrame {
  ContactStatus status = ContactStatus::kNoContact;
  DepthResult depth;  // indentation [m] and the Poisson grid
  ContactMask mask;   // contact pixels
  // Back-projected contact pixels in S [m]: p_S = o + d (t_gel - u). Normals are the object's
  // outward surface normals, i.e. minus the gel normals of the normal image (not re-estimated).
  // Only the contact's core pixels when `core` is set.
  PointCloud cloud_sensor;
  // cloud_sensor holds the contact's core only (MaskOptions::core_relative_depth): the core
  // constrains as many pose directions as the whole contact.
  bool core = false;
  // Normals rejected anywhere in the image (NaN, inf, far from unit length, or n.d <= 0 along
  // the pixel's ray d: facing the camera, which a gel surface it sees cannot); the integration
  // fills their gradient from their neighbours, and they give no point.
  int rejected_normals = 0;
};

// Back-projects the contact pixels in `box` (mask > 0, and indented by more than
// min_indentation_m) into S with their normals (see ContactFrame::cloud_sensor). Pixels whose
// normal is not finite, unit (kMinNormalLength to kMaxNormalLength) and +z are skipped and
// counted in the return value.
// `cloud_sensor` is cleared first; its capacity is reused.
int back_project_contact(const GelRays& rays, const ImageF& depth, const ImageU8& mask,
                         const PixelRect& box, const ImageF& normals, PointCloud& cloud_sensor,
                         float min_indentation_m = 0.0f);

// The smallest contact, mask.min_area_m2, in pixels of the sensor whose rays these are (at
// least 1).
int min_contact_pixels(const GelRays& rays, const MaskOptions& mask);

// Coordinates the steps for one sensor; keeps the per-sensor constants, FFTW plans and scratch
// buffers, so frames allocate nothing once the sizes have been seen. Not thread-safe: one per
// thread (or per sensor).
class ContactCloudBuilder {
 public:
  // reference_normals: see DepthFromNormals (a no-contact frame's normals; empty = gel model).
  ContactCloudBuilder(const SensorModel& sensor, const ContactCloudOptions& options,
                      const ImageF& reference_normals = ImageF());

  // normals: width x height x 3 unit gel normals in S (+z out of the gel), as rendered or as
  // estimated from the colour image. `frame`'s buffers are reused.
  void build(const ImageF& normals, ContactFrame& frame);
  ContactFrame build(const ImageF& normals);
  // A frame with no usable image at all (a camera dropout): kUnreadable, every pixel rejected,
  // no contact mask and no cloud.
  void build_unreadable(ContactFrame& frame) const;
  // A frame whose image shows nothing pressing the gel, found without estimating its normals
  // (a colour frame no different from the no-contact reference beyond the camera's noise):
  // kNoContact, no contact mask and no cloud.
  void build_untouched(ContactFrame& frame) const;
  // The smallest contact, mask.min_area_m2, in pixels of this sensor (at least 1).
  int min_contact_pixels() const;

  const GelRays& rays() const { return depth_.rays(); }
  const ContactCloudOptions& options() const { return options_; }

 private:
  // A frame measured without normals: no mask, no cloud, `status`, `rejected` pixels.
  static void set_without_normals(ContactFrame& frame, ContactStatus status, int rejected);
  // Replaces frame.cloud_sensor by the contact's core when the core constrains as much.
  void keep_core_if_as_constrained(const ImageF& normals, ContactFrame& frame);

  ContactCloudOptions options_;
  DepthFromNormals depth_;
  PointCloud core_cloud_;  // scratch, reused frame to frame
};

}  // namespace pg
