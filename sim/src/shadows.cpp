#include "shadows.h"

#include <algorithm>
#include <cmath>

namespace pg {

ShadowCaster::ShadowCaster(const Shader& shader, const GelGeometry& g, const CameraModel& camera)
    : gel_(&g), camera_(camera) {
  for (const ShadingLight& l : shader.lights) {
    Light light;
    light.position = l.position;
    const float depth = l.position.z() - g.origin_sensor.z();
    light.in_front = depth > 1e-6f;
    if (light.in_front) {
      light.x = float(camera.fx) * l.position.x() / depth + float(camera.cx);
      light.y = float(camera.fy) * l.position.y() / depth + float(camera.cy);
      light.inv_depth = 1.0f / depth;
      for (float cx : {-0.5f, float(g.width) - 0.5f}) {
        for (float cy : {-0.5f, float(g.height) - 0.5f}) {
          light.farthest_px = std::max(light.farthest_px, std::hypot(cx - light.x, cy - light.y));
        }
      }
    }
    lights_.push_back(light);
  }
  for (float t : g.t_gel) far_depth_ = std::max(far_depth_, t);
}

// Per tile x tile tile of rect_, the smallest depth_ within its 3 x 3 neighbourhood of tiles:
// a stretch of `tile` steps that starts in a tile, and the pixels the surface is interpolated
// from, stay within it.
ShadowCaster::Tiles ShadowCaster::tile_minima(int tile) const {
  const int w = rect_.width(), h = rect_.height();
  Tiles t;
  t.size = tile;
  t.nx = (w + tile - 1) / tile;
  const int ny = (h + tile - 1) / tile;
  std::vector<float>& own = t.own;
  own.assign(std::size_t(t.nx) * ny, INFINITY);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      float& m = own[std::size_t(y / tile) * t.nx + x / tile];
      m = std::min(m, depth_[std::size_t(y) * w + x]);
    }
  }
  t.depth.assign(own.size(), INFINITY);
  for (int ty = 0; ty < ny; ++ty)
    for (int tx = 0; tx < t.nx; ++tx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = tx + dx, ny2 = ty + dy;
          if (nx < 0 || ny2 < 0 || nx >= t.nx || ny2 >= ny) continue;
          float& m = t.depth[std::size_t(ty) * t.nx + tx];
          m = std::min(m, own[std::size_t(ny2) * t.nx + nx]);
        }
  return t;
}

// Where the dent can shadow the undeformed gel from `light`, one tile of the dent at a time.
// The path from an undeformed point at camera depth d to the light runs straight in the image,
// over image length len, its inverse depth growing linearly from 1/d to the light's 1/d_L; it
// can only be blocked over a tile while it is farther from the camera than the tile's
// shallowest point D, so within
//   len * (1/D - 1/d) / (1/d_L - 1/d)
// of its start, which grows with d and len: at most with len = Light::farthest_px (to the
// farthest image corner) at the gel's largest depth. The point lies that far at most beyond a
// pixel q of the tile, away from the light's image position l, along (q - l) / |q - l|: the
// tile's rectangle grows on each side by that length times the largest component of this
// direction toward the side, plus a pixel for the interpolation between pixels. Empty when no
// undeformed point can be farther than D.
PixelRect ShadowCaster::tile_reach(const Light& light, const PixelRect& tile,
                                   float shallowest) const {
  const float inv_near = 1.0f / shallowest, inv_far = 1.0f / far_depth_;
  if (!(inv_near > inv_far)) return {};
  const float reach = light.farthest_px * (inv_near - inv_far) / (light.inv_depth - inv_far);
  // How far the rectangle grows toward +a (or -a): the reach times the largest component that
  // way of (q - l) / |q - l| over q in the tile, found at its last (first) pixel along a,
  // `edge` = that pixel minus l, and at the least distance `gap` from l to its pixels across a
  // (the component grows with |edge| and falls with the gap).
  auto grow = [&](float edge, float gap, bool toward_plus) {
    if (toward_plus ? !(edge > 0.0f) : !(edge < 0.0f)) return 0;
    return int(std::ceil(reach * std::abs(edge) / std::hypot(edge, gap))) + 1;
  };
  auto gap = [](float l, int lo, int hi) {  // distance from l to [lo, hi - 1]
    return std::max({0.0f, float(lo) - l, l - float(hi - 1)});
  };
  const float gap_y = gap(light.y, tile.y0, tile.y1), gap_x = gap(light.x, tile.x0, tile.x1);
  const PixelRect r{tile.x0 - grow(float(tile.x0) - light.x, gap_y, false),
                    tile.y0 - grow(float(tile.y0) - light.y, gap_x, false),
                    tile.x1 + grow(float(tile.x1 - 1) - light.x, gap_y, true),
                    tile.y1 + grow(float(tile.y1 - 1) - light.y, gap_x, true)};
  return r.clipped(gel_->width, gel_->height);
}

