// Steps 1-3 of the pipeline (DESIGN.md, "Renderer pipeline"): cull the objects that cannot reach
// the gel, bound each one's footprint in the image, and find the rigid indentation per pixel,
// by rasterizing the object's triangles near the gel or by casting rays, whichever is cheaper.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "raycast.h"
#include "render_state.h"

namespace pg {

namespace {

// Measured with tacsim bench on the development machine: a ray through an object's BVH costs
// 150-400 ns (more for bigger meshes), a triangle near the gel 8 ns to cull and draw when it
// is smaller than a pixel, about 50 ns when it covers ten.
constexpr double kTrianglesPerRay = 16.0;

// The image rectangle (plus a pixel) that the sensor-frame box [lo, hi] projects to, with z cut
// to [z_lo, z_hi]; empty if the box lies outside that z range.
PixelRect project_box(const CameraModel& cam, Eigen::Vector3d lo, Eigen::Vector3d hi, double z_lo,
                      double z_hi, int width, int height) {
  lo.z() = std::max(lo.z(), z_lo);
  hi.z() = std::min(hi.z(), z_hi);
  if (lo.z() > hi.z()) return {};
  PixelRect r{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(),
              std::numeric_limits<int>::min(), std::numeric_limits<int>::min()};
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d p((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(),
                            (k & 4) ? hi.z() : lo.z());
    // Clamped near the image before the conversion to int: a corner of a huge object projects
    // beyond int's range (its footprint came out empty and the object was culled).
    const Eigen::Vector2d px = cam.project(p + Eigen::Vector3d(0, 0, cam.distance_m))
                                   .cwiseMax(Eigen::Vector2d(-4.0, -4.0))
                                   .cwiseMin(Eigen::Vector2d(width + 4.0, height + 4.0));
    r.x0 = std::min(r.x0, int(std::floor(px.x())));
    r.y0 = std::min(r.y0, int(std::floor(px.y())));
    r.x1 = std::max(r.x1, int(std::ceil(px.x())) + 1);
    r.y1 = std::max(r.y1, int(std::ceil(px.y())) + 1);
  }
  return r.dilated(1).clipped(width, height);
}

// record_hit for one row of an object's raster hits (+inf where none), as a vector loop; also
// cleans the raster for the next object. The rasterizer is used only where no ray starts inside
// the object, so a hit is never inside. Not inlined: GCC 12 drops restrict when inlining.
__attribute__((noinline)) void record_raster_row(int n, std::int16_t obj,
                                                 const float* __restrict t_gel,
                                                 float* __restrict raster_t,
                                                 float* __restrict rigid, float* __restrict hit_t,
                                                 std::int16_t* __restrict hit_object) {
  for (int i = 0; i < n; ++i) {
    const float t = raster_t[i];
    const float pen = t_gel[i] - t;
    const bool keep = (t < INFINITY) & (pen > 0.0f) & (pen > rigid[i]);
    rigid[i] = keep ? pen : rigid[i];
    hit_t[i] = keep ? t : hit_t[i];
    hit_object[i] = keep ? obj : hit_object[i];
    raster_t[i] = INFINITY;
  }
}

// Clamps one row of the rigid indentation to the slab; counts its contact and clamped pixels
// and keeps its deepest value. A vector loop: the indentation is never negative, and
// non-negative floats order like their bit patterns, whose maximum vectorises (a float
// maximum does not, for the sake of NaN).
__attribute__((noinline)) void clamp_row(int n, float slab, float* __restrict rigid,
                                         RenderStats& stats, float& deepest) {
  int contact = 0, clamped = 0;
  std::int32_t deepest_bits = 0;
  for (int i = 0; i < n; ++i) {
    const float r = rigid[i];
    contact += r > 0.0f;
    clamped += r > slab;
    const float c = r > slab ? slab : r;
    rigid[i] = c;
    std::int32_t bits;
    std::memcpy(&bits, &c, sizeof(bits));
    deepest_bits = std::max(deepest_bits, bits);
  }
  stats.contact_pixels += contact;
  stats.clamped_pixels += clamped;
  float d;
  std::memcpy(&d, &deepest_bits, sizeof(d));
  deepest = std::max(deepest, d);
}

}  // namespace

// Pixels whose rays could meet the object: its bounds, cut to the slab the gel can be indented
// in, projected into the image (plus a pixel).
PixelRect SensorRenderer::State::footprint(const SE3& T_sensor_object,
                                           const ObjectShape& shape) const {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d hi = -lo;
  const Bounds3& b = shape.bounds();
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d corner((k & 1) ? b.max.x() : b.min.x(), (k & 2) ? b.max.y() : b.min.y(),
                                 (k & 4) ? b.max.z() : b.min.z());
    const Eigen::Vector3d p = T_sensor_object * corner;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  return project_box(sensor.camera, lo, hi, double(gel.z_gel_min) - slab_m() - margin_m,
                     double(margin_m), width(), height());
}

// About how many pixels the object's triangles near the gel cover: the projected bounds of
// their clusters, within the footprint.
long SensorRenderer::State::near_gel_pixels(const SlabClusters& slab, const PixelRect& fp) const {
  if (slab.clusters.empty()) return 0;
  const CameraModel& c = sensor.camera;  // cut to what lies in front of the camera
  const PixelRect r =
      project_box(c, slab.lo.cast<double>(), slab.hi.cast<double>(), c.near_m - c.distance_m,
                  std::numeric_limits<double>::infinity(), width(), height());
  return r.intersected(fp).area();
}

// Fine pass: keeps the deepest penetration over objects at pixel i, from a first hit at camera
// depth t (`inside`: the hit faces away on a closed surface, so the ray started inside).
void SensorRenderer::State::record_hit(Workspace& ws, int i, int obj, float t, bool inside) const {
  const float pen = inside ? std::numeric_limits<float>::infinity() : gel.t_gel[i] - t;
  if (pen <= 0.0f || pen <= ws.rigid[i]) return;
  ws.rigid[i] = pen;
  // A ray that starts inside the object meets no surface of it: no contact point there.
  ws.hit_t[i] = inside ? std::numeric_limits<float>::quiet_NaN() : t;
  ws.hit_object[i] = std::int16_t(obj);
}

// Casts the rays of `pixels` against the objects `objs`. Fine pass: records the rigid
// indentation. Coarse pass: marks in ws.near the pixels where an object comes within margin_m
// of the gel, and sets *deep where one reaches deeper than the gel allows.
void SensorRenderer::State::cast(const std::vector<int>& pixels, const std::vector<int>& objs,
                                 const std::vector<SE3>& poses, bool coarse, Workspace& ws,
                                 RenderStats& stats, bool* deep) const {
  const float slab = slab_m();
  const float extra = coarse ? margin_m : 0.0f;
  RayPacket rays;
  rays.origin_sensor = gel.origin_sensor;
  PacketHits hits;
  for (std::size_t start = 0; start < pixels.size(); start += kPacket) {
    rays.count = int(std::min<std::size_t>(kPacket, pixels.size() - start));
    for (int k = 0; k < rays.count; ++k) {
      const int i = pixels[start + k];
      rays.dir_sensor[k] = gel.dir_sensor[i];
      // Never before the camera's near plane: on a sensor of a few pixels (or a very wide field
      // of view) a tile's margin is centimetres, more than the gel's distance.
      rays.tnear[k] = settings.slab_limited_rays
                          ? std::max(gel.t_gel[i] - slab - extra, float(sensor.camera.near_m))
                          : float(sensor.camera.near_m);
    }
    for (int obj : objs) {
      const ObjectShape& shape = *objects[obj];
      for (int k = 0; k < rays.count; ++k) {
        // A closed surface needs its first hit beyond the gel too, to tell inside from outside.
        rays.tfar_open[k] = gel.t_gel[pixels[start + k]] + extra;
        rays.tfar[k] =
            shape.any_part_closed() ? std::numeric_limits<float>::infinity() : rays.tfar_open[k];
      }
      intersect(shape, poses[obj], rays, hits);
      stats.rays_cast += rays.count;
      for (int k = 0; k < rays.count; ++k) {
        const int i = pixels[start + k];
        if (!std::isfinite(hits.t[k])) continue;
        if (!coarse) {
          record_hit(ws, i, obj, hits.t[k], hits.inside[k]);
          continue;
        }
        const bool inside = hits.inside[k];
        const float pen = gel.t_gel[i] - hits.t[k];
        if (inside || pen > -margin_m) ws.near[start + k] = 1;
        if (inside || pen >= slab) *deep = true;
      }
    }
  }
}

// Coarse pass over `rect`'s tile corners for ws.coarse_objects; fills ws.pixels with every
// pixel of the tiles near the gel, in 4x4 blocks so that each ray packet is coherent.
void SensorRenderer::State::coarse_pass(const std::vector<SE3>& poses, const PixelRect& r,
                                        Workspace& ws, RenderStats& stats, bool& deep) const {
  const int nx = (r.width() + tile - 1) / tile, ny = (r.height() + tile - 1) / tile;
  ws.corners.clear();
  for (int b = 0; b <= ny; ++b)
    for (int a = 0; a <= nx; ++a)
      ws.corners.push_back(
          gel.index(std::min(r.x0 + a * tile, r.x1 - 1), std::min(r.y0 + b * tile, r.y1 - 1)));
  ws.near.assign(ws.corners.size(), 0);
  cast(ws.corners, ws.coarse_objects, poses, true, ws, stats, &deep);
  for (int b = 0; b < ny; ++b) {
    for (int a = 0; a < nx; ++a) {
      const int c = b * (nx + 1) + a;
      if (!(ws.near[c] || ws.near[c + 1] || ws.near[c + nx + 1] || ws.near[c + nx + 2])) continue;
      const PixelRect t =
          PixelRect{r.x0 + a * tile, r.y0 + b * tile, r.x0 + (a + 1) * tile, r.y0 + (b + 1) * tile}
              .clipped(r.x1, r.y1);
      for (int by = t.y0; by < t.y1; by += 4)
        for (int bx = t.x0; bx < t.x1; bx += 4)
          for (int y = by; y < std::min(by + 4, t.y1); ++y)
            for (int x = bx; x < std::min(bx + 4, t.x1); ++x) ws.pixels.push_back(gel.index(x, y));
    }
  }
}

// Fine pass for one object by rasterizing its triangles near the gel (ws.slab[obj]) over rect.
void SensorRenderer::State::rasterize_object(int obj, const SE3& T_sensor_object,
                                             const PixelRect& rect, Workspace& ws,
                                             RenderStats& stats, PixelRect& touched) const {
  const SlabClusters& slab = ws.slab[obj];
  SlabRaster raster;
  raster.gel = &gel;
  raster.slab_m = slab_m();
  raster.front_faces_only = objects[obj]->closed();
  raster.rect = rect;
  raster.hit_t = ws.raster_t.data();
  const auto& c = sensor.camera;
  rasterize_clusters(triangle_clusters(*objects[obj]), slab.clusters, T_sensor_object,
                     Eigen::Vector4d(c.fx, c.fy, c.cx, c.cy), raster);
  stats.triangles_rasterized += slab.triangles;
  const PixelRect& r = raster.touched;
  for (int y = r.y0; y < r.y1; ++y) {
    const int i = gel.index(r.x0, y);
    record_raster_row(r.width(), std::int16_t(obj), &gel.t_gel[i], &ws.raster_t[i], &ws.rigid[i],
                      &ws.hit_t[i], &ws.hit_object[i]);
  }
  touched = touched.united(r);
}

bool SensorRenderer::State::in_front_of_camera(const SlabClusters& slab) const {
  // A table-sized object pressed at a tilt: its clusters near the gel reach behind the camera
  // (their contact had vanished from every output); rays see it. So do clusters wider than a
  // metre, whose corners project beyond what the rasterizer's float edge functions resolve.
  const CameraModel& c = sensor.camera;
  constexpr float kWidest = 1.0f;  // [m]
  return slab.triangles == 0 ||
         (double(slab.lo.z()) > c.near_m - c.distance_m &&
          slab.lo.head<2>().minCoeff() > -kWidest && slab.hi.head<2>().maxCoeff() < kWidest);
}

void SensorRenderer::State::find_contact(const std::vector<SE3>& poses, Workspace& ws,
                                         RenderStats& stats, FrameRegions& frame) const {
  const RenderSettings& opt = settings;
  const PixelRect all{0, 0, width(), height()};
  // 1-2. Cull and footprint; rasterize right away the objects that need no rays: those that no
  // ray can start inside (their lowest point is above every ray's start, the bottom of the
  // slab) and whose triangles near the gel are cheaper to draw than the rays would be to cast.
  ws.coarse_objects.clear();
  PixelRect coarse_rect;
  for (int i = 0; i < int(objects.size()); ++i) {
    const PixelRect fp = footprint(poses[i], *objects[i]);
    if (opt.cull && fp.empty()) {
      ++stats.objects_culled;
      continue;
    }
    if (opt.rasterize && opt.footprint) {
      SlabClusters& slab = ws.slab[i];
      clusters_in_slab(triangle_clusters(*objects[i]), poses[i], gel, slab_m(), slab);
      const bool shallow = slab.lowest_z > -slab_m();
      const long corners = long(fp.width() / tile + 2) * (fp.height() / tile + 2);
      const long rays = corners + near_gel_pixels(slab, fp);
      if (shallow && in_front_of_camera(slab) &&
          double(slab.triangles) <= kTrianglesPerRay * double(rays)) {
        rasterize_object(i, poses[i], fp, ws, stats, frame.touched);
        continue;
      }
    }
    ws.coarse_objects.push_back(i);
    coarse_rect = coarse_rect.united(opt.footprint ? fp : all);
  }

  // 3. The rest by rays: a coarse pass over the footprint's tile corners, then every pixel of
  // the tiles near the gel (without the footprint skip, every pixel). Per object, rasterize
  // the triangles near the gel or cast the rays, whichever is cheaper; but rays where the
  // coarse pass saw an object deeper than the gel allows: only a ray can tell that it starts
  // inside the object where no surface crosses the slab.
  if (!ws.coarse_objects.empty()) {
    ws.pixels.clear();
    bool deep = !opt.footprint;  // without the coarse pass, assume the worst
    if (opt.footprint) {
      coarse_pass(poses, coarse_rect, ws, stats, deep);
    } else {
      const PixelRect& r = coarse_rect;
      for (int by = r.y0; by < r.y1; by += 4)
        for (int bx = r.x0; bx < r.x1; bx += 4)
          for (int y = by; y < std::min(by + 4, r.y1); ++y)
            for (int x = bx; x < std::min(bx + 4, r.x1); ++x) ws.pixels.push_back(gel.index(x, y));
    }
    ws.ray_objects.clear();
    for (int obj : ws.coarse_objects) {
      if (opt.rasterize && opt.footprint && !deep && !ws.pixels.empty() &&
          in_front_of_camera(ws.slab[obj]) &&
          double(ws.slab[obj].triangles) <= kTrianglesPerRay * double(ws.pixels.size())) {
        rasterize_object(obj, poses[obj], coarse_rect, ws, stats, frame.touched);
      } else {
        ws.ray_objects.push_back(obj);
      }
    }
    if (!ws.ray_objects.empty() && !ws.pixels.empty()) {
      cast(ws.pixels, ws.ray_objects, poses, false, ws, stats);
      frame.touched = frame.touched.united(coarse_rect);
    }
  }

  // Clamp what reaches beyond the gel's maximum indentation, and bound the contact.
  const PixelRect& t = frame.touched;
  int x0 = t.x1, x1 = t.x0, y0 = t.y1, y1 = t.y0;
  for (int y = t.y0; y < t.y1; ++y) {
    float* row = &ws.rigid[gel.index(0, y)];
    const int before = stats.contact_pixels;
    clamp_row(t.width(), slab_m(), row + t.x0, stats, frame.deepest);
    if (stats.contact_pixels == before) continue;
    int a = t.x0, b = t.x1;
    while (!(row[a] > 0.0f)) ++a;
    while (!(row[b - 1] > 0.0f)) --b;
    x0 = std::min(x0, a);
    x1 = std::max(x1, b);
    y0 = std::min(y0, y);
    y1 = y + 1;
  }
  frame.contact = PixelRect{x0, y0, x1, y1};
  if (frame.contact.empty()) frame.contact = {};
  if (objects.size() > 1) {
    stats.object_contact_pixels.assign(objects.size(), 0);
    const PixelRect& r = frame.contact;
    for (int y = r.y0; y < r.y1; ++y) {
      for (int x = r.x0; x < r.x1; ++x) {
        const int i = gel.index(x, y);
        if (ws.rigid[i] > 0.0f) ++stats.object_contact_pixels[std::size_t(ws.hit_object[i])];
      }
    }
  }
}

}  // namespace pg
