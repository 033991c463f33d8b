// Per-frame pipeline (DESIGN.md, "Renderer pipeline"): cull -> footprint -> rays -> indentation ->
// elastic deformation -> normals -> shading -> background blend -> noise; each step only over the
// pixels it can change, and only for the outputs asked for.
#include "pg/sim/renderer.h"

#include <tbb/enumerable_thread_specific.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "gel_surface.h"
#include "pg/core/error.h"
#include "rasterize.h"
#include "raycast.h"
#include "shading.h"

namespace pg {

namespace {

// Image-sized scratch arrays, one set per thread. Between frames `rigid`, `hit_object` and `u`
// are all zero / -1: each frame clears what it wrote.
struct Workspace {
  std::vector<float> rigid, hit_t, u, scratch, normals, color, blend_a, blend_b;
  std::vector<std::int16_t> hit_object;
  std::vector<float> raster_t;              // first hit per pixel while rasterizing one object
  std::vector<std::uint8_t> raster_back;
  std::vector<float> row;  // one row of 0-255 colour values, for the noise pass
  explicit Workspace(int w, int h)
      : rigid(std::size_t(w) * h, 0.0f),
        hit_t(std::size_t(w) * h, 0.0f),
        u(std::size_t(w) * h, 0.0f),
        scratch(std::size_t(w) * h, 0.0f),
        normals(std::size_t(w) * h * 3, 0.0f),
        color(std::size_t(w) * h * 3, 0.0f),
        blend_a(std::size_t(w) * h, 0.0f),
        blend_b(std::size_t(w) * h, 0.0f),
        hit_object(std::size_t(w) * h, -1),
        raster_t(std::size_t(w) * h, INFINITY),
        raster_back(std::size_t(w) * h, 0),
        row(std::size_t(w) * 3, 0.0f) {}
};

ImageF resample_bilinear(const ImageF& src, int w, int h) {
  if (src.width == w && src.height == h) return src;
  ImageF dst(w, h, src.channels);
  // Integer downsampling factors average whole blocks; anything else is bilinear.
  const bool block = src.width % w == 0 && src.height % h == 0 && src.width / w == src.height / h;
  const int f = block ? src.width / w : 1;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < src.channels; ++c) {
        float v = 0.0f;
        if (block) {
          for (int dy = 0; dy < f; ++dy)
            for (int dx = 0; dx < f; ++dx) v += src.at(x * f + dx, y * f + dy, c);
          v /= float(f * f);
        } else {
          const float sx = std::clamp((x + 0.5f) * src.width / w - 0.5f, 0.0f, src.width - 1.0f);
          const float sy = std::clamp((y + 0.5f) * src.height / h - 0.5f, 0.0f, src.height - 1.0f);
          const int x0 = int(sx), y0 = int(sy);
          const int x1 = std::min(x0 + 1, src.width - 1), y1 = std::min(y0 + 1, src.height - 1);
          const float ax = sx - x0, ay = sy - y0;
          v = (1 - ay) * ((1 - ax) * src.at(x0, y0, c) + ax * src.at(x1, y0, c)) +
              ay * ((1 - ax) * src.at(x0, y1, c) + ax * src.at(x1, y1, c));
        }
        dst.at(x, y, c) = v;
      }
    }
  }
  return dst;
}

// Per row of `region`, the run [first, second) of pixels whose normal or shading can differ from
// the undeformed gel's: those whose displacement, or a 3x3 neighbour's, is non-zero. Without
// contact (the no-contact cache switched off) every row is one full run.
std::vector<std::pair<int, int>> moved_runs(int width, const float* u,
                                            const PixelRect& region, bool contact) {
  std::vector<std::pair<int, int>> runs(std::size_t(region.height()), {region.x0, region.x1});
  if (!contact) return runs;
  std::vector<std::pair<int, int>> moved(runs.size(), {region.x1, region.x0});
  for (int y = region.y0; y < region.y1; ++y) {
    auto& m = moved[y - region.y0];
    for (int x = region.x0; x < region.x1; ++x) {
      if (u[y * width + x] > 0.0f) {
        m.first = std::min(m.first, x);
        m.second = std::max(m.second, x + 1);
      }
    }
  }
  for (int r = 0; r < int(runs.size()); ++r) {
    int x0 = region.x1, x1 = region.x0;
    for (int d = -1; d <= 1; ++d) {
      if (r + d < 0 || r + d >= int(runs.size())) continue;
      x0 = std::min(x0, moved[r + d].first - 1);
      x1 = std::max(x1, moved[r + d].second + 1);
    }
    runs[r] = {std::max(x0, region.x0), std::min(x1, region.x1)};
  }
  return runs;
}

}  // namespace