// Per light and dented tile, the pixels the tile can shadow (tile_reach); reach_rect_ is their
// union, and reach_mask_ flags each of its pixels with the lights that reach it.
void ShadowCaster::find_reach() {
  reach_rect_ = {};
  thread_local std::vector<std::pair<PixelRect, std::uint8_t>> marks;
  marks.clear();
  const int ny = tiles_.nx > 0 ? int(tiles_.own.size()) / tiles_.nx : 0;
  for (std::size_t k = 0; k < lights_.size(); ++k) {
    const Light& light = lights_[k];
    // Lights the march in the image handles, nearer to the camera than the dent.
    if (!light.in_front || !(light.inv_depth > inv_depth_max_)) continue;
    const std::uint8_t bit = std::uint8_t(1u << std::min<std::size_t>(k, 7));
    for (int ty = 0; ty < ny; ++ty) {
      for (int tx = 0; tx < tiles_.nx; ++tx) {
        const float shallowest = tiles_.own[std::size_t(ty) * tiles_.nx + tx];
        if (!std::isfinite(shallowest)) continue;
        const PixelRect tile = PixelRect{rect_.x0 + tx * kTile, rect_.y0 + ty * kTile,
                                         rect_.x0 + (tx + 1) * kTile, rect_.y0 + (ty + 1) * kTile}
                                   .intersected(rect_);
        const PixelRect r = tile_reach(light, tile, shallowest);
        if (r.empty()) continue;
        reach_rect_ = reach_rect_.united(r);
        marks.push_back({r, bit});
      }
    }
  }
  const int w = reach_rect_.width();
  reach_mask_.assign(std::size_t(reach_rect_.area()), 0);
  for (const auto& [r, bit] : marks) {
    for (int y = r.y0; y < r.y1; ++y) {
      std::uint8_t* row = &reach_mask_[std::size_t(y - reach_rect_.y0) * w];
      for (int x = r.x0; x < r.x1; ++x) row[x - reach_rect_.x0] |= bit;
    }
  }
}

unsigned ShadowCaster::reaching(int x, int y) const {
  if (!reach_rect_.contains(x, y)) return 0;
  const unsigned m = reach_mask_[std::size_t(y - reach_rect_.y0) * reach_rect_.width() +
                                 std::size_t(x - reach_rect_.x0)];
  return m & 0x80u ? m | ~0x7fu : m;  // bit 7 stands for the 8th light and those after it
}

void ShadowCaster::set_surface(const float* u, const PixelRect& dent) {
  rect_ = dent;
  const int w = dent.width();
  depth_.resize(std::size_t(dent.area()));
  float shallowest = INFINITY;
  const GelGeometry& g = *gel_;
  for (int y = dent.y0; y < dent.y1; ++y) {
    float* out = &depth_[std::size_t(y - dent.y0) * w];
    for (int x = dent.x0; x < dent.x1; ++x) {
      const int i = g.index(x, y);
      out[x - dent.x0] = u[i] > 0.0f ? g.t_gel[i] - u[i] + 1e-6f : INFINITY;
      shallowest = std::min(shallowest, out[x - dent.x0]);
    }
  }
  inv_depth_max_ = 1.0f / shallowest;
  tiles_ = tile_minima(kTile);
  find_reach();
}

