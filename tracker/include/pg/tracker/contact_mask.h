#pragma once
// Contact mask from the indentation: pixels pressed deeper than a threshold; a contact smaller
// than a minimum area counts as no contact (noise, a grazing touch).
#include <algorithm>

#include "pg/core/image.h"
#include "pg/core/pixel_rect.h"

namespace pg {

struct MaskOptions {
  double min_depth_m = 1e-4;    // a pixel is in contact when its indentation exceeds this [m]
  double min_area_m2 = 0.5e-6;  // less contact than this is no contact [m^2] (0.5 mm^2)
  // A pixel is in contact only where its indentation also exceeds this fraction of the frame's
  // deepest (its 98th percentile, robust to a stray pixel). An elastic gel sinks in around a
  // contact without touching the object there; that ring is shallow, and its points would pull the
  // registrations off the object's surface.
  double relative_depth = 0.0;
  // The contact's core: the pixels deeper than this fraction of the frame's deepest (as
  // relative_depth). The point cloud keeps only the core when the core alone constrains as many
  // pose directions as the whole contact (ContactCloudBuilder). The shallow band along the
  // contact's rim, where a rigid gel's surface kinks, is the least trustworthy: its normals are
  // central differences across the kink (the chord's, not either face's), and with the averaged
  // integration its depth was 13-19 um RMS off at 0.10-0.15 mm of indentation against 2-6 um
  // deeper. On a corner that band tilts the registrations (all 20 benchmark cubes, parity
  // integration: 0.0011 rad with the core, 0.0037 without), while on a shallow edge press it
  // holds the only view of the turn about the edge. The mask itself stays the whole contact. 0,
  // or not above relative_depth: the whole contact always.
  double core_relative_depth = 0.2;
};

struct ContactMask {
  ImageU8 mask;          // width x height x 1, 255 in contact, else 0
  PixelRect box;         // bounding box of the contact pixels (empty: none)
  int pixels = 0;        // contact pixels [px]
  double area_m2 = 0;    // pixels times the pixel area at the gel centre [m^2]
  bool contact = false;  // area_m2 >= min_area_m2
  // The frame's deepest indentation as the relative thresholds see it: the 98th percentile of the
  // pixels above min_depth_m (0: none) [m].
  float deepest_m = 0.0f;
};

// The indentation a pixel must exceed: min_depth_m, and `fraction` of the frame's deepest
// (ContactMask::deepest_m) [m]. The mask uses relative_depth; the contact's core
// core_relative_depth.
inline float indentation_threshold(const MaskOptions& options, double fraction, float deepest_m) {
  return std::max(float(options.min_depth_m), float(fraction) * deepest_m);
}

// Thresholds `depth` over `window` (the only region where it can be non-zero; pass the whole
// image when unsure). `out`'s buffers are reused; what it marked last time is cleared.
void contact_mask(const ImageF& depth, const PixelRect& window, const MaskOptions& options,
                  double pixel_area_m2, ContactMask& out);

}  // namespace pg