struct SensorRenderer::State {
  SensorModel sensor;
  RenderSettings settings;
  std::vector<std::shared_ptr<const ObjectShape>> objects;
  GelGeometry gel;
  ElasticKernel kernel;
  Shader shader;
  NoiseTable noise;
  int tile = 4;          // coarse-pass tile size [px], a multiple of the 4x4 ray packets
  float margin_m = 0;    // a coarse ray within this of the gel marks its tiles for full casting
  int blend_radius = 0;  // box radius of the real-background blend blur, 0 without one
  ImageF normals0;       // undeformed gel normals
  ImageF sim0;           // shading of the undeformed gel, linear [0, 1]
  ImageF background;     // what a no-contact frame shows: sim0, or the real background
  std::vector<float> background_255;
  ImageU8 background_u8;
  mutable tbb::enumerable_thread_specific<Workspace> workspaces;

  State(SensorModel s, std::vector<std::shared_ptr<const ObjectShape>> objs, RenderSettings rs)
      : sensor(std::move(s)),
        settings(std::move(rs)),
        objects(std::move(objs)),
        workspaces([this] { return Workspace(gel.width, gel.height); }) {}

  int width() const { return gel.width; }
  int height() const { return gel.height; }
  float slab_m() const { return float(sensor.gel.max_indentation_m); }

  // Shades the pixels of `rect`; u must be valid on `deformed` (zero elsewhere).
  void shade_rect(const PixelRect& rect, const PixelRect& deformed, const float* u,
                  const float* normals, float* rgb) const;
  void prepare();
  PixelRect footprint(const SE3& T_sensor_object, const ObjectShape& shape) const;
  void cast(const std::vector<int>& pixels, const std::vector<int>& active,
            const std::vector<SE3>& poses, bool coarse, Workspace& ws, RenderStats& stats,
            std::vector<char>* near = nullptr, bool* deep = nullptr) const;
  // Fine pass for one object by rasterization, if its triangles near the gel are cheaper to
  // draw than `rays` rays; returns false (nothing done) otherwise.
  bool rasterize_object(int obj, const SE3& T_sensor_object, const PixelRect& rect, long rays,
                        Workspace& ws, RenderStats& stats) const;
  // Fine pass: keeps the deepest penetration over objects at pixel i, from a first hit at
  // camera depth t (a hit that faces away, on a closed mesh, means the ray started inside).
  void record_hit(Workspace& ws, int i, int obj, float t, bool back_face) const {
    const bool inside = objects[obj]->closed() && back_face;
    const float pen = inside ? std::numeric_limits<float>::infinity() : gel.t_gel[i] - t;
    if (pen <= 0.0f || pen <= ws.rigid[i]) return;
    ws.rigid[i] = pen;
    ws.hit_t[i] = inside ? gel.t_gel[i] - slab_m() : t;
    ws.hit_object[i] = std::int16_t(obj);
  }
  void finish_color(const PixelRect& region, const float* rgb, std::uint64_t seed, ImageU8& out,
                    Workspace& ws) const;
};