// The path from pixel (x, y)'s surface point (camera depth `depth`) to a light nearer to the
// camera. In the image it runs straight from (x, y) toward the light's image position, and its
// inverse camera depth changes linearly along it (perspective-correct interpolation). It is
// sampled where it crosses each pixel column (or row, whichever it crosses more of): step k is
// k pixels along that major axis, the surface depth interpolated between the two pixels of the
// minor axis that the path passes between.
bool ShadowCaster::blocked_in_image(const Light& light, int x, int y, float depth) const {
  const float dx = light.x - float(x), dy = light.y - float(y);
  const bool along_x = std::abs(dx) >= std::abs(dy);
  const float length = along_x ? std::abs(dx) : std::abs(dy);  // [px] along the major axis
  if (!(length >= 1.0f)) return false;
  const float inv0 = 1.0f / depth, inv_step = (light.inv_depth - inv0) / length;
  // Major axis a (integer steps), minor axis m; their ranges in rect_ and strides in depth_.
  const int w = rect_.width();
  const int a0 = along_x ? x : y, a_lo = along_x ? rect_.x0 : rect_.y0;
  const int a_hi = along_x ? rect_.x1 : rect_.y1;
  const int m_lo = along_x ? rect_.y0 : rect_.x0, m_hi = along_x ? rect_.y1 : rect_.x1;
  const int stride_a = along_x ? 1 : w, stride_m = along_x ? w : 1;
  const int step = (along_x ? dx : dy) > 0.0f ? 1 : -1;
  const float m0 = float(along_x ? y : x), m_step = (along_x ? dy : dx) / length;
  // The steps inside the rectangle, where the surface can be dented (pixel (x, y) itself may lie
  // outside it): the path is a straight line in the image, so it enters and leaves once. Along
  // the minor axis the rectangle spans (m_lo - 0.5, m_hi - 0.5).
  int first = std::max(1, step > 0 ? a_lo - a0 : a0 - (a_hi - 1));
  int last = std::min(int(length), step > 0 ? a_hi - 1 - a0 : a0 - a_lo);
  const float m_in = float(m_lo) - 0.5f, m_out = float(m_hi) - 0.5f;
  if (m_step != 0.0f) {
    // (Clamped before they become integers: a nearly axis-aligned path divides by almost 0.)
    const float k_lo = std::clamp(((m_step > 0.0f ? m_in : m_out) - m0) / m_step, -1e6f, 1e6f);
    const float k_hi = std::clamp(((m_step > 0.0f ? m_out : m_in) - m0) / m_step, -1e6f, 1e6f);
    first = std::max(first, int(std::floor(k_lo)) + 1);
    last = std::min(last, int(std::ceil(k_hi)) - 1);
  } else if (!(m0 > m_in && m0 < m_out)) {
    return false;
  }
  const int tiles_x = tiles_.nx, tiles_y = int(tiles_.depth.size()) / tiles_.nx;
  for (int k = first; k <= last; ++k) {
    const float inv = inv0 + float(k) * inv_step;
    if (inv >= inv_depth_max_) return false;  // nearer than any surface point: it stays inside
    const int a = a0 + k * step;
    const float m = m0 + float(k) * m_step;
    // The next kTile steps are nearer to the camera than this one: skip them if this one is
    // already nearer than every surface point within their reach.
    if ((k - first) % kTile == 0) {
      const int ta = (a - a_lo) / kTile;
      const int tm =
          std::clamp((int(m + 0.5f) - m_lo) / kTile, 0, (along_x ? tiles_y : tiles_x) - 1);
      const int i = along_x ? tm * tiles_.nx + ta : ta * tiles_.nx + tm;
      if (inv * tiles_.depth[std::size_t(i)] >= 1.0f) {
        k += kTile - 1;
        continue;
      }
    }
    const float m_floor = std::floor(m);
    const float f = m - m_floor;
    const int i_a = (a - a_lo) * stride_a;
    const int mi0 = std::max(int(m_floor), m_lo) - m_lo,
              mi1 = std::min(int(m_floor) + 1, m_hi - 1) - m_lo;
    const float d0 = depth_[std::size_t(i_a + mi0 * stride_m)];
    const float d1 = depth_[std::size_t(i_a + mi1 * stride_m)];
    // Next to the undented gel (+inf) the dented neighbour alone.
    const float surface = std::isinf(d0) ? d1 : std::isinf(d1) ? d0 : (1.0f - f) * d0 + f * d1;
    if (inv * surface < 1.0f) return true;  // farther than the surface: outside the gel
  }
  return false;
}

// Any other light (behind the camera's centre, or farther than the point): march the path in
// space, 24 steps down to the shallowest surface point.
bool ShadowCaster::blocked_in_space(const Light& light, const Eigen::Vector3f& p) const {
  constexpr int kSteps = 24;
  const GelGeometry& g = *gel_;
  const Eigen::Vector3f to_light = light.position - p;
  const float z_stop = 1.0f / inv_depth_max_ + g.origin_sensor.z();
  const float s_end = to_light.z() < 0.0f ? std::min(1.0f, (z_stop - p.z()) / to_light.z()) : 1.0f;
  for (int s = 1; s <= kSteps; ++s) {
    const Eigen::Vector3f q = p + to_light * (s_end * float(s) / kSteps);
    const float depth = q.z() - g.origin_sensor.z();
    if (depth <= 0.0f) break;
    const int x = int(std::lround(camera_.fx * q.x() / depth + camera_.cx));
    const int y = int(std::lround(camera_.fy * q.y() / depth + camera_.cy));
    if (rect_.contains(x, y) && depth > depth_at(x, y)) return true;
  }
  return false;
}

void ShadowCaster::visibility(int x, int y, const Eigen::Vector3f& p, const Eigen::Vector3f& n,
                              float* visibility, unsigned light_mask) const {
  const float depth = p.z() - gel_->origin_sensor.z();
  // A point at the dent's shallowest depth (its flat bottom, say) sees every light nearer to
  // the camera: nothing on the way can be farther from the camera than the surface.
  const bool shallowest = 1.0f / depth >= inv_depth_max_;
  for (std::size_t k = 0; k < lights_.size(); ++k) {
    const Light& light = lights_[k];
    bool blocked = false;
    if (k < 32 && !((light_mask >> k) & 1u)) {
      visibility[k] = 1.0f;
      continue;
    }
    if (n.dot(light.position - p) < 0.0f && inv_depth_max_ > 0.0f) {  // lit side, and a dent
      if (light.in_front && 1.0f / depth < light.inv_depth) {
        blocked = !shallowest && blocked_in_image(light, x, y, depth);
      } else {
        blocked = blocked_in_space(light, p);
      }
    }
    visibility[k] = blocked ? 0.0f : 1.0f;
  }
}

}  // namespace pg
