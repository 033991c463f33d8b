#pragma once
// The tactile renderer: ray-casts object meshes into the sensor's gel, deforms the gel, shades it
// with the sensor's lights and emits colour plus ground truth (normals, indentation, mask,
// contact points). Cost follows the contact area and the requested outputs.
#include <memory>
#include <string>
#include <vector>

#include "pg/core/dataset.h"
#include "pg/core/sensor.h"
#include "pg/sim/mesh.h"

namespace pg {

// One mesh's acceleration structure (an Embree BVH), built once and shared by every sensor and
// thread; per frame only the object's pose changes. Immutable and thread-safe after creation.
class ObjectShape {
 public:
  // Throws InputError for an empty mesh, a non-finite vertex, a vertex index out of range or a
  // closed surface facing inward that is not a cavity (its box within another closed surface's)
  // (load_mesh's meshes have none: it turns a file's surfaces outward).
  explicit ObjectShape(TriangleMesh mesh);
  ~ObjectShape();
  ObjectShape(const ObjectShape&) = delete;
  ObjectShape& operator=(const ObjectShape&) = delete;

  const TriangleMesh& mesh() const { return mesh_; }
  const Bounds3& bounds() const { return bounds_; }
  // Every surface (triangles joined by shared edges) closed: each edge shared by exactly two
  // triangles. A ray that starts inside a closed surface is recognised (its first hit faces
  // away) and counts as full penetration; an open one counts only where it is.
  bool closed() const { return closed_; }
  bool any_part_closed() const { return any_closed_; }

  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  TriangleMesh mesh_;
  Bounds3 bounds_;
  bool closed_ = false, any_closed_ = false;
  std::unique_ptr<Impl> impl_;
};

struct RenderSettings {
  // Outputs. Work that no requested output needs is not done.
  bool color = true;
  bool normal = true;
  bool depth = true;
  bool mask = true;
  bool contact_points = false;  // contact points in each object's frame
  bool shadows = false;         // shadows the deformed gel casts on itself
  bool noise = true;
  std::string background;  // "" = synthetic (shading of the undeformed gel), else an image path
  // Work skipping; all on by default. Switch one off only to measure what it saves.
  bool cull = true;               // skip objects whose bounds do not reach the gel slab
  bool footprint = true;          // cast rays only near the contact, not over the whole image
  bool slab_limited_rays = true;  // start rays at the slab, not at the camera's near plane
  bool no_contact_cache = true;   // a frame without contact is the cached background
  // Fine pass by rasterizing the triangles near the gel instead of a ray per pixel, where that
  // is cheaper (same result; rays are kept where an object reaches deeper than the gel allows).
  bool rasterize = true;
};

struct RenderStats {
  bool contact = false;
  int objects_culled = 0;
  long rays_cast = 0;
  long triangles_rasterized = 0;
  int contact_pixels = 0;
  int clamped_pixels = 0;  // penetration beyond the gel's max indentation, clamped
  int shaded_pixels = 0;   // pixels whose surface differs from the undeformed gel
  // Contact pixels per object (the object touching deepest at each), when there are several
  // objects; empty for one, whose contact_pixels they all are.
  std::vector<int> object_contact_pixels;
};

struct RenderedFrame {
  FrameImages images;  // only the requested outputs are filled
  // Per object: the object surface points where it touches the gel, in the object frame [m].
  std::vector<std::vector<Eigen::Vector3f>> contact_points_object;
  RenderStats stats;
  // Bookkeeping for rendering into this frame again: which renderer filled `images` (a number
  // unique in the process, 0 for none) and the pixels [x0, x1) x [y0, y1) where they may differ
  // from its no-contact images.
  struct Filled {
    std::uint64_t by = 0;
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  } filled;
};

// Renders one sensor. Thread-safe: render() may be called from several threads at once.
class SensorRenderer {
 public:
  // Throws InputError for a background image that is missing or unreadable (naming its path), a
  // sensor a sensor file could not give (check_sensor_model), a null object, or more than 32767.
  SensorRenderer(SensorModel sensor, std::vector<std::shared_ptr<const ObjectShape>> objects,
                 RenderSettings settings);
  ~SensorRenderer();

  // T_sensor_objects[i] is object i's pose in the sensor frame. `noise_seed` seeds this frame's
  // noise (the same seed gives the same image). A pose that is not finite (is_finite: a zero
  // quaternion neither) throws InputError.
  RenderedFrame render(const std::vector<SE3>& T_sensor_objects, std::uint64_t noise_seed) const;
  // The same into `out`, reusing its buffers: no allocation once `out` has the images' sizes.
  // When `out` was last filled by this renderer, only the pixels that differ from the
  // no-contact images, then or now, are rewritten (besides the colour's noise), so a frame
  // without contact costs little more than its noise. So reset `out.filled = {}` before
  // editing or replacing pixels of out.images (an image moved out or resized is detected).
  void render(const std::vector<SE3>& T_sensor_objects, std::uint64_t noise_seed,
              RenderedFrame& out) const;

  const SensorModel& sensor() const;
  const RenderSettings& settings() const;
  // The no-contact images (before noise): what a frame without contact shows.
  const ImageF& background_color() const;
  const ImageU8& background_color_u8() const;  // the same, quantised as colour frames are
  const ImageF& undeformed_normals() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace pg
