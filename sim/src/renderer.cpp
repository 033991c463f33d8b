// Per-frame pipeline (DESIGN.md, "Renderer pipeline"): cull -> footprint -> rays -> indentation ->
// elastic deformation -> normals -> shading -> background blend -> noise; each step only over the
// pixels it can change, and only for the outputs asked for. This file sets a renderer up and
// runs the steps in order; contact_pass.cpp and frame_outputs.cpp hold the steps.
#include "pg/sim/renderer.h"

#include <atomic>
#include <cmath>
#include <limits>

#include "pg/core/error.h"
#include "pg/core/sensor.h"
#include "render_state.h"

namespace pg {

namespace {

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
// the undeformed gel's: those whose displacement, or a 3x3 neighbour's, is non-zero (u is zero
// outside `deformed`).
void moved_runs(int width, const float* u, const PixelRect& deformed, const PixelRect& region,
                RowRuns& runs) {
  const int rows = region.height();
  runs.assign(std::size_t(rows), {region.x1, region.x0});
  thread_local RowRuns moved;
  moved.assign(std::size_t(rows), {region.x1, region.x0});
  for (int y = deformed.y0; y < deformed.y1; ++y) {
    const float* row = u + std::size_t(y) * width;
    int a = deformed.x0, b = deformed.x1;
    while (a < b && !(row[a] > 0.0f)) ++a;
    while (b > a && !(row[b - 1] > 0.0f)) --b;
    if (a < b) moved[y - region.y0] = {a, b};
  }
  for (int r = 0; r < rows; ++r) {
    int x0 = region.x1, x1 = region.x0;
    for (int d = -1; d <= 1; ++d) {
      if (r + d < 0 || r + d >= rows || moved[r + d].first >= moved[r + d].second) continue;
      x0 = std::min(x0, moved[r + d].first - 1);
      x1 = std::max(x1, moved[r + d].second + 1);
    }
    runs[r] = {std::max(x0, region.x0), std::min(x1, region.x1)};
  }
}

// A number per renderer, so that a frame knows which one filled it.
std::uint64_t next_renderer_id() {
  static std::atomic<std::uint64_t> next{1};
  return next++;
}

}  // namespace

// Step 4: the elastic deformation, and where the frame differs from the no-contact frame.
void SensorRenderer::State::deform(Workspace& ws, RenderStats& stats, FrameRegions& frame) const {
  const State& s = *this;
  const int w = s.width(), h = s.height();
  stats.contact = !frame.contact.empty();
  ws.runs.clear();
  if (stats.contact) {
    frame.deformed =
        elastic_displacement(s.kernel, w, h, frame.contact, frame.deepest, ws.rigid.data(),
                             ws.scratch_a.data(), ws.scratch_b.data(), ws.u.data());
    frame.region = frame.deformed.dilated(1).clipped(w, h);
    moved_runs(w, ws.u.data(), frame.deformed, frame.region, ws.runs);
  } else if (!s.settings.no_contact_cache) {
    frame.region = PixelRect{0, 0, w, h};  // measuring the cache: shade the undeformed gel again
    ws.runs.assign(std::size_t(h), {0, w});
  }
  frame.shaded = frame.region;
  frame.color = frame.region;
  if (s.background_blend() && !frame.region.empty()) {
    frame.color = frame.region.dilated(s.blend_blur.radius()).clipped(w, h);
  }
  for (const auto& r : ws.runs) stats.shaded_pixels += std::max(0, r.second - r.first);
}

Workspace::Workspace(int w, int h, int objects, const ShadowCaster& caster)
    : rigid(std::size_t(w) * h, 0.0f),
      hit_t(std::size_t(w) * h, 0.0f),
      u(std::size_t(w) * h, 0.0f),
      scratch_a(std::size_t(w) * h, 0.0f),
      scratch_b(std::size_t(w) * h, 0.0f),
      normals(std::size_t(w) * h * 3, 0.0f),
      color(std::size_t(w) * h * 3, 0.0f),
      hit_object(std::size_t(w) * h, -1),
      raster_t(std::size_t(w) * h, INFINITY),
      row(std::size_t(w) * 3, 0),
      blocks(std::size_t((w + 3) / 4) * std::size_t((h + 3) / 4), 0),
      slab(std::size_t(objects)),
      shadows(caster) {}

SensorRenderer::State::State(SensorModel s, std::vector<std::shared_ptr<const ObjectShape>> objs,
                             RenderSettings rs)
    : sensor(std::move(s)),
      settings(std::move(rs)),
      objects(std::move(objs)),
      id(next_renderer_id()),
      workspaces([this] {
        return Workspace(width(), height(), int(objects.size()),
                         ShadowCaster(shader, gel, sensor.camera));
      }) {}

void SensorRenderer::State::prepare() {
  gel = make_gel_geometry(sensor);
  const int w = width(), h = height();
  kernel = make_elastic_kernel(sensor.gel.elastic, float(gel.px_per_m), std::max(w, h) + 2);
  shader = make_shader(sensor);
  if (settings.noise && sensor.noise.sigma > 0) noise.emplace(float(sensor.noise.sigma));
  const PixelRect all{0, 0, w, h};
  std::vector<float> zero(std::size_t(w) * h, 0.0f);
  normals0 = ImageF(w, h, 3);
  surface_normals(gel, zero.data(), all, normals0.data.data());
  // The undeformed gel casts no shadow on itself: it is convex, and the lights sit inside it.
  sim0 = ImageF(w, h, 3);
  Workspace ws(w, h, int(objects.size()), ShadowCaster(shader, gel, sensor.camera));
  for (int y = 0; y < h; ++y) {
    shade_row({0, y, w, y + 1}, zero.data(), normals0.data.data(), sim0.data.data(), ws, false);
  }
  background = sim0;
  if (!settings.background.empty()) {
    const ImageF real = read_image_float(settings.background);
    if (real.channels < 3) {
      throw InputError(settings.background + ": " + std::to_string(real.channels) +
                       (real.channels == 1 ? " channel (grey)" : " channels") +
                       "; a background image must be RGB, as the sensor's camera sees it");
    }
    // It is scaled to the sensor's image, not cropped: another shape would stretch it.
    const double aspect = double(real.width) / real.height, wanted = double(w) / h;
    if (std::abs(aspect / wanted - 1.0) > 0.02) {
      const bool turned = std::abs(1.0 / aspect / wanted - 1.0) <= 0.02;
      throw InputError(settings.background + ": background image is " + std::to_string(real.width) +
                       "x" + std::to_string(real.height) + ", not of the sensor's shape (" +
                       std::to_string(w) + "x" + std::to_string(h) +
                       ", or any size of that shape; a background is scaled to the sensor's "
                       "image, never cropped)" +
                       (turned ? ": it is turned by 90 degrees; turn it first" : ""));
    }
    ImageF rgb(real.width, real.height, 3);
    for (int y = 0; y < real.height; ++y)
      for (int x = 0; x < real.width; ++x)
        for (int c = 0; c < 3; ++c) rgb.at(x, y, c) = real.at(x, y, c);
    // A float image (EXR) can hold values that are no number; clamped, they read black.
    if (const auto bad = first_non_finite(rgb)) {
      throw InputError(settings.background + ": pixel (" + std::to_string((*bad)[0]) + ", " +
                       std::to_string((*bad)[1]) + ") channel " + std::to_string((*bad)[2]) +
                       " is not a finite number");
    }
    background = resample_bilinear(rgb, w, h);
    blend_blur = gaussian_kernel(gel.blend_blur_px(sensor.shading));
  }
  background_u8 = ImageU8(w, h, 3);
  if (noise) background_fixed.resize(background.data.size());
  for (std::size_t i = 0; i < background.data.size(); ++i) {
    const float v = std::clamp(background.data[i], 0.0f, 1.0f) * 255.0f;
    background_u8.data[i] = std::uint8_t(v + 0.5f);
    if (noise) background_fixed[i] = noise->to_fixed(v);
  }
}

namespace {

// The renderer's inputs set in C++, checked as a sensor file and a scene's objects are: a camera
// left at fx = 0 had crashed the gel's set-up, a null object the first frame, and an object
// numbered past the per-pixel record's 16 bits had corrupted the heap.
SensorModel checked(SensorModel sensor,
                    const std::vector<std::shared_ptr<const ObjectShape>>& objects) {
  check_sensor_model(sensor, "SensorRenderer: sensor " + sensor.name);
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (!objects[i]) throw InputError("SensorRenderer: object " + std::to_string(i) + " is null");
  }
  // The workspace's per-pixel object numbers (Workspace::hit_object).
  constexpr std::size_t kMaxObjects =
      std::numeric_limits<decltype(Workspace::hit_object)::value_type>::max();
  if (objects.size() > kMaxObjects) {
    throw InputError("SensorRenderer: " + std::to_string(objects.size()) + " objects; at most " +
                     std::to_string(kMaxObjects) + " are rendered together");
  }
  return sensor;
}

}  // namespace