void SensorRenderer::State::shade_rect(const PixelRect& rect, const PixelRect& deformed,
                                       const float* u, const float* normals, float* rgb) const {
  const int n = rect.width();
  if (n <= 0) return;
  thread_local std::vector<float> soa, visibility;
  soa.resize(std::size_t(n) * 6);
  const bool shadows = settings.shadows;
  const std::size_t lights = shader.lights.size();
  if (shadows) visibility.resize(lights * n);
  std::vector<float> vis_one(lights);
  ShadeSpan span;
  span.count = n;
  span.px = soa.data();
  span.py = soa.data() + n;
  span.pz = soa.data() + 2 * n;
  span.nx = soa.data() + 3 * n;
  span.ny = soa.data() + 4 * n;
  span.nz = soa.data() + 5 * n;
  span.visibility = shadows ? visibility.data() : nullptr;
  float* out = soa.data();
  for (int y = rect.y0; y < rect.y1; ++y) {
    for (int k = 0; k < n; ++k) {
      const int i = gel.index(rect.x0 + k, y);
      const Eigen::Vector3f p = gel.point(i, u[i]);
      out[k] = p.x();
      out[n + k] = p.y();
      out[2 * n + k] = p.z();
      out[3 * n + k] = normals[3 * i];
      out[4 * n + k] = normals[3 * i + 1];
      out[5 * n + k] = normals[3 * i + 2];
      if (shadows) {
        light_visibility(shader, gel, sensor, u, deformed, i, vis_one.data());
        for (std::size_t l = 0; l < lights; ++l) visibility[l * n + k] = vis_one[l];
      }
    }
    shade_span(shader, span, rgb + 3 * std::size_t(gel.index(rect.x0, y)));
  }
}

void SensorRenderer::State::prepare() {
  gel = make_gel_geometry(sensor);
  kernel = make_elastic_kernel(sensor.gel.elastic, gel.px_per_m);
  shader = make_shader(sensor);
  // Tiles of about 0.3 mm; a coarse ray counts as near when the object is within two tile widths
  // of the gel, which catches any contact whose surface rises slower than about 63 degrees.
  tile = std::max(4, 4 * int(std::lround(0.0003 * gel.px_per_m / 4.0)));
  margin_m = 2.0f * float(tile) / gel.px_per_m;
  const int w = width(), h = height();
  const PixelRect all{0, 0, w, h};
  std::vector<float> zero(std::size_t(w) * h, 0.0f);
  normals0 = ImageF(w, h, 3);
  surface_normals(gel, zero.data(), all, normals0.data.data());
  sim0 = ImageF(w, h, 3);
  shade_rect(all, all, zero.data(), normals0.data.data(), sim0.data.data());
  background = sim0;
  if (!settings.background.empty()) {
    const ImageF real = read_image_float(settings.background);
    if (real.channels < 3) {
      throw InputError(settings.background + ": background image must be RGB");
    }
    ImageF rgb(real.width, real.height, 3);
    for (int y = 0; y < real.height; ++y)
      for (int x = 0; x < real.width; ++x)
        for (int c = 0; c < 3; ++c) rgb.at(x, y, c) = real.at(x, y, c);
    background = resample_bilinear(rgb, w, h);
    blend_radius = gaussian_box_radius(sensor.shading.background_blur_m * gel.px_per_m);
  }
  background_255.resize(background.data.size());
  background_u8 = ImageU8(w, h, 3);
  for (std::size_t i = 0; i < background.data.size(); ++i) {
    background_255[i] = std::clamp(background.data[i], 0.0f, 1.0f) * 255.0f;
    background_u8.data[i] = std::uint8_t(background_255[i] + 0.5f);
  }
}

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
  const double z_lo = std::max(lo.z(), double(gel.z_gel_min) - slab_m() - margin_m);
  const double z_hi = std::min(hi.z(), double(margin_m));
  if (z_lo > z_hi) return {};
  const CameraModel& cam = sensor.camera;
  PixelRect r{std::numeric_limits<int>::max(), std::numeric_limits<int>::max(),
              std::numeric_limits<int>::min(), std::numeric_limits<int>::min()};
  for (int k = 0; k < 8; ++k) {
    const Eigen::Vector3d p((k & 1) ? hi.x() : lo.x(), (k & 2) ? hi.y() : lo.y(),
                            (k & 4) ? z_hi : z_lo);
    const Eigen::Vector2d px = cam.project(p + Eigen::Vector3d(0, 0, cam.distance_m));
    r.x0 = std::min(r.x0, int(std::floor(px.x())));
    r.y0 = std::min(r.y0, int(std::floor(px.y())));
    r.x1 = std::max(r.x1, int(std::ceil(px.x())) + 1);
    r.y1 = std::max(r.y1, int(std::ceil(px.y())) + 1);
  }
  return r.dilated(1).clipped(width(), height());
}

