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

// Well above float rounding in the vertices and a ray's hit (nanometres) [m].
constexpr double kMargin = 1e-5;

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

// Pixels whose rays could meet the object in front of the gel: its bounds, cut to the slab
// (`shallow`: the object reaches no deeper) or else to the camera's near plane, projected into
// the image (plus a pixel).
PixelRect SensorRenderer::State::footprint(const SE3& T_sensor_object, const ObjectShape& shape,
                                           bool shallow) const {
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
  const CameraModel& c = sensor.camera;
  const double z_lo =
      shallow ? double(gel.z_gel_min) - slab_m() - kMargin : c.near_m - c.distance_m;
  return project_box(c, lo, hi, z_lo, kMargin, width(), height());
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

// Casts the rays of `pixels` against the objects `objs` and records the rigid indentation. An
// object that reaches below the slab (SlabClusters::reach_m infinite) gets rays from the
// camera's near plane: one started at the slab could start inside one closed part of it and
// meet an overlapping part's front face first, which reads as outside. A ray can then start
// inside an object only where the object reaches the near plane; elsewhere a first hit on a face
// turned away is a rounding error where the ray grazes the object's outline, and no contact.
void SensorRenderer::State::cast(const std::vector<int>& pixels, const std::vector<int>& objs,
                                 const std::vector<SE3>& poses, Workspace& ws,
                                 RenderStats& stats) const {
  const float slab = slab_m(), near = float(sensor.camera.near_m);
  RayPacket rays;
  rays.origin_sensor = gel.origin_sensor;
  PacketHits hits;
  for (std::size_t start = 0; start < pixels.size(); start += kPacket) {
    rays.count = int(std::min<std::size_t>(kPacket, pixels.size() - start));
    for (int k = 0; k < rays.count; ++k) rays.dir_sensor[k] = gel.dir_sensor[pixels[start + k]];
    for (int obj : objs) {
      const SlabClusters& clusters = ws.slab[obj];
      const bool from_slab = settings.slab_limited_rays && std::isfinite(clusters.reach_m);
      const bool may_start_inside =
          objects[obj]->any_part_closed() && clusters.triangles > 0 &&
          double(clusters.lo.z()) <= sensor.camera.near_m - sensor.camera.distance_m;
      for (int k = 0; k < rays.count; ++k) {
        const float t_gel = gel.t_gel[pixels[start + k]];
        // Never before the near plane: on a sensor of a few pixels (or a very wide field of
        // view) the slab can reach behind it.
        rays.tnear[k] = from_slab ? std::max(t_gel - slab, near) : near;
        rays.tfar_open[k] = t_gel;
        // Where it may start inside a closed surface, a ray needs its first hit beyond the gel
        // too, to tell inside from outside.
        rays.tfar[k] = may_start_inside ? std::numeric_limits<float>::infinity() : t_gel;
      }
      intersect(*objects[obj], poses[obj], rays, hits);
      stats.rays_cast += rays.count;
      for (int k = 0; k < rays.count; ++k) {
        if (!std::isfinite(hits.t[k]) || (hits.inside[k] && !may_start_inside)) continue;
        record_hit(ws, pixels[start + k], obj, hits.t[k], hits.inside[k]);
      }
    }
  }
}

// Marks in ws.blocks the 4 x 4 pixel blocks that an object's rays must cover: those its clusters
// in the slab (or, reaching below it, in front of the gel) project into, within its footprint.
// Every triangle a ray can meet in front of the gel lies in one of those clusters' boxes, so no
// contact is missed, however thin. Clusters that reach behind the camera (which would project
// mirrored) mark the whole footprint.
void SensorRenderer::State::mark_blocks(const SlabClusters& slab, const TriangleClusters& c,
                                        const SE3& T_sensor_object, const PixelRect& fp,
                                        Workspace& ws) const {
  const auto mark = [&](const PixelRect& r) {
    if (r.empty()) return;
    const PixelRect b =
        PixelRect{r.x0 / 4 * 4, r.y0 / 4 * 4, (r.x1 + 3) / 4 * 4, (r.y1 + 3) / 4 * 4}.clipped(
            width(), height());
    for (int by = b.y0 / 4; by < (b.y1 + 3) / 4; ++by)
      for (int bx = b.x0 / 4; bx < (b.x1 + 3) / 4; ++bx)
        ws.blocks[std::size_t(by) * blocks_x() + bx] = 1;
    ws.marked = ws.marked.united(b);
  };
  if (!in_front_of_camera(slab)) return mark(fp);
  const CameraModel& cam = sensor.camera;
  const Eigen::Matrix3f R = T_sensor_object.rotation_matrix().cast<float>();
  const Eigen::Matrix3f R_abs = R.cwiseAbs();
  const Eigen::Vector3f t = T_sensor_object.translation().cast<float>();
  for (int i : slab.clusters) {
    const auto& cl = c.clusters[std::size_t(i)];
    const Eigen::Vector3f centre = R * cl.centre + t, extent = R_abs * cl.half_extent;
    mark(project_box(cam, (centre - extent).cast<double>(), (centre + extent).cast<double>(),
                     cam.near_m - cam.distance_m, 0.0, width(), height())
             .intersected(fp));
  }
}

// Fine pass for one object by rasterizing its triangles near the gel (ws.slab[obj]) over rect.
void SensorRenderer::State::rasterize_object(int obj, const SE3& T_sensor_object,
                                             const PixelRect& rect, Workspace& ws,
                                             RenderStats& stats, PixelRect& touched) const {
  const SlabClusters& slab = ws.slab[obj];
  SlabRaster raster;
  raster.gel = &gel;
  raster.slab_m = slab.reach_m;
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
  // 1-2. Cull and footprint. Per object, the clusters that can reach in front of the gel: within
  // the slab, or, where the mesh reaches below the slab (where a pixel's ray could start inside
  // it), all the way to the camera. Rasterize them when that is cheaper than the rays, else mark
  // the pixel blocks they project into for rays (without the footprint skip, every pixel).
  ws.ray_objects.clear();
  ws.marked = {};
  for (int i = 0; i < int(objects.size()); ++i) {
    SlabClusters& slab = ws.slab[i];
    const TriangleClusters& clusters = triangle_clusters(*objects[i]);
    clusters_in_slab(clusters, poses[i], gel, slab_m(), slab);
    const bool shallow = slab.lowest_z > -slab_m();
    const PixelRect fp = footprint(poses[i], *objects[i], shallow);
    if (opt.cull && fp.empty()) {
      ++stats.objects_culled;
      continue;
    }
    if (!shallow) {
      clusters_in_slab(clusters, poses[i], gel, std::numeric_limits<float>::infinity(), slab);
    }
    if (!opt.footprint) {
      ws.ray_objects.push_back(i);
      continue;
    }
    if (slab.clusters.empty()) continue;  // nothing of it in front of the gel
    if (opt.rasterize && in_front_of_camera(slab) &&
        double(slab.triangles) <= kTrianglesPerRay * double(near_gel_pixels(slab, fp))) {
      rasterize_object(i, poses[i], fp, ws, stats, frame.touched);
      continue;
    }
    ws.ray_objects.push_back(i);
    mark_blocks(slab, clusters, poses[i], fp, ws);
  }

  // 3. The rest by rays, every pixel of the marked blocks, in 4 x 4 blocks so that each ray
  // packet is coherent.
  if (!ws.ray_objects.empty()) {
    ws.pixels.clear();
    const PixelRect r = opt.footprint ? ws.marked : all;
    for (int by = r.y0 / 4 * 4; by < r.y1; by += 4) {
      for (int bx = r.x0 / 4 * 4; bx < r.x1; bx += 4) {
        if (opt.footprint && !ws.blocks[std::size_t(by / 4) * blocks_x() + bx / 4]) continue;
        ws.blocks[std::size_t(by / 4) * blocks_x() + bx / 4] = 0;
        for (int y = by; y < std::min(by + 4, height()); ++y)
          for (int x = bx; x < std::min(bx + 4, width()); ++x) ws.pixels.push_back(gel.index(x, y));
      }
    }
    if (!ws.pixels.empty()) {
      cast(ws.pixels, ws.ray_objects, poses, ws, stats);
      frame.touched = frame.touched.united(r);
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
