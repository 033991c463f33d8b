#pragma once
// Internal to pg_sim: the state of a SensorRenderer, shared by the files of its pipeline:
// renderer.cpp (set-up, and each frame's steps in order), contact_pass.cpp (cull, footprint,
// rigid indentation by rays or rasterization) and frame_outputs.cpp (shading, colour with
// noise, ground truth).
#include <tbb/enumerable_thread_specific.h>

#include <optional>
#include <utility>
#include <vector>

#include "gel_surface.h"
#include "pg/core/pixel_rect.h"
#include "pg/sim/renderer.h"
#include "rasterize.h"
#include "shading.h"
#include "shadows.h"

namespace pg {

// Per row of a rectangle, the run [first, second) of pixels to work on.
using RowRuns = std::vector<std::pair<int, int>>;

// Image-sized scratch arrays and per-frame lists, one set per thread. Between frames `rigid`
// and `u` are zero, `hit_object` -1 and `raster_t` +inf: each frame restores what it wrote.
struct Workspace {
  std::vector<float> rigid, hit_t, u, scratch_a, scratch_b, normals, color;
  std::vector<std::int16_t> hit_object;
  std::vector<float> raster_t;    // first hit per pixel while rasterizing one object
  std::vector<std::int16_t> row;  // one row of fixed-point colour, for the noise pass
  // Per-frame lists, kept from frame to frame to save their allocations.
  std::vector<int> ray_objects, pixels;
  std::vector<char> blocks;        // per 4 x 4 pixel block: marked for rays (cleared when cast)
  PixelRect marked;                // bounds of the marked blocks
  std::vector<SlabClusters> slab;  // per object
  RowRuns runs;
  RowRuns color_runs;         // runs, extended over the undeformed pixels the dent shadows
  std::vector<int> shadowed;  // those pixels
  std::vector<float> soa, visibility, shadowed_rgb;
  ShadowCaster shadows;
  Workspace(int w, int h, int objects, const ShadowCaster& caster);
};

// Where one frame differs from the no-contact frame.
struct FrameRegions {
  PixelRect touched;   // rigid, hit_t and hit_object were written here
  PixelRect contact;   // bounding box of the pixels with a rigid indentation
  float deepest = 0;   // the deepest rigid indentation [m]
  PixelRect deformed;  // u is zero outside
  PixelRect region;    // normals and shading may differ here (deformed, plus a pixel)
  PixelRect shaded;    // colour is shaded here: region, and undeformed gel the dent shadows
  PixelRect color;     // colour may differ here (shaded, plus the background blend's blur)
};

struct SensorRenderer::State {
  SensorModel sensor;
  RenderSettings settings;
  std::vector<std::shared_ptr<const ObjectShape>> objects;
  GelGeometry gel;
  ElasticKernel kernel;
  Shader shader;
  std::optional<NoiseTable> noise;  // when noise is on
  GaussianKernel blend_blur;        // the real background blend's blur (no weights: none)
  // A real background: the shading is blended into it.
  bool background_blend() const { return !settings.background.empty(); }
  ImageF normals0;    // undeformed gel normals
  ImageF sim0;        // shading of the undeformed gel, linear [0, 1]
  ImageF background;  // what a no-contact frame shows: sim0, or the real background
  ImageU8 background_u8;
  std::vector<std::int16_t> background_fixed;  // the same in the noise table's fixed point
  std::uint64_t id = 0;                        // unique in the process: RenderedFrame::filled.by
  mutable tbb::enumerable_thread_specific<Workspace> workspaces;

  State(SensorModel s, std::vector<std::shared_ptr<const ObjectShape>> objs, RenderSettings rs);
  void prepare();
  int width() const { return gel.width; }
  int height() const { return gel.height; }
  int blocks_x() const { return (width() + 3) / 4; }  // 4 x 4 pixel blocks per row
  float slab_m() const { return float(sensor.gel.max_indentation_m); }
  bool noisy() const { return noise.has_value(); }

  // contact_pass.cpp: steps 1-3, the rigid indentation (ws.rigid, hit_t, hit_object).
  void find_contact(const std::vector<SE3>& T_sensor_objects, Workspace& ws, RenderStats& stats,
                    FrameRegions& frame) const;
  PixelRect footprint(const SE3& T_sensor_object, const ObjectShape& shape, bool shallow) const;

  // renderer.cpp: step 4, the elastic deformation and the regions it moves.
  void deform(Workspace& ws, RenderStats& stats, FrameRegions& frame) const;

  // frame_outputs.cpp: steps 5-6.
  // Shades the pixels of `rect` (one row) into rgb; u must be valid around it, and with
  // `shadows` ws.shadows must hold this frame's surface.
  void shade_row(const PixelRect& rect, const float* u, const float* normals, float* rgb,
                 Workspace& ws, bool shadows) const;
  void write_outputs(const std::vector<SE3>& T_sensor_objects, std::uint64_t seed,
                     FrameRegions& frame, Workspace& ws, RenderedFrame& out) const;

 private:
  void mark_blocks(const SlabClusters& slab, const TriangleClusters& clusters,
                   const SE3& T_sensor_object, const PixelRect& footprint, Workspace& ws) const;
  void cast(const std::vector<int>& pixels, const std::vector<int>& objs,
            const std::vector<SE3>& poses, Workspace& ws, RenderStats& stats) const;
  void rasterize_object(int obj, const SE3& T_sensor_object, const PixelRect& rect, Workspace& ws,
                        RenderStats& stats, PixelRect& touched) const;
  long near_gel_pixels(const SlabClusters& slab, const PixelRect& footprint) const;
  // Whether the rasterizer can draw these clusters: all of their boxes in front of the camera's
  // near plane (it projects every corner; one behind the camera would project mirrored).
  bool in_front_of_camera(const SlabClusters& slab) const;
  void record_hit(Workspace& ws, int i, int obj, float t, bool inside) const;
  void write_color(std::uint64_t seed, FrameRegions& frame, bool reuse, Workspace& ws,
                   RenderedFrame& out) const;
  int shade_cast_shadows(FrameRegions& frame, Workspace& ws) const;
  void write_ground_truth(const std::vector<SE3>& T_sensor_objects, const FrameRegions& frame,
                          bool reuse, const Workspace& ws, RenderedFrame& out) const;
};

}  // namespace pg
