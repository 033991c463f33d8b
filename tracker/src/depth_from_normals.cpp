#include "pg/tracker/depth_from_normals.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "pg/core/error.h"
#include "pg/core/sensor.h"

namespace pg {

namespace {

// Eq. 4 in perspective form: the gradient of ln t (per pixel) from the normal n at a pixel whose
// ray is d (d_z = 1). Scale-invariant in n. Returns false when n.d had to be clamped.
inline bool log_depth_gradient(const float* n, const Eigen::Vector3f& d, float fx, float fy,
                               float min_dot, float& gx, float& gy) {
  const float dot = n[0] * d.x() + n[1] * d.y() + n[2];
  const bool ok = dot >= min_dot;
  const float inv = 1.0f / (ok ? dot : min_dot);
  gx = -n[0] * inv / fx;
  gy = -n[1] * inv / fy;
  return ok;
}

// A usable normal: finite, of unit length within kMinNormalLength-kMaxNormalLength (the
// gradient does not depend on the length) and facing away from the camera
// along the pixel's ray d (n.d > 0; the normals point out of the gel, away from the camera): the
// camera cannot see a surface from its far side. Not n.z > 0: off the axis a pixel sees walls
// that lean past the vertical, such as a stud's rim on the GelSight Mini (2026-12-03: hundreds of
// rendered pixels a frame had been rejected so). False for NaN and inf (|n|^2 is then NaN or inf);
// branch-free, so that classify_row's loop vectorises.
inline bool valid_normal(const float* n, const float* d) {
  const float sq = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
  const float facing = n[0] * d[0] + n[1] * d[1] + n[2];
  return (sq > kMinNormalLength * kMinNormalLength) & (sq < kMaxNormalLength * kMaxNormalLength) &
         (facing > 0.0f);
}

// Fills the gradient at invalid normals (grid indices `holes`, ascending) by linear
// interpolation between the nearest valid pixels left and right in the same grid row (or the one
// valid side). Taking them as undisturbed instead (zero) would cut a dent into the integrated
// indentation around every corrupted pixel inside a contact.
void fill_holes(const std::vector<std::size_t>& holes, int gw, std::vector<float>& gx,
                std::vector<float>& gy) {
  std::vector<std::uint8_t> is_hole(gx.size(), 0);
  for (std::size_t j : holes) is_hole[j] = 1;
  for (std::size_t k = 0; k < holes.size();) {
    // A run of holes [a, b) within one row.
    const std::size_t a = holes[k], row_start = a - a % std::size_t(gw);
    const std::size_t row_end = row_start + std::size_t(gw);
    std::size_t b = a;
    while (b < row_end && is_hole[b]) ++b;
    while (k < holes.size() && holes[k] < b) ++k;
    const bool left = a > row_start, right = b < row_end;
    if (!left && !right) continue;  // a whole row of holes stays zero
    for (std::size_t j = a; j < b; ++j) {
      const float s = left && right ? float(j - a + 1) / float(b - a + 1) : left ? 0.0f : 1.0f;
      const std::size_t l = left ? a - 1 : b, r = right ? b : a - 1;
      gx[j] = (1 - s) * gx[l] + s * gx[r];
      gy[j] = (1 - s) * gy[l] + s * gy[r];
    }
  }
}

// One image row: flags[x] = 1 where the normal is valid and more than the threshold angle from
// the reference (n.r < cos(angle) |n|, without a square root), else 0. Returns the number of
// invalid normals and adds the flagged ones to `disturbed`. Branch-free, so it vectorises.
// `ray` reads a row of GelRays::dir_sensor as packed floats.
static_assert(sizeof(Eigen::Vector3f) == 3 * sizeof(float));
int classify_row(const float* n, const float* ref, const float* ray, int width, float cos_threshold,
                 std::uint8_t* flags, int& disturbed) {
  const float c2 = cos_threshold * cos_threshold;
  int invalid = 0, count = 0;
  for (int x = 0; x < width; ++x) {
    const float nx = n[3 * x], ny = n[3 * x + 1], nz = n[3 * x + 2];
    const float sq = nx * nx + ny * ny + nz * nz;
    const float dot = nx * ref[3 * x] + ny * ref[3 * x + 1] + nz * ref[3 * x + 2];
    const bool valid = valid_normal(n + 3 * x, ray + 3 * x);
    const bool far = (dot <= 0.0f) | (dot * dot < c2 * sq);
    const bool flag = valid & far;
    flags[x] = flag;
    invalid += !valid;
    count += flag;
  }
  disturbed += count;
  return invalid;
}

// Grows [lo, hi) by `margin` on both sides and then to the next fast DST size, centring the
// padding. The result may reach past the image.
void fast_window(int lo, int hi, int margin, int& out_lo, int& out_hi, bool even) {
  const int want = (hi - lo) + 2 * margin;
  const int n = even ? 2 * dst_fast_size((want + 1) / 2) : dst_fast_size(want);
  out_lo = lo - margin - (n - want) / 2;
  out_hi = out_lo + n;
}

// The image row or column each of `count` grid positions from `first` reads (-1: none, past an
// edge not mirrored or past the mirrored copy) and the sign of the gradient's component along
// the axis there: a position mirrored across an edge reads the pixel as far inside it, the
// gradient's component across the edge reversed.
void map_grid_axis(int first, int count, int size, bool mirror_low, bool mirror_high,
                   std::vector<int>& source, std::vector<float>& sign) {
  source.resize(std::size_t(count));
  sign.resize(std::size_t(count));
  for (int k = 0; k < count; ++k) {
    int v = first + k;
    float s = 1.0f;
    if (v < 0 && mirror_low) {
      v = -1 - v;
      s = -1.0f;
    } else if (v >= size && mirror_high) {
      v = 2 * size - 1 - v;
      s = -1.0f;
    }
    source[std::size_t(k)] = v >= 0 && v < size ? v : -1;
    sign[std::size_t(k)] = s;
  }
}

void check_normal_image(const ImageF& image, const GelRays& rays, const char* what) {
  const std::size_t values = image.shape_values();
  if (image.same_shape(rays.width, rays.height, 3) && image.data.size() != values) {
    // A camera buffer wrapped by hand, its size not the shape's: it had been read past its end.
    throw InputError(std::string(what) + ": " + std::to_string(image.width) + " x " +
                     std::to_string(image.height) + " x 3 image holds " +
                     std::to_string(image.data.size()) + " values, not " + std::to_string(values));
  }
  if (!image.same_shape(rays.width, rays.height, 3)) {
    throw InputError(std::string(what) + ": expected a " + std::to_string(rays.width) + " x " +
                     std::to_string(rays.height) + " x 3 normal image, got " +
                     std::to_string(image.width) + " x " + std::to_string(image.height) + " x " +
                     std::to_string(image.channels));
  }
}

// `sensor`, once it is one a sensor file could give (a 0 x 0 camera set in C++ had been taken, and
// every frame then read as no contact).
const SensorModel& checked(const SensorModel& sensor) {
  check_sensor_model(sensor, "DepthFromNormals: sensor " + sensor.name);
  return sensor;
}

}  // namespace

DepthFromNormals::DepthFromNormals(const SensorModel& sensor, const DepthOptions& options,
                                   const ImageF& reference_normals)
    : options_(options),
      rays_(make_gel_rays(checked(sensor).camera, sensor.gel)),
      solver_(PoissonDstOptions{options.dst_backend, options.measure_fft_plans, 32}) {
  options_.crop_margin_px = std::max(options_.crop_margin_px, 1);
  const double c = options_.min_normal_dot_ray;
  const double widen = kGuardPitchM * rays_.px_per_m;  // over the pixel's size on the gel
  min_dot_ = float(c);
  if (widen > 1.0 && c < 1.0) {
    const double slope = widen * std::sqrt(1.0 - c * c) / c;
    min_dot_ = float(1.0 / std::sqrt(1.0 + slope * slope));
  }
  const bool gel_model = reference_normals.empty();
  if (gel_model) {
    reference_normals_ = undeformed_gel_normals(rays_);
  } else {
    check_normal_image(reference_normals, rays_, "reference normals");
    reference_normals_ = reference_normals;
  }
  const std::size_t n = std::size_t(rays_.width) * rays_.height;
  reference_gradient_.resize(2 * n);
  for (std::size_t i = 0; i < n; ++i) {
    float* nr = &reference_normals_.data[3 * i];
    if (!valid_normal(nr, rays_.dir_sensor[i].data())) {
      const std::string pixel = "pixel (" + std::to_string(i % rays_.width) + ", " +
                                std::to_string(i / rays_.width) + ")";
      if (gel_model) {  // the sensor's own gel model, which names no file (an audit's 2.5 rad)
        throw InputError("the sensor's undeformed gel has no usable normal at " + pixel +
                         ": its camera sees past the gel there, or along it (the camera's field "
                         "of view, camera.fov_y_rad or fx and fy, against gel.width_m and "
                         "gel.height_m)");
      }
      throw InputError("reference normals: " + pixel + " is not a finite unit normal");
    }
    // Made unit: the disturbance test compares angles as n.r against |n| (a reference of length
    // 0.99, as a network gives, had flagged every pixel; one of 1.01 widened the threshold to 8
    // deg).
    // (One unit to float precision is left as it is: the gel model's own, to the last bit.)
    const float length = std::sqrt(nr[0] * nr[0] + nr[1] * nr[1] + nr[2] * nr[2]);
    if (std::abs(length - 1.0f) > 1e-6f)
      for (int c = 0; c < 3; ++c) nr[c] /= length;
    log_depth_gradient(nr, rays_.dir_sensor[i], float(rays_.fx), float(rays_.fy), min_dot_,
                       reference_gradient_[2 * i], reference_gradient_[2 * i + 1]);
  }
}

void DepthFromNormals::compute(const ImageF& normals, DepthResult& out,
                               const std::array<bool, 4>& mirror_edges) {
  check_normal_image(normals, rays_, "normals");
  const int W = rays_.width, H = rays_.height;

  // Clear what the previous frame wrote (or allocate on first use).
  if (!out.depth.same_shape(W, H, 1)) {
    out.depth = ImageF(W, H, 1, 0.0f);
  } else {
    const PixelRect old = out.window.clipped(W, H);
    for (int y = old.y0; y < old.y1; ++y) {
      std::fill_n(&out.depth.at(old.x0, y), old.width(), 0.0f);
    }
  }
  out.window = {};
  out.disturbed_box = {};
  out.mirrored = {};
  out.disturbed_pixels = out.invalid_normals = out.clamped_normals = 0;

  // 1. Which pixels differ from the reference, row by row.
  const float cos_threshold = float(std::cos(options_.disturbed_angle_rad));
  flags_.resize(std::size_t(W));
  int bx0 = W, by0 = H, bx1 = -1, by1 = -1;
  for (int y = 0; y < H; ++y) {
    const std::size_t row = 3 * std::size_t(y) * W;
    int disturbed = 0;
    out.invalid_normals += classify_row(
        normals.data.data() + row, reference_normals_.data.data() + row,
        rays_.dir_sensor[std::size_t(y) * W].data(), W, cos_threshold, flags_.data(), disturbed);
    if (disturbed == 0) continue;
    out.disturbed_pixels += disturbed;
    int first = 0, last = W - 1;
    while (!flags_[first]) ++first;
    while (!flags_[last]) --last;
    bx0 = std::min(bx0, first);
    bx1 = std::max(bx1, last);
    by0 = std::min(by0, y);
    by1 = y;
  }
  if (out.disturbed_pixels == 0) return;  // flat: u = 0 everywhere
  out.disturbed_box = {bx0, by0, bx1 + 1, by1 + 1};

  // 2. The Poisson grid: the disturbed box plus margin, or the whole image, at fast DST sizes;
  // with the box's mirror image across each edge to mirror (the header's compute).
  const std::array<bool, 4> reached = {bx0 == 0, by0 == 0, bx1 == W - 1, by1 == H - 1};
  for (int e = 0; e < 4; ++e) out.mirrored[e] = mirror_edges[e] && reached[e];
  const PixelRect box = options_.crop ? out.disturbed_box : PixelRect{0, 0, W, H};
  PixelRect need = box;
  if (out.mirrored[0]) need.x0 = -box.x1;
  if (out.mirrored[1]) need.y0 = -box.y1;
  if (out.mirrored[2]) need.x1 = 2 * W - box.x0;
  if (out.mirrored[3]) need.y1 = 2 * H - box.y0;
  const int margin = options_.crop ? options_.crop_margin_px : 0;
  PixelRect& win = out.window;
  const bool parity = options_.integration == DepthIntegration::kParity;
  fast_window(need.x0, need.x1, margin, win.x0, win.x1, parity);
  fast_window(need.y0, need.y1, margin, win.y0, win.y1, parity);
  const int nx = win.width(), ny = win.height();

  // 3. g - g_ref over the grid and a one-pixel ring: the image's own inside it, mirrored across
  // an edge the contact reaches, zero past any other edge. Invalid normals are holes, filled
  // afterwards from their row's valid neighbours.
  const int gw = nx + 2, gh = ny + 2;
  gx_.assign(std::size_t(gw) * gh, 0.0f);
  gy_.assign(std::size_t(gw) * gh, 0.0f);
  map_grid_axis(win.x0 - 1, gw, W, out.mirrored[0], out.mirrored[2], source_x_, sign_x_);
  map_grid_axis(win.y0 - 1, gh, H, out.mirrored[1], out.mirrored[3], source_y_, sign_y_);
  std::vector<std::size_t> holes;  // grid indices; allocated only for a frame that has some
  const float* nimg = normals.data.data();
  const float fx = float(rays_.fx), fy = float(rays_.fy);
  const float min_dot = min_dot_;
  for (int gy = 0; gy < gh; ++gy) {
    const int y = source_y_[std::size_t(gy)];
    if (y < 0) continue;
    const bool own_row = y == win.y0 - 1 + gy;
    for (int gx = 0; gx < gw; ++gx) {
      const int x = source_x_[std::size_t(gx)];
      if (x < 0) continue;
      const std::size_t i = std::size_t(y) * W + x;
      const std::size_t j = std::size_t(gy) * gw + gx;
      const float* n = nimg + 3 * i;
      if (!valid_normal(n, rays_.dir_sensor[i].data())) {
        holes.push_back(j);
        continue;
      }
      float g_x, g_y;
      const bool unclamped = log_depth_gradient(n, rays_.dir_sensor[i], fx, fy, min_dot, g_x, g_y);
      // (A mirrored pixel is the image's own pixel again: counted once.)
      if (!unclamped && own_row && x == win.x0 - 1 + gx) ++out.clamped_normals;
      gx_[j] = sign_x_[std::size_t(gx)] * (g_x - reference_gradient_[2 * i]);
      gy_[j] = sign_y_[std::size_t(gy)] * (g_y - reference_gradient_[2 * i + 1]);
    }
  }

  if (!holes.empty()) fill_holes(holes, gw, gx_, gy_);

  // 4. Solve for w = ln(t / t_gel) over the grid.
  const float* w = parity ? integrate_parity(nx, ny) : integrate_averaged(nx, ny);

  // 5. u = t_gel (1 - exp(w)) on the grid's pixels inside the image.
  const PixelRect inside = win.clipped(W, H);
  for (int y = inside.y0; y < inside.y1; ++y) {
    const float* wr = w + std::size_t(y - win.y0) * nx;  // the grid's row, from win.x0
    float* ur = &out.depth.at(0, y);
    const float* tg = &rays_.t_gel[std::size_t(y) * W];
    for (int x = inside.x0; x < inside.x1; ++x) ur[x] = tg[x] * -std::expm1(wr[x - win.x0]);
  }
}

// The gradients averaged to the half-pixel positions so that the divergence matches the 5-point
// Laplacian: f = (g_x(x+1) - g_x(x-1)) / 2 + (g_y(y+1) - g_y(y-1)) / 2.
const float* DepthFromNormals::integrate_averaged(int nx, int ny) {
  const int gw = nx + 2;
  float* f = solver_.grid(nx, ny);
  for (int y = 0; y < ny; ++y) {
    const float* gxr = &gx_[std::size_t(y + 1) * gw + 1];
    const float* gyu = &gy_[std::size_t(y) * gw + 1];
    const float* gyd = &gy_[std::size_t(y + 2) * gw + 1];
    float* fr = f + std::size_t(y) * nx;
    for (int x = 0; x < nx; ++x) {
      fr[x] = 0.5f * (gxr[x + 1] - gxr[x - 1]) + 0.5f * (gyd[x] - gyu[x]);
    }
  }
  solver_.solve();
  return f;
}

// On the sub-grid of one parity (step 2 px), w(x + 2) - w(x) = 2 g_x(x + 1): its Laplacian is
// 2 (g_x(x+1) - g_x(x-1)) + 2 (g_y(y+1) - g_y(y-1)) at each of its cells. nx, ny are even (see
// fast_window), so the four sub-grids are nx/2 x ny/2 and their cells just outside lie on the
// grid's ring or one beyond it, both undisturbed (w = 0) by the crop margin.
const float* DepthFromNormals::integrate_parity(int nx, int ny) {
  const int gw = nx + 2, mx = nx / 2, my = ny / 2;
  w_.resize(std::size_t(nx) * ny);
  for (int py = 0; py < 2; ++py) {
    for (int px = 0; px < 2; ++px) {
      float* f = solver_.grid(mx, my);
      for (int j = 0; j < my; ++j) {
        const float* g_x = &gx_[std::size_t(py + 2 * j + 1) * gw + px + 1];
        const float* g_yu = &gy_[std::size_t(py + 2 * j) * gw + px + 1];
        const float* g_yd = g_yu + 2 * std::size_t(gw);
        float* fr = f + std::size_t(j) * mx;
        for (int i = 0; i < mx; ++i) {
          const int c = 2 * i;
          fr[i] = 2.0f * (g_x[c + 1] - g_x[c - 1]) + 2.0f * (g_yd[c] - g_yu[c]);
        }
      }
      solver_.solve();
      for (int j = 0; j < my; ++j) {
        float* wr = &w_[std::size_t(py + 2 * j) * nx + px];
        const float* fr = f + std::size_t(j) * mx;
        for (int i = 0; i < mx; ++i) wr[2 * i] = fr[i];
      }
    }
  }
  return w_.data();
}

}  // namespace pg