// Casts the rays of `pixels` against every active object. Fine pass: records the rigid
// indentation (deepest over objects, clamped to the slab). Coarse pass: marks in `near` the
// pixels where an object comes within margin_m of the gel.
void SensorRenderer::State::cast(const std::vector<int>& pixels, const std::vector<int>& active,
                                 const std::vector<SE3>& poses, bool coarse, Workspace& ws,
                                 RenderStats& stats, std::vector<char>* near, bool* deep) const {
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
      rays.tnear[k] =
          settings.slab_limited_rays ? gel.t_gel[i] - slab - extra : float(sensor.camera.near_m);
    }
    for (int obj : active) {
      const ObjectShape& shape = *objects[obj];
      for (int k = 0; k < rays.count; ++k) {
        // A closed mesh needs its first surface beyond the gel too, to tell inside from outside.
        rays.tfar[k] = shape.closed() ? std::numeric_limits<float>::infinity()
                                      : gel.t_gel[pixels[start + k]] + extra;
      }
      intersect(shape, poses[obj], rays, hits);
      stats.rays_cast += rays.count;
      for (int k = 0; k < rays.count; ++k) {
        const int i = pixels[start + k];
        if (!std::isfinite(hits.t[k])) continue;
        if (!coarse) {
          record_hit(ws, i, obj, hits.t[k], hits.back_face[k]);
          continue;
        }
        const bool inside = shape.closed() && hits.back_face[k];
        const float pen = gel.t_gel[i] - hits.t[k];
        if (inside || pen > -margin_m) (*near)[start + k] = 1;
        if (inside || pen >= slab) *deep = true;
      }
    }
  }
}

bool SensorRenderer::State::rasterize_object(int obj, const SE3& T_sensor_object,
                                             const PixelRect& rect, long rays, Workspace& ws,
                                             RenderStats& stats) const {
  // Measured on this machine: a ray costs about as much as drawing three small triangles.
  constexpr double kTrianglesPerRay = 3.0;
  const TriangleClusters& clusters = triangle_clusters(*objects[obj]);
  const std::vector<int> near_gel =
      clusters_in_slab(clusters, T_sensor_object, gel.z_gel_min - slab_m(), 0.0f);
  const long triangles = triangle_count(clusters, near_gel);
  if (double(triangles) > kTrianglesPerRay * double(rays)) return false;
  for (int y = rect.y0; y < rect.y1; ++y) {
    std::fill_n(&ws.raster_t[gel.index(rect.x0, y)], rect.width(), INFINITY);
  }
  SlabRaster raster;
  raster.gel = &gel;
  raster.slab_m = slab_m();
  raster.rect = rect;
  raster.hit_t = ws.raster_t.data();
  raster.back = ws.raster_back.data();
  const auto& c = sensor.camera;
  rasterize_clusters(objects[obj]->mesh(), clusters, near_gel, T_sensor_object,
                     Eigen::Vector4d(c.fx, c.fy, c.cx, c.cy), raster);
  stats.triangles_rasterized += triangles;
  for (int y = rect.y0; y < rect.y1; ++y) {
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = gel.index(x, y);
      if (std::isfinite(ws.raster_t[i])) record_hit(ws, i, obj, ws.raster_t[i], ws.raster_back[i]);
    }
  }
  return true;
}

