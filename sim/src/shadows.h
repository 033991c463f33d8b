#pragma once
// Shadows the deformed gel casts on itself: whether the straight path from a surface point to
// a light leaves the gel on the way.
#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "gel_surface.h"
#include "pg/core/sensor.h"
#include "shading.h"

namespace pg {

// A light is blocked at a surface point when the path from the point to the light passes,
// somewhere on the dented part of the surface (u > 0), farther from the camera than the surface
// seen there: outside the gel. (The undeformed gel is convex and the lights sit inside it, so
// only the dent can block.) The path is marched in the image, where it is a straight line too,
// one pixel column (or row) per step with the surface interpolated between the two pixels it
// passes, and only as far as it can still be blocked: it stops when it leaves the dent's
// rectangle or comes nearer to the camera than the dent's shallowest point, and skips stretches
// of 8 steps that are nearer to the camera than every surface point around them.
//
// The dent also shadows undeformed gel beside it, on its side away from a light: reach() bounds
// the pixels it can shadow, so that only those need a march.
class ShadowCaster {
 public:
  ShadowCaster(const Shader& shader, const GelGeometry& g, const CameraModel& camera);
  // Per frame: the deformed surface u, zero outside `dent`. Also finds each light's reach.
  void set_surface(const float* u, const PixelRect& dent);
  // The rectangle of the pixels (the dent's own included) whose path to some light can cross the
  // dent: empty when there is no dent. Lights the march in the image does not handle (behind
  // the camera's centre, or farther from the camera than the dent) add nothing.
  const PixelRect& reach() const { return reach_rect_; }
  // The lights (a bit each, from bit 0) whose path from pixel (x, y) can cross the dent: a
  // finer mask than the rectangles, from the dent's 8 x 8 tiles; bit 7 stands for the 8th light
  // and every light after it.
  unsigned reaching(int x, int y) const;
  std::size_t lights() const { return lights_.size(); }
  // Fraction in [0, 1] of each light that reaches pixel (x, y)'s surface point p with outward
  // normal n; a light the point faces away from gets 1 (it adds nothing to the shading anyway).
  // Only the lights whose bit is set in `light_mask` are marched (all from the 33rd on); the
  // others get 1.
  void visibility(int x, int y, const Eigen::Vector3f& p, const Eigen::Vector3f& n,
                  float* visibility, unsigned light_mask = ~0u) const;

 private:
  static constexpr int kTile = 8;  // [px], also the length of a skipped stretch [steps]
  struct Tiles {
    int size = 0, nx = 0;
    std::vector<float> depth;  // per tile, the smallest depth_ around it
    std::vector<float> own;    // per tile, its own smallest depth_
  };
  Tiles tile_minima(int tile) const;
  struct Light {
    Eigen::Vector3f position;
    bool in_front = false;  // in front of the camera: its image position is finite
    float x = 0, y = 0;     // its image position [px]
    float inv_depth = 0;    // 1 / its camera depth [1/m]
    float farthest_px = 0;  // from its image position to the farthest image corner [px]
  };
  PixelRect tile_reach(const Light& light, const PixelRect& tile, float shallowest) const;
  void find_reach();
  bool blocked_in_image(const Light& light, int x, int y, float depth) const;
  bool blocked_in_space(const Light& light, const Eigen::Vector3f& p) const;
  float depth_at(int x, int y) const {
    return depth_[std::size_t(y - rect_.y0) * rect_.width() + (x - rect_.x0)];
  }

  const GelGeometry* gel_;
  CameraModel camera_;
  std::vector<Light> lights_;
  PixelRect rect_;                        // the dent
  PixelRect reach_rect_;                  // the pixels whose path to a light can cross the dent
  std::vector<std::uint8_t> reach_mask_;  // per pixel of reach_rect_, the lights reaching it
  float far_depth_ = 0;                   // the largest camera depth of the undeformed gel [m]
  // Per pixel of rect_: camera depth of the dented surface + 1 um (+inf where u = 0). A path
  // point farther than that from the camera is outside the gel.
  std::vector<float> depth_;
  Tiles tiles_;
  float inv_depth_max_ = 0;  // 1 / the smallest depth_: a path point nearer cannot be outside
};

}  // namespace pg
