// Steps 5-6 of the pipeline (DESIGN.md, "Renderer pipeline"): normals and shading over the
// pixels that moved, the real background's blend, the colour with its noise, and the
// ground-truth images. Rendering into a frame this renderer filled before rewrites only the
// pixels that differ from the no-contact images, then or now (and the colour's noise).
#include <algorithm>
#include <cmath>

#include "render_state.h"

namespace pg {

namespace {

// body(y, x0, x1) for each non-empty run of `runs`, which holds one run per row of `rect`.
template <typename Body>
void for_each_run(const RowRuns& runs, const PixelRect& rect, Body&& body) {
  for (int y = rect.y0; y < rect.y1; ++y) {
    const auto& r = runs[std::size_t(y - rect.y0)];
    if (r.first < r.second) body(y, r.first, r.second);
  }
}

template <typename T>
void copy_rect(const Image<T>& src, const PixelRect& rect, Image<T>& dst) {
  for (int y = rect.y0; y < rect.y1; ++y) {
    std::copy_n(&src.at(rect.x0, y), std::size_t(rect.width()) * src.channels, &dst.at(rect.x0, y));
  }
}

template <typename T>
void fill_rect(Image<T>& dst, const PixelRect& rect, T value) {
  for (int y = rect.y0; y < rect.y1; ++y) {
    std::fill_n(&dst.at(rect.x0, y), std::size_t(rect.width()) * dst.channels, value);
  }
}

// Clears `image` to `value` where the earlier frame may have left anything else (everywhere
// without reuse), allocating it if it has the wrong shape.
template <typename T>
void reset_image(Image<T>& image, int w, int h, int channels, T value, bool reuse,
                 const PixelRect& old) {
  if (!image.same_shape(w, h, channels)) {
    image = Image<T>(w, h, channels, value);
  } else if (reuse) {
    fill_rect(image, old, value);
  } else {
    std::fill(image.data.begin(), image.data.end(), value);
  }
}

float to_255(float linear) { return std::clamp(linear, 0.0f, 1.0f) * 255.0f; }

}  // namespace

void SensorRenderer::State::shade_row(const PixelRect& rect, const float* u, const float* normals,
                                      float* rgb, Workspace& ws, bool shadows) const {
  const int n = rect.width();
  if (n <= 0) return;
  const int y = rect.y0;
  const std::size_t lights = shader.lights.size();
  ws.soa.resize(std::size_t(n) * 6);
  ShadeSpan span;
  span.count = n;
  float* px = ws.soa.data();
  float *py = px + n, *pz = py + n, *nx = pz + n, *ny = nx + n, *nz = ny + n;
  const float oz = gel.origin_sensor.z();
  for (int k = 0; k < n; ++k) {
    const int i = gel.index(rect.x0 + k, y);
    const float s = gel.t_gel[i] - u[i];  // camera depth of the displaced surface
    px[k] = gel.dir_x[i] * s;
    py[k] = gel.dir_y[i] * s;
    pz[k] = oz + s;
    nx[k] = normals[3 * i];
    ny[k] = normals[3 * i + 1];
    nz[k] = normals[3 * i + 2];
  }
  span.px = px, span.py = py, span.pz = pz, span.nx = nx, span.ny = ny, span.nz = nz;
  if (shadows) {
    ws.visibility.resize(lights * (n + 1));
    float* one = ws.visibility.data() + lights * n;
    for (int k = 0; k < n; ++k) {
      ws.shadows.visibility(rect.x0 + k, y, {px[k], py[k], pz[k]}, {nx[k], ny[k], nz[k]}, one);
      for (std::size_t l = 0; l < lights; ++l) ws.visibility[l * n + k] = one[l];
    }
    span.visibility = ws.visibility.data();
  }
  shade_span(shader, span, rgb + 3 * std::size_t(gel.index(rect.x0, y)));
}

void SensorRenderer::State::write_outputs(const std::vector<SE3>& T_sensor_objects,
                                          std::uint64_t seed, FrameRegions& frame, Workspace& ws,
                                          RenderedFrame& out) const {
  const RenderSettings& opt = settings;
  const int w = width(), h = height();
  const FrameImages& im = out.images;
  const bool reuse = out.filled.by == id && (!opt.color || im.color.same_shape(w, h, 3)) &&
                     (!opt.normal || im.normal.same_shape(w, h, 3)) &&
                     (!opt.depth || im.depth.same_shape(w, h, 1)) &&
                     (!opt.mask || im.mask.same_shape(w, h, 1));
  if (opt.normal || opt.color) {
    for_each_run(ws.runs, frame.region, [&](int y, int x0, int x1) {
      surface_normals(gel, ws.u.data(), {x0, y, x1, y + 1}, ws.normals.data());
    });
  }
  if (opt.color) write_color(seed, frame, reuse, ws, out);
  write_ground_truth(T_sensor_objects, frame, reuse, ws, out);
  const PixelRect changed = frame.color.united(frame.shaded).united(frame.contact);
  out.filled = {id, changed.x0, changed.y0, changed.x1, changed.y1};
}

// The undeformed pixels beside the dent (outside the runs) that it shadows from a light: each
// light's reach is marched for that light only, and the pixels it blocks are shaded again into
// ws.color. ws.color_runs become the runs of frame.shaded, which grows over them, with the
// undeformed gel's shading copied into ws.color where a run grew over pixels in between.
// Returns the number of pixels shaded.
int SensorRenderer::State::shade_cast_shadows(FrameRegions& frame, Workspace& ws) const {
  const ShadowCaster& caster = ws.shadows;
  const std::size_t lights = caster.lights();
  const PixelRect& region = frame.region;
  auto moved_run = [&](int y) {
    return region.contains(region.x0, y) ? ws.runs[std::size_t(y - region.y0)]
                                         : std::pair<int, int>{0, 0};
  };
  const PixelRect& reach = caster.reach();
  ws.shadowed.clear();
  ws.visibility.clear();
  std::vector<float>& vis = ws.shadowed_rgb;  // per pixel and light, until shaded
  vis.clear();
  thread_local std::vector<float> one_buffer;
  one_buffer.resize(lights);
  float* one = one_buffer.data();
  const float oz = gel.origin_sensor.z();
  PixelRect shadowed;
  for (int y = reach.y0; y < reach.y1; ++y) {
    const auto run = moved_run(y);
    for (int x = reach.x0; x < reach.x1; ++x) {
      if (x >= run.first && x < run.second) {
        x = run.second - 1;  // shaded already, with its shadows
        continue;
      }
      const unsigned mask = caster.reaching(x, y);
      if (mask == 0) continue;
      const int i = gel.index(x, y);
      const float t = gel.t_gel[i];
      const Eigen::Vector3f p(gel.dir_x[i] * t, gel.dir_y[i] * t, oz + t);
      const Eigen::Vector3f n(normals0.data[3 * i], normals0.data[3 * i + 1],
                              normals0.data[3 * i + 2]);
      caster.visibility(x, y, p, n, one, mask);
      if (std::all_of(one, one + lights, [](float v) { return v >= 1.0f; })) continue;
      ws.shadowed.push_back(i);
      vis.insert(vis.end(), one, one + lights);
      shadowed.include(x, y);
    }
  }
  frame.shaded = region.united(shadowed);
  const PixelRect& rect = frame.shaded;
  // The colour's runs: the moved runs, grown over the shadowed pixels.
  ws.color_runs.assign(std::size_t(rect.height()), {rect.x1, rect.x0});
  for (int y = rect.y0; y < rect.y1; ++y) {
    const auto run = moved_run(y);
    if (run.first < run.second) ws.color_runs[std::size_t(y - rect.y0)] = run;
  }
  const int count = int(ws.shadowed.size());
  for (int i : ws.shadowed) {
    auto& run = ws.color_runs[std::size_t(i / width() - rect.y0)];
    run = {std::min(run.first, i % width()), std::max(run.second, i % width() + 1)};
  }
  if (count == 0) return 0;
  float* rgb = ws.color.data();
  for (int y = rect.y0; y < rect.y1; ++y) {
    const auto run = ws.color_runs[std::size_t(y - rect.y0)], moved = moved_run(y);
    auto copy = [&](int x0, int x1) {
      if (x0 < x1) std::copy_n(&sim0.at(x0, y), 3 * (x1 - x0), rgb + 3 * gel.index(x0, y));
    };
    if (moved.first < moved.second) {
      copy(run.first, moved.first);
      copy(moved.second, run.second);
    } else {
      copy(run.first, run.second);
    }
  }
  // Shade the shadowed pixels together, then put them in place.
  ws.soa.resize(std::size_t(count) * 6);
  float* px = ws.soa.data();
  float *py = px + count, *pz = py + count, *nx = pz + count, *ny = nx + count, *nz = ny + count;
  ws.visibility.resize(lights * std::size_t(count));
  for (int k = 0; k < count; ++k) {
    const int i = ws.shadowed[std::size_t(k)];
    const float t = gel.t_gel[i];
    px[k] = gel.dir_x[i] * t;
    py[k] = gel.dir_y[i] * t;
    pz[k] = oz + t;
    nx[k] = normals0.data[3 * i];
    ny[k] = normals0.data[3 * i + 1];
    nz[k] = normals0.data[3 * i + 2];
    for (std::size_t l = 0; l < lights; ++l)
      ws.visibility[l * count + k] = vis[std::size_t(k) * lights + l];
  }
  ShadeSpan span;
  span.count = count;
  span.px = px, span.py = py, span.pz = pz, span.nx = nx, span.ny = ny, span.nz = nz;
  span.visibility = ws.visibility.data();
  vis.resize(3 * std::size_t(count));
  shade_span(shader, span, vis.data());
  for (int k = 0; k < count; ++k) {
    std::copy_n(&vis[3 * std::size_t(k)], 3, rgb + 3 * std::size_t(ws.shadowed[std::size_t(k)]));
  }
  return count;
}

void SensorRenderer::State::write_color(std::uint64_t seed, FrameRegions& frame, bool reuse,
                                        Workspace& ws, RenderedFrame& out) const {
  const int w = width(), h = height();
  const float* u = ws.u.data();
  float* rgb = ws.color.data();
  // Shade the moved pixels; the rest of the region keeps the undeformed gel's shading.
  const bool shadows = settings.shadows && !frame.region.empty();
  if (shadows) ws.shadows.set_surface(u, frame.region);
  for_each_run(ws.runs, frame.region, [&](int y, int x0, int x1) {
    shade_row({x0, y, x1, y + 1}, u, ws.normals.data(), rgb, ws, settings.shadows);
  });
  // And the undeformed gel the dent shadows.
  const RowRuns* shaded_runs = &ws.runs;
  if (shadows) {
    out.stats.shaded_pixels += shade_cast_shadows(frame, ws);
    shaded_runs = &ws.color_runs;
    frame.color = frame.shaded;
    if (background_blend()) frame.color = frame.shaded.dilated(blend_blur.radius()).clipped(w, h);
  }
  // Where `rgb` holds this frame's colour: the runs, or with a real background (blended with a
  // blur) all of frame.color. Everywhere else the frame shows the background.
  const RowRuns* runs = shaded_runs;
  PixelRect runs_rect = frame.shaded;
  thread_local RowRuns full_rows;
  if (background_blend() && !frame.shaded.empty()) {
    // TACTO's blend: real background + blur(sim - sim_bg) * gain, channel by channel.
    const PixelRect& cr = frame.color;
    const float gain = float(sensor.shading.background_gain);
    float* diff = ws.scratch_a.data();
    float* blurred = ws.scratch_b.data();
    for (int c = 0; c < 3; ++c) {
      for (int y = cr.y0; y < cr.y1; ++y) std::fill_n(diff + gel.index(cr.x0, y), cr.width(), 0.0f);
      for_each_run(*shaded_runs, frame.shaded, [&](int y, int x0, int x1) {
        for (int i = gel.index(x0, y); i < gel.index(x1, y); ++i)
          diff[i] = rgb[3 * i + c] - sim0.data[3 * i + c];
      });
      const float* smoothed = diff;
      if (!blend_blur.weights.empty()) {
        gaussian_blur(diff, blurred, diff, w, cr, blend_blur);
        smoothed = blurred;
      }
      for (int y = cr.y0; y < cr.y1; ++y)
        for (int i = gel.index(cr.x0, y); i < gel.index(cr.x1, y); ++i)
          rgb[3 * i + c] = background.data[3 * i + c] + gain * smoothed[i];
    }
    full_rows.assign(std::size_t(cr.height()), {cr.x0, cr.x1});
    runs = &full_rows;
    runs_rect = cr;
  }
  auto run_of = [&](int y) {
    return runs_rect.contains(runs_rect.x0, y) ? (*runs)[std::size_t(y - runs_rect.y0)]
                                               : std::pair<int, int>{0, 0};
  };

  ImageU8& img = out.images.color;
  if (!img.same_shape(w, h, 3)) img = ImageU8(w, h, 3);
  const std::size_t stride = 3 * std::size_t(w);
  if (!noise) {
    if (reuse) {
      copy_rect(background_u8, {out.filled.x0, out.filled.y0, out.filled.x1, out.filled.y1}, img);
    } else {
      img.data = background_u8.data;
    }
    for (int y = runs_rect.y0; y < runs_rect.y1; ++y) {
      const auto r = run_of(y);
      for (std::size_t i = y * stride + 3 * r.first; i < y * stride + 3 * r.second; ++i)
        img.data[i] = std::uint8_t(to_255(rgb[i]) + 0.5f);
    }
    return;
  }
  // Noise on every pixel: rows without colour of their own in one piece from the background,
  // the others in three (background, own colour, background).
  for (int y = 0; y < h;) {
    int y_end = y;
    while (y_end < h && run_of(y_end).first >= run_of(y_end).second) ++y_end;
    if (y_end > y) {
      const std::size_t i = y * stride;
      noise->apply(&background_fixed[i], &img.data[i], (y_end - y) * stride, seed, i);
      y = y_end;
      continue;
    }
    const auto r = run_of(y);
    const std::size_t i0 = y * stride, i1 = i0 + 3 * r.first, i2 = i0 + 3 * r.second;
    for (std::size_t i = i1; i < i2; ++i) ws.row[i - i1] = noise->to_fixed(to_255(rgb[i]));
    noise->apply(&background_fixed[i0], &img.data[i0], i1 - i0, seed, i0);
    noise->apply(ws.row.data(), &img.data[i1], i2 - i1, seed, i1);
    noise->apply(&background_fixed[i2], &img.data[i2], i0 + stride - i2, seed, i2);
    ++y;
  }
}

void SensorRenderer::State::write_ground_truth(const std::vector<SE3>& T_sensor_objects,
                                               const FrameRegions& frame, bool reuse,
                                               const Workspace& ws, RenderedFrame& out) const {
  const RenderSettings& opt = settings;
  const int w = width(), h = height();
  const PixelRect old{out.filled.x0, out.filled.y0, out.filled.x1, out.filled.y1};
  if (opt.normal) {
    ImageF& n = out.images.normal;
    if (reuse) {
      copy_rect(normals0, old, n);
    } else {
      n = normals0;
    }
    for_each_run(ws.runs, frame.region, [&](int y, int x0, int x1) {
      std::copy_n(&ws.normals[3 * std::size_t(gel.index(x0, y))], 3 * (x1 - x0), &n.at(x0, y));
    });
  }
  if (opt.depth) {
    ImageF& d = out.images.depth;
    reset_image(d, w, h, 1, 0.0f, reuse, old);
    const PixelRect& r = frame.deformed;
    for (int y = r.y0; y < r.y1; ++y)
      std::copy_n(&ws.u[std::size_t(gel.index(r.x0, y))], r.width(), &d.at(r.x0, y));
  }
  if (opt.mask) {
    ImageU8& m = out.images.mask;
    reset_image(m, w, h, 1, std::uint8_t(0), reuse, old);
    const PixelRect& r = frame.contact;
    for (int y = r.y0; y < r.y1; ++y)
      for (int x = r.x0; x < r.x1; ++x)
        if (ws.rigid[gel.index(x, y)] > 0.0f) m.at(x, y) = 255;
  }
  if (opt.contact_points) {
    out.contact_points_object.resize(objects.size());
    for (auto& points : out.contact_points_object) points.clear();
    std::vector<SE3> T_object_sensor;
    for (const auto& T : T_sensor_objects) T_object_sensor.push_back(T.inverse());
    const PixelRect& r = frame.contact;
    for (int y = r.y0; y < r.y1; ++y)
      for (int x = r.x0; x < r.x1; ++x) {
        const int i = gel.index(x, y);
        // Where the object reaches past the gel's maximum indentation (a clamped pixel) the gel
        // does not touch its surface; a ray that started inside it (hit_t NaN) met none.
        if (ws.rigid[i] <= 0.0f || !(gel.t_gel[i] - ws.hit_t[i] <= slab_m())) continue;
        const int obj = ws.hit_object[i];
        const Eigen::Vector3d p_sensor =
            (gel.origin_sensor + gel.dir_sensor[i] * ws.hit_t[i]).cast<double>();
        out.contact_points_object[obj].push_back((T_object_sensor[obj] * p_sensor).cast<float>());
      }
  }
}

}  // namespace pg