void SensorRenderer::State::finish_color(const PixelRect& region, const float* rgb,
                                         std::uint64_t seed, ImageU8& out, Workspace& ws) const {
  const int w = width(), h = height();
  out = settings.noise && sensor.noise.sigma > 0 ? ImageU8(w, h, 3) : background_u8;
  const bool noisy = settings.noise && sensor.noise.sigma > 0;
  const float sigma = float(sensor.noise.sigma);
  for (int y = 0; y < h; ++y) {
    const std::size_t row0 = std::size_t(y) * w * 3;
    const bool in_region = y >= region.y0 && y < region.y1;
    if (!in_region) {
      if (noisy)
        noise.apply(&background_255[row0], &out.data[row0], std::size_t(w) * 3, sigma, seed, row0);
      continue;
    }
    float* row = ws.row.data();
    std::memcpy(row, &background_255[row0], sizeof(float) * w * 3);
    for (int x = region.x0; x < region.x1; ++x) {
      for (int c = 0; c < 3; ++c)
        row[3 * x + c] = std::clamp(rgb[row0 + 3 * x + c], 0.0f, 1.0f) * 255.0f;
    }
    if (noisy) {
      noise.apply(row, &out.data[row0], std::size_t(w) * 3, sigma, seed, row0);
    } else {
      for (int x = region.x0; x < region.x1; ++x)
        for (int c = 0; c < 3; ++c)
          out.data[row0 + 3 * x + c] = std::uint8_t(row[3 * x + c] + 0.5f);
    }
  }
}

SensorRenderer::SensorRenderer(SensorModel sensor,
                               std::vector<std::shared_ptr<const ObjectShape>> objects,
                               RenderSettings settings)
    : state_(std::make_unique<State>(std::move(sensor), std::move(objects), std::move(settings))) {
  state_->prepare();
}

SensorRenderer::~SensorRenderer() = default;

const SensorModel& SensorRenderer::sensor() const { return state_->sensor; }
const RenderSettings& SensorRenderer::settings() const { return state_->settings; }
const ImageF& SensorRenderer::background_color() const { return state_->background; }
const ImageF& SensorRenderer::undeformed_normals() const { return state_->normals0; }

