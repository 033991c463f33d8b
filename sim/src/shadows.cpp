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
    }
    lights_.push_back(light);
  }
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
  std::vector<float> own(std::size_t(t.nx) * ny, INFINITY);
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

void ShadowCaster::set_surface(const float* u, const PixelRect& rect) {
  rect_ = rect;
  const int w = rect.width();
  depth_.resize(std::size_t(rect.area()));
  float shallowest = INFINITY;
  const GelGeometry& g = *gel_;
  for (int y = rect.y0; y < rect.y1; ++y) {
    float* out = &depth_[std::size_t(y - rect.y0) * w];
    for (int x = rect.x0; x < rect.x1; ++x) {
      const int i = g.index(x, y);
      out[x - rect.x0] = u[i] > 0.0f ? g.t_gel[i] - u[i] + 1e-6f : INFINITY;
      shallowest = std::min(shallowest, out[x - rect.x0]);
    }
  }
  inv_depth_max_ = 1.0f / shallowest;
  tiles_ = tile_minima(kTile);
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
  // The last step inside the rectangle: the path is a straight line in the image, so once out
  // it stays out.
  int steps = std::min(int(length), step > 0 ? a_hi - 1 - a0 : a0 - a_lo);
  if (m_step != 0.0f) {
    const float m_edge = m_step > 0.0f ? float(m_hi) - 0.5f : float(m_lo) - 0.5f;
    steps = std::min(steps, int(std::ceil((m_edge - m0) / m_step)) - 1);
  }
  for (int k = 1; k <= steps; ++k) {
    const float inv = inv0 + float(k) * inv_step;
    if (inv >= inv_depth_max_) return false;  // nearer than any surface point: it stays inside
    const int a = a0 + k * step;
    const float m = m0 + float(k) * m_step;
    // The next kTile steps are nearer to the camera than this one: skip them if this one is
    // already nearer than every surface point within their reach.
    if ((k - 1) % kTile == 0) {
      const int ta = (a - a_lo) / kTile, tm = (int(m + 0.5f) - m_lo) / kTile;
      const int i = along_x ? tm * tiles_.nx + ta : ta * tiles_.nx + tm;
      if (inv * tiles_.depth[std::size_t(i)] >= 1.0f) {
        k += kTile - 1;
        continue;
      }
    }
    const float m_floor = std::floor(m);
    const float f = m - m_floor;
    const int i_a = (a - a_lo) * stride_a;
    const int mi0 = std::max(int(m_floor), m_lo) - m_lo, mi1 = std::min(int(m_floor) + 1, m_hi - 1) - m_lo;
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
                              float* visibility) const {
  const float depth = p.z() - gel_->origin_sensor.z();
  // A point at the dent's shallowest depth (its flat bottom, say) sees every light nearer to
  // the camera: nothing on the way can be farther from the camera than the surface.
  const bool shallowest = 1.0f / depth >= inv_depth_max_;
  for (std::size_t k = 0; k < lights_.size(); ++k) {
    const Light& light = lights_[k];
    bool blocked = false;
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