SensorRenderer::SensorRenderer(SensorModel sensor,
                               std::vector<std::shared_ptr<const ObjectShape>> objects,
                               RenderSettings settings)
    : state_(std::make_unique<State>(checked(std::move(sensor), objects), std::move(objects),
                                     std::move(settings))) {
  state_->prepare();
}

SensorRenderer::~SensorRenderer() = default;

const SensorModel& SensorRenderer::sensor() const { return state_->sensor; }
const RenderSettings& SensorRenderer::settings() const { return state_->settings; }
const ImageF& SensorRenderer::background_color() const { return state_->background; }
const ImageU8& SensorRenderer::background_color_u8() const { return state_->background_u8; }
const ImageF& SensorRenderer::undeformed_normals() const { return state_->normals0; }

RenderedFrame SensorRenderer::render(const std::vector<SE3>& T_sensor_objects,
                                     std::uint64_t noise_seed) const {
  RenderedFrame out;
  render(T_sensor_objects, noise_seed, out);
  return out;
}

void SensorRenderer::render(const std::vector<SE3>& T_sensor_objects, std::uint64_t noise_seed,
                            RenderedFrame& out) const {
  const State& s = *state_;
  if (T_sensor_objects.size() != s.objects.size()) {
    throw std::invalid_argument("SensorRenderer::render: one pose per object expected");
  }
  // A NaN pose had rendered as no contact, the object gone without a word; a zero quaternion (an
  // unset pose) as the identity.
  for (std::size_t i = 0; i < T_sensor_objects.size(); ++i) {
    if (!is_finite(T_sensor_objects[i])) {
      throw InputError("SensorRenderer::render: object " + std::to_string(i) +
                       "'s pose is not finite (or its quaternion not of unit length)");
    }
  }
  Workspace& ws = s.workspaces.local();
  out.stats = RenderStats{};
  FrameRegions frame;
  s.find_contact(T_sensor_objects, ws, out.stats, frame);         // 1-3
  s.deform(ws, out.stats, frame);                                 // 4
  s.write_outputs(T_sensor_objects, noise_seed, frame, ws, out);  // 5-6

  // 7. Leave the workspace clean for the next frame.
  const int w = s.width();
  for (int y = frame.touched.y0; y < frame.touched.y1; ++y) {
    const std::size_t i0 = std::size_t(y) * w + frame.touched.x0;
    std::fill_n(&ws.rigid[i0], frame.touched.width(), 0.0f);
    std::fill_n(&ws.hit_object[i0], frame.touched.width(), std::int16_t(-1));
  }
  for (int y = frame.deformed.y0; y < frame.deformed.y1; ++y) {
    std::fill_n(&ws.u[std::size_t(y) * w + frame.deformed.x0], frame.deformed.width(), 0.0f);
  }
}

}  // namespace pg