RenderedFrame SensorRenderer::render(const std::vector<SE3>& T_sensor_objects,
                                     std::uint64_t noise_seed) const {
  const State& s = *state_;
  if (T_sensor_objects.size() != s.objects.size()) {
    throw std::invalid_argument("SensorRenderer::render: one pose per object expected");
  }
  const int w = s.width(), h = s.height();
  const PixelRect all{0, 0, w, h};
  const RenderSettings& opt = s.settings;
  RenderedFrame out;
  RenderStats& stats = out.stats;
  Workspace& ws = s.workspaces.local();

  // 1-2. Cull and footprint.
  std::vector<int> active;
  PixelRect cast_rect;
  for (std::size_t i = 0; i < s.objects.size(); ++i) {
    const PixelRect fp = s.footprint(T_sensor_objects[i], *s.objects[i]);
    if (opt.cull && fp.empty()) {
      ++stats.objects_culled;
      continue;
    }
    active.push_back(int(i));
    cast_rect = cast_rect.united(opt.footprint ? fp : all);
  }

  // 3. Rays: a coarse pass over the footprint's tile corners, then every pixel of the tiles near
  // the gel. Without the footprint skip, every pixel.
  PixelRect contact;
  if (!active.empty()) {
    std::vector<int> pixels;
    bool deep = !opt.footprint;  // without the coarse pass, assume the worst
    if (opt.footprint) {
      const PixelRect& r = cast_rect;
      const int nx = (r.width() + s.tile - 1) / s.tile, ny = (r.height() + s.tile - 1) / s.tile;
      std::vector<int> corners;
      for (int b = 0; b <= ny; ++b)
        for (int a = 0; a <= nx; ++a)
          corners.push_back(s.gel.index(std::min(r.x0 + a * s.tile, r.x1 - 1),
                                        std::min(r.y0 + b * s.tile, r.y1 - 1)));
      std::vector<char> near(corners.size(), 0);
      s.cast(corners, active, T_sensor_objects, true, ws, stats, &near, &deep);
      for (int b = 0; b < ny; ++b) {
        for (int a = 0; a < nx; ++a) {
          const int c = b * (nx + 1) + a;
          if (!(near[c] || near[c + 1] || near[c + nx + 1] || near[c + nx + 2])) continue;
          // The tile's pixels in 4x4 blocks, so that each packet is coherent.
          const PixelRect t = PixelRect{r.x0 + a * s.tile, r.y0 + b * s.tile,
                                        r.x0 + (a + 1) * s.tile, r.y0 + (b + 1) * s.tile}
                                  .clipped(r.x1, r.y1);
          for (int by = t.y0; by < t.y1; by += 4)
            for (int bx = t.x0; bx < t.x1; bx += 4)
              for (int y = by; y < std::min(by + 4, t.y1); ++y)
                for (int x = bx; x < std::min(bx + 4, t.x1); ++x)
                  pixels.push_back(s.gel.index(x, y));
        }
      }
    } else {
      for (int by = cast_rect.y0; by < cast_rect.y1; by += 4)
        for (int bx = cast_rect.x0; bx < cast_rect.x1; bx += 4)
          for (int y = by; y < std::min(by + 4, cast_rect.y1); ++y)
            for (int x = bx; x < std::min(bx + 4, cast_rect.x1); ++x)
              pixels.push_back(s.gel.index(x, y));
    }
    // Per object, rasterize the triangles near the gel or cast the rays, whichever is cheaper.
    // Rays where the coarse pass saw an object deeper than the gel allows: only a ray can tell
    // that it starts inside the object where no surface crosses the slab.
    std::vector<int> ray_objects;
    for (int obj : active) {
      if (opt.rasterize && !deep && !pixels.empty() &&
          s.rasterize_object(obj, T_sensor_objects[obj], cast_rect, long(pixels.size()), ws, stats)) {
        continue;
      }
      ray_objects.push_back(obj);
    }
    if (!ray_objects.empty()) s.cast(pixels, ray_objects, T_sensor_objects, false, ws, stats);
    for (int y = cast_rect.y0; y < cast_rect.y1; ++y) {
      for (int x = cast_rect.x0; x < cast_rect.x1; ++x) {
        float& r = ws.rigid[s.gel.index(x, y)];
        if (r <= 0.0f) continue;
        contact.include(x, y);
        ++stats.contact_pixels;
        if (r > s.slab_m()) {
          r = s.slab_m();
          ++stats.clamped_pixels;
        }
      }
    }
  }
  stats.contact = !contact.empty();

  // 4. Elastic deformation and the region whose surface differs from the undeformed gel.
  PixelRect region;
  if (stats.contact) {
    float deepest = 0.0f;
    for (int y = contact.y0; y < contact.y1; ++y)
      for (int x = contact.x0; x < contact.x1; ++x) deepest = std::max(deepest, ws.rigid[s.gel.index(x, y)]);
    region = contact.dilated(s.kernel.support(deepest) + 1).clipped(w, h);
    elastic_displacement(s.kernel, w, region, ws.rigid.data(), ws.scratch.data(), ws.u.data());
  } else if (!opt.no_contact_cache) {
    region = all;  // measuring the cache: shade the whole undeformed gel again
  }

  // 5. Normals and colour, only on the runs of each row whose surface (or a neighbour's) moved;
  // the rest of the region keeps the undeformed gel's normals and shading.
  const std::vector<std::pair<int, int>> runs = moved_runs(w, ws.u.data(), region, stats.contact);
  for (const auto& r : runs) stats.shaded_pixels += std::max(0, r.second - r.first);
  auto for_each_run = [&](auto&& body) {
    for (int y = region.y0; y < region.y1; ++y) {
      const auto& r = runs[y - region.y0];
      if (r.first < r.second) body(PixelRect{r.first, y, r.second, y + 1});
    }
  };
  // Outside the runs the region holds the undeformed gel's values.
  auto fill_outside_runs = [&](float* dst, const ImageF& src) {
    for (int y = region.y0; y < region.y1; ++y) {
      const auto& r = runs[y - region.y0];
      for (int x = region.x0; x < region.x1; ++x) {
        if (x >= r.first && x < r.second) continue;
        const std::size_t i = 3 * std::size_t(s.gel.index(x, y));
        std::copy_n(&src.data[i], 3, &dst[i]);
      }
    }
  };
  if (opt.normal || opt.color) {
    for_each_run([&](const PixelRect& r) { surface_normals(s.gel, ws.u.data(), r, ws.normals.data()); });
    fill_outside_runs(ws.normals.data(), s.normals0);
  }
  if (opt.color) {
    PixelRect color_region = region;
    if (!region.empty()) {
      for_each_run([&](const PixelRect& r) {
        s.shade_rect(r, region, ws.u.data(), ws.normals.data(), ws.color.data());
      });
      fill_outside_runs(ws.color.data(), s.sim0);
      if (s.blend_radius > 0) {
        // TACTO's blend: real background + blur(sim - sim_bg) * gain, channel by channel.
        color_region = region.dilated(3 * s.blend_radius).clipped(w, h);
        const float gain = float(s.sensor.shading.background_gain);
        for (int c = 0; c < 3; ++c) {
          float* diff = ws.blend_a.data();
          float* blurred = ws.blend_b.data();
          for (int y = color_region.y0; y < color_region.y1; ++y)
            for (int x = color_region.x0; x < color_region.x1; ++x) {
              const int i = s.gel.index(x, y);
              diff[i] = region.contains(x, y) ? ws.color[3 * i + c] - s.sim0.data[3 * i + c] : 0.0f;
            }
          gaussian_blur(diff, blurred, ws.scratch.data(), w, color_region, s.blend_radius);
          for (int y = color_region.y0; y < color_region.y1; ++y)
            for (int x = color_region.x0; x < color_region.x1; ++x) {
              const int i = s.gel.index(x, y);
              ws.color[3 * i + c] = s.background.data[3 * i + c] + gain * blurred[i];
            }
        }
      }
    }
    s.finish_color(color_region, ws.color.data(), noise_seed, out.images.color, ws);
  }

  // 6. Ground truth.
  if (opt.normal) {
    out.images.normal = s.normals0;
    for (int y = region.y0; y < region.y1; ++y)
      std::memcpy(&out.images.normal.at(region.x0, y),
                  &ws.normals[3 * std::size_t(s.gel.index(region.x0, y))],
                  sizeof(float) * 3 * region.width());
  }
  if (opt.depth) {
    out.images.depth = ImageF(w, h, 1, 0.0f);
    for (int y = region.y0; y < region.y1; ++y)
      for (int x = region.x0; x < region.x1; ++x)
        out.images.depth.at(x, y) = ws.u[s.gel.index(x, y)];
  }
  if (opt.mask) {
    out.images.mask = ImageU8(w, h, 1, 0);
    for (int y = contact.y0; y < contact.y1; ++y)
      for (int x = contact.x0; x < contact.x1; ++x)
        if (ws.rigid[s.gel.index(x, y)] > 0.0f) out.images.mask.at(x, y) = 255;
  }
  if (opt.contact_points) {
    out.contact_points_object.resize(s.objects.size());
    std::vector<SE3> T_object_sensor;
    for (const auto& T : T_sensor_objects) T_object_sensor.push_back(T.inverse());
    for (int y = contact.y0; y < contact.y1; ++y)
      for (int x = contact.x0; x < contact.x1; ++x) {
        const int i = s.gel.index(x, y);
        if (ws.rigid[i] <= 0.0f) continue;
        const int obj = ws.hit_object[i];
        const Eigen::Vector3d p_sensor =
            (s.gel.origin_sensor + s.gel.dir_sensor[i] * ws.hit_t[i]).cast<double>();
        out.contact_points_object[obj].push_back((T_object_sensor[obj] * p_sensor).cast<float>());
      }
  }

  // 7. Leave the workspace clean for the next frame.
  const PixelRect dirty = cast_rect.united(region);
  for (int y = dirty.y0; y < dirty.y1; ++y) {
    const std::size_t i0 = std::size_t(s.gel.index(dirty.x0, y)), n = std::size_t(dirty.width());
    std::fill_n(&ws.rigid[i0], n, 0.0f);
    std::fill_n(&ws.u[i0], n, 0.0f);
    std::fill_n(&ws.hit_object[i0], n, std::int16_t(-1));
  }
  return out;
}

}  // namespace pg
