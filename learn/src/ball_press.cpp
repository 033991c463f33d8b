#include "pg/learn/ball_press.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <limits>
#include <vector>

#include "pg/core/gel_elastic.h"
#include "pg/core/image_change.h"

namespace pg {
namespace {

// A second changed region at least 1 / this of the largest is a second contact.
constexpr int kSecondContactFraction = 10;
// A circle needs this many boundary points, and must pass this close to them: within 3 % of its
// radius (RMS), or half a pixel for small ones. Rendered ball presses fit within 0.15-0.46 px,
// at most 2.3 % of their radius; a cube's corner or edge 1.4-7.8 % (docs/learned_normals.md).
constexpr int kMinBoundaryPoints = 12;
constexpr double kMaxRmsFraction = 0.03, kMinRmsLimitPx = 0.5;
// How far outside its circle a press's pixels at the image's edge may lie [px].
constexpr double kEdgeSlackPx = 2.0;
// The four neighbours of a pixel.
constexpr int kDx[4] = {-1, 1, 0, 0}, kDy[4] = {0, 0, -1, 1};

std::string format(const char* fmt, double a, double b = 0) {
  char text[256];
  std::snprintf(text, sizeof(text), fmt, a, b);
  return text;
}

// The undeformed gel point seen at image position (u, v) [px]: the pixels' gel points,
// interpolated bilinearly (clamped to the image).
Eigen::Vector3d gel_point(const GelRays& rays, double u, double v) {
  u = std::clamp(u, 0.0, double(rays.width - 1));
  v = std::clamp(v, 0.0, double(rays.height - 1));
  const int x0 = std::min(int(u), rays.width - 2), y0 = std::min(int(v), rays.height - 2);
  const double fx = u - x0, fy = v - y0;
  const auto p = [&](int x, int y) -> Eigen::Vector3d {
    return rays.point(rays.index(x, y), 0.0f).cast<double>();
  };
  return (1 - fy) * ((1 - fx) * p(x0, y0) + fx * p(x0 + 1, y0)) +
         fy * ((1 - fx) * p(x0, y0 + 1) + fx * p(x0 + 1, y0 + 1));
}

// The centre c on the object's side (+z) of the points q that puts them all at `radius` (least
// squares, Gauss-Newton from the centre of the circle they span). Returns false when the points
// span a circle wider than the ball.
bool fit_ball(const std::vector<Eigen::Vector3d>& q, double radius, Eigen::Vector3d* centre) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : q) mean += p;
  mean /= double(q.size());
  double spread = 0;
  for (const auto& p : q) spread += (p - mean).head<2>().norm();
  spread /= double(q.size());
  if (spread >= radius) return false;
  Eigen::Vector3d c =
      mean + Eigen::Vector3d::UnitZ() * std::sqrt(radius * radius - spread * spread);
  for (int it = 0; it < 50; ++it) {
    Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const auto& p : q) {
      const Eigen::Vector3d d = p - c;
      const double n = d.norm();
      const Eigen::Vector3d J = -d / n;  // d(|p - c| - radius) / dc
      H += J * J.transpose();
      g += J * (n - radius);
    }
    const Eigen::Vector3d step = H.ldlt().solve(-g);
    if (!step.allFinite()) break;
    c += step;
    if (step.norm() < 1e-12) break;
  }
  *centre = c;
  return c.allFinite();
}

// The circle through image points (least squares, x^2 + y^2 + a x + b y + c = 0).
void image_circle(const std::vector<Eigen::Vector2d>& points, Eigen::Vector2d* centre,
                  double* radius) {
  Eigen::MatrixXd A(points.size(), 3);
  Eigen::VectorXd rhs(points.size());
  for (std::size_t k = 0; k < points.size(); ++k) {
    A.row(Eigen::Index(k)) << points[k].x(), points[k].y(), 1.0;
    rhs(Eigen::Index(k)) = -points[k].squaredNorm();
  }
  const Eigen::Vector3d abc = A.colPivHouseholderQr().solve(rhs);
  *centre = -0.5 * abc.head<2>();
  *radius = std::sqrt(std::max(0.0, centre->squaredNorm() - abc.z()));
}

// Puts the press's ball at `centre`: its depth, or the reason it cannot be there.
bool place_at(const GelRays& rays, const Eigen::Vector3d& centre, double radius_m,
              double max_indentation_m, BallPress* press) {
  const ImageF u = sphere_indentation(rays, centre, radius_m);
  press->centre_m = centre;
  press->depth_m = double(*std::max_element(u.data.begin(), u.data.end()));
  if (press->depth_m <= 0) {
    press->reason = "the fitted ball does not indent the gel";
    return false;
  }
  if (press->depth_m > max_indentation_m) {
    press->reason = format(
        "the fitted ball is %.2f mm deep, deeper than the gel takes (%.2f mm, the sensor's "
        "max_indentation_m): a press to the gel's bottom, whose shape the ball no longer "
        "gives, or a wrong diameter",
        press->depth_m * 1e3, max_indentation_m * 1e3);
    return false;
  }
  return true;
}

// Fits the ball to the image points (u, v) on its contact's boundary, drops the points more than
// three median deviations (at least a pixel) off it and fits again; then the depth and checks.
BallPress fit_press(const GelRays& rays, const std::vector<Eigen::Vector2d>& boundary,
                    const std::vector<Eigen::Vector2d>& at_edge, double radius_m) {
  BallPress press;
  if (int(boundary.size()) < kMinBoundaryPoints) {
    press.reason = format("the contact's boundary has %.0f points, fewer than %.0f to fit a circle",
                          double(boundary.size()), kMinBoundaryPoints);
    return press;
  }
  std::vector<Eigen::Vector2d> image = boundary;
  std::vector<Eigen::Vector3d> q;
  for (const auto& b : boundary) q.push_back(gel_point(rays, b.x(), b.y()));
  const auto off_px = [&](const Eigen::Vector3d& p, const Eigen::Vector3d& c) {
    return std::abs((p - c).norm() - radius_m) * rays.px_per_m;
  };
  Eigen::Vector3d c;
  for (int pass = 0; pass < 2; ++pass) {
    if (!fit_ball(q, radius_m, &c)) {
      press.reason = format(
          "the contact is wider than a ball of diameter %.2f mm makes: is the diameter right?",
          2e3 * radius_m);
      return press;
    }
    if (pass == 1) break;
    std::vector<double> off;
    for (const auto& p : q) off.push_back(off_px(p, c));
    std::vector<double> sorted = off;
    std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
    const double keep = std::max(1.0, 3.0 * 1.4826 * sorted[sorted.size() / 2]);
    std::vector<Eigen::Vector3d> kept;
    std::vector<Eigen::Vector2d> kept_image;
    for (std::size_t k = 0; k < q.size(); ++k) {
      if (off[k] > keep) continue;
      kept.push_back(q[k]);
      kept_image.push_back(image[k]);
    }
    if (int(kept.size()) < kMinBoundaryPoints) break;
    q.swap(kept);
    image.swap(kept_image);
  }
  double sum_sq = 0;
  for (const auto& p : q) sum_sq += off_px(p, c) * off_px(p, c);
  press.rms_px = std::sqrt(sum_sq / double(q.size()));
  press.boundary_points = int(q.size());
  press.centre_m = c;
  // The circle in the image through the same points: what --circles takes back.
  image_circle(image, &press.centre_px, &press.radius_px);
  const double limit = std::max(kMinRmsLimitPx, kMaxRmsFraction * press.radius_px);
  if (press.rms_px > limit) {
    press.reason = format(
        "the change is not a circle: its boundary lies %.2f px (RMS) off the "
        "best ball, more than %.2f px; one ball pressed at a time?",
        press.rms_px, limit);
    return press;
  }
  // The press where the image's edge cuts it must lie inside the circle: a short arc can fit a
  // smaller circle than the press's (the region is one pixel wider than its boundary, and the
  // change test's mean reaches one more).
  double beyond = -std::numeric_limits<double>::infinity();
  for (const auto& p : at_edge) beyond = std::max(beyond, (p - press.centre_px).norm());
  if (beyond > press.radius_px + kEdgeSlackPx) {
    press.reason = format(
        "the press runs off the image's edge %.1f px beyond the circle fitted to its arc (radius "
        "%.1f px): too little of it in the image to place the ball",
        beyond - press.radius_px, press.radius_px);
    return press;
  }
  // A short arc (a press mostly beyond the image's edge) leaves the centre poorly determined.
  std::vector<double> angles;
  for (const auto& p : image) {
    angles.push_back(std::atan2(p.y() - press.centre_px.y(), p.x() - press.centre_px.x()));
  }
  std::sort(angles.begin(), angles.end());
  double gap = angles.front() + 2 * kPi - angles.back();
  for (std::size_t k = 1; k < angles.size(); ++k) gap = std::max(gap, angles[k] - angles[k - 1]);
  if (gap > kPi) {
    press.reason = format(
        "less than half of the contact's circle is in the image (%.0f of 360 "
        "deg): too little to place the ball",
        360.0 - gap * 180.0 / kPi);
    return press;
  }
  // The gel's depth limit is checked once the ball is placed (by the shading): through the circle
  // alone it sits too deep on an elastic gel.
  press.found = place_at(rays, c, radius_m, std::numeric_limits<double>::infinity(), &press);
  return press;
}

// The boundary of the change a press makes: the largest 4-connected region of the pixels that
// differ from the no-contact reference beyond the camera's noise, its holes filled, less its
// outermost ring; the points midway between it and the pixels outside, and its pixels next to
// the image's outermost ones (which the change test never marks). False (with none's reason and
// no_change) when the frame shows no single press.
bool change_boundary(const ImageU8& color, const ImageU8& reference,
                     std::vector<Eigen::Vector2d>* boundary, std::vector<Eigen::Vector2d>* at_edge,
                     BallPress* none) {
  const int w = color.width, h = color.height;
  const ChangedRegions changes = changed_regions(color, reference);
  const int changed_count = changes.changed;
  if (changed_count < kMinPressPixels) {
    none->no_change = true;
    none->reason = format(
        "%.0f px differ from the no-contact reference beyond the camera's noise, "
        "fewer than a press changes (%.0f): no contact",
        double(changed_count), double(kMinPressPixels));
    return false;
  }
  if (changed_count > w * h / 2) {
    none->reason = format(
        "%.0f %% of the image differs from the no-contact reference: a camera "
        "dropout, or the lighting changed since the reference was taken",
        100.0 * changed_count / (w * h));
    return false;
  }
  const std::vector<int>& label = changes.region;
  const int best = changes.largest();
  const int best_size = changes.sizes[std::size_t(best)];
  // Changes of a tenth of the largest or more (and at least a press's) are contacts; smaller ones
  // (a speck of dust, a noise cluster) are left out.
  std::vector<int> sizes = changes.sizes;
  std::sort(sizes.begin(), sizes.end(), std::greater<int>());
  const int regions = int(std::count_if(sizes.begin(), sizes.end(), [&](int size) {
    return size >= kMinPressPixels && size * kSecondContactFraction >= best_size;
  }));
  const int second_size = sizes.size() > 1 ? sizes[1] : 0;
  if (regions >= 3) {
    none->reason = format(
        "the frame differs from the no-contact reference in %.0f separate places: the lighting "
        "changed or the camera moved since the reference was taken?",
        double(regions));
    return false;
  }
  if (regions == 2) {
    none->reason = format("two separate contacts (%.0f and %.0f px): one ball at a time",
                          double(best_size), double(second_size));
    return false;
  }
  if (best_size < kMinPressPixels) {
    // Scattered specks (a noisy reference's, or dust's) and no press: labelled as a frame
    // without contact.
    none->no_change = true;
    none->reason = format("the largest change covers %.0f px, fewer than a press's %.0f",
                          double(best_size), double(kMinPressPixels)) +
                   format(": no contact (%.0f changed pixels, scattered: camera noise?)",
                          double(changed_count));
    return false;
  }
  // Its holes filled (a press's flat middle may look like the reference): every pixel that the
  // image's border cannot reach without crossing the region.
  std::vector<char> outside(label.size(), 0);
  std::vector<int> stack;
  for (int i = 0; i < w * h; ++i) {
    const int x = i % w, y = i / w;
    if ((x == 0 || y == 0 || x == w - 1 || y == h - 1) && label[std::size_t(i)] != best) {
      outside[std::size_t(i)] = 1;
      stack.push_back(i);
    }
  }
  flood_fill(
      w, h, stack, [&](int j) { return !outside[std::size_t(j)] && label[std::size_t(j)] != best; },
      [&](int j) { outside[std::size_t(j)] = 1; });
  // The change test's 3x3 mean reaches one pixel beyond a sharp change: the region less its
  // outermost pixels (measured on rendered presses of the rigid gel: the ball's centre 0.15 mm
  // off without this, 0.05 mm with it; docs/learned_normals.md).
  // The image's outermost pixels, which the change test never marks, are not outside the press.
  const auto beyond = [&](int x, int y) {
    return x > 0 && y > 0 && x < w - 1 && y < h - 1 && outside[std::size_t(y) * w + x];
  };
  std::vector<char> grown = outside;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      if (beyond(x - 1, y) || beyond(x + 1, y) || beyond(x, y - 1) || beyond(x, y + 1)) {
        grown[std::size_t(y) * w + x] = 1;
      }
    }
  }
  outside.swap(grown);
  // The boundary: midway between each region pixel and an outside neighbour, except at the
  // image's outermost pixels, which the change test never marks (a press cut by the image's edge
  // keeps only its arc inside).
  boundary->clear();
  at_edge->clear();
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      if (outside[std::size_t(y) * w + x]) continue;
      if (x == 1 || y == 1 || x == w - 2 || y == h - 2) at_edge->emplace_back(x, y);
      for (int k = 0; k < 4; ++k) {
        const int dx = kDx[k], dy = kDy[k], nx = x + dx, ny = y + dy;
        if (nx <= 0 || ny <= 0 || nx >= w - 1 || ny >= h - 1) continue;
        if (outside[std::size_t(ny) * w + nx]) boundary->emplace_back(x + 0.5 * dx, y + 0.5 * dy);
      }
    }
  }
  return true;
}

// The press's middle, where the gel takes the ball's shape whatever its elasticity: within this
// fraction of the circle's radius, and tilted less than this (the colour change is near linear
// in the tilt there, as at the edge of the visible change); the colour model needs this many of
// its pixels.
constexpr double kMiddleFraction = 0.75, kMaxModelTilt = 0.2;
constexpr int kMinModelPixels = 20;
// The placed ball's predicted circle must have the found one's radius to this much [px].
constexpr double kRadiusTolerancePx = 0.5;

// Places the press's ball by the shading (find_ball_press, step 2). `press` holds the ball
// placed through its circle; its centre is moved (and shading_fit set) when the colour model can
// be fitted and the predicted circle brought onto the found one; otherwise it is left as it was.
// Its depth is the caller's to update (place()).
void place_by_shading(const ImageU8& color, const ImageU8& reference, const GelRays& rays,
                      double radius_m, const GelModel& gel, double blend_blur_px,
                      BallPress* press) {
  const int w = rays.width, h = rays.height;
  const ImageF flat = undeformed_gel_normals(rays);
  // The colour change per channel against the tilt (nx, ny of the normal less the undeformed
  // gel's) over the middle, by least squares with an offset (the middle's mean change).
  const ImageF ball = gel_normals(rays, sphere_indentation(rays, press->centre_m, radius_m));
  std::vector<Eigen::Vector3d> rows;
  std::vector<Eigen::Vector3d> change;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      if ((Eigen::Vector2d(x, y) - press->centre_px).norm() > kMiddleFraction * press->radius_px)
        continue;
      const std::size_t i = std::size_t(y) * w + x;
      const double tx = ball.data[3 * i] - flat.data[3 * i];
      const double ty = ball.data[3 * i + 1] - flat.data[3 * i + 1];
      if (std::hypot(tx, ty) > kMaxModelTilt) continue;
      rows.emplace_back(1.0, tx, ty);
      change.emplace_back(double(color.data[3 * i]) - reference.data[3 * i],
                          double(color.data[3 * i + 1]) - reference.data[3 * i + 1],
                          double(color.data[3 * i + 2]) - reference.data[3 * i + 2]);
    }
  }
  if (int(rows.size()) < kMinModelPixels) return;
  Eigen::MatrixXd A(rows.size(), 3), B(rows.size(), 3);
  for (std::size_t k = 0; k < rows.size(); ++k) {
    A.row(Eigen::Index(k)) = rows[k].transpose();
    B.row(Eigen::Index(k)) = change[k].transpose();
  }
  const Eigen::Matrix3d model = A.colPivHouseholderQr().solve(B);  // rows: offset, tx, ty
  if (!model.allFinite()) return;
  const Eigen::Matrix<double, 2, 3> slope = model.bottomRows<2>();

  // The circle the search finds in the frame the gel model and the colour model predict for a
  // ball at c.
  std::vector<Eigen::Vector2d> boundary, edge;
  ImageU8 predicted = reference;
  // A blended frame's change was blurred (TACTO's blend): the predicted one is too, so that its
  // visible edge falls where the frame's does.
  const GaussianKernel blur = gaussian_kernel(blend_blur_px);
  const std::size_t n = std::size_t(w) * h;
  std::vector<float> delta_of(blur.weights.empty() ? 0 : 3 * n), plane(delta_of.empty() ? 0 : n),
      blurred(plane.size());
  const auto predicted_circle = [&](const Eigen::Vector3d& c, Eigen::Vector2d* centre,
                                    double* radius) {
    const ImageF rigid = sphere_indentation(rays, c, radius_m);
    const ImageF normal = gel_normals(rays, elastic_indentation(gel.elastic, rays.px_per_m, rigid));
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d tilt(normal.data[3 * i] - flat.data[3 * i],
                                 normal.data[3 * i + 1] - flat.data[3 * i + 1]);
      const Eigen::Vector3d delta = slope.transpose() * tilt;
      for (int ch = 0; ch < 3; ++ch) {
        if (!delta_of.empty()) {
          delta_of[3 * i + ch] = float(delta[ch]);
          continue;
        }
        predicted.data[3 * i + ch] =
            std::uint8_t(std::clamp(std::lround(reference.data[3 * i + ch] + delta[ch]), 0L, 255L));
      }
    }
    if (!delta_of.empty()) {
      const PixelRect all{0, 0, w, h};
      for (int ch = 0; ch < 3; ++ch) {
        for (std::size_t i = 0; i < n; ++i) plane[i] = delta_of[3 * i + ch];
        gaussian_blur(plane.data(), blurred.data(), plane.data(), w, all, blur);
        for (std::size_t i = 0; i < n; ++i)
          predicted.data[3 * i + ch] = std::uint8_t(
              std::clamp(std::lround(reference.data[3 * i + ch] + blurred[i]), 0L, 255L));
      }
    }
    BallPress ignored;
    if (!change_boundary(predicted, reference, &boundary, &edge, &ignored) ||
        int(boundary.size()) < kMinBoundaryPoints)
      return false;
    image_circle(boundary, centre, radius);
    return true;
  };
  // The depth that gives the circle's radius, by bisection along z between the ball just
  // touching and 0.5 mm deeper than the circle put it.
  Eigen::Vector3d c = press->centre_m;
  const auto fit_depth = [&]() {
    double deeper = -5e-4, shallower = press->depth_m;
    Eigen::Vector2d centre;
    double r_deep = 0, r_shallow = 0;
    const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
    if (!predicted_circle(c + deeper * z, &centre, &r_deep) || r_deep < press->radius_px)
      return false;
    if (predicted_circle(c + shallower * z, &centre, &r_shallow) && r_shallow > press->radius_px)
      return false;
    // 14 halvings of the 0.8-2.5 mm bracket: under 0.2 um, far below a pixel's step in radius.
    for (int it = 0; it < 14; ++it) {
      const double mid = 0.5 * (deeper + shallower);
      double r = 0;
      if (predicted_circle(c + mid * z, &centre, &r) && r > press->radius_px)
        deeper = mid;
      else
        shallower = mid;
    }
    c += 0.5 * (deeper + shallower) * z;
    // The end of the bisection must give the radius (a predicted frame that failed half-way, e.g.
    // split in two, would have steered it to one end).
    double r = 0;
    return predicted_circle(c, &centre, &r) && std::abs(r - press->radius_px) < kRadiusTolerancePx;
  };
  if (!fit_depth()) return;
  // Then the side: the predicted circle's centre onto the found one's, on the gel; then the depth
  // again. Any failure keeps step 1's ball.
  Eigen::Vector2d centre;
  double r = 0;
  if (!predicted_circle(c, &centre, &r)) return;
  const Eigen::Vector3d shift = gel_point(rays, press->centre_px.x(), press->centre_px.y()) -
                                gel_point(rays, centre.x(), centre.y());
  c.head<2>() += shift.head<2>();
  if (!fit_depth()) return;
  press->centre_m = c;
  press->shading_fit = true;
}

// Step 2 and the depth check for a ball placed through its circle.
void place(const ImageU8& color, const ImageU8& reference, const GelRays& rays, double radius_m,
           const GelModel& gel, double blend_blur_px, BallPress* press) {
  if (!press->found) return;
  place_by_shading(color, reference, rays, radius_m, gel, blend_blur_px, press);
  press->found = place_at(rays, press->centre_m, radius_m, gel.max_indentation_m, press);
  if (!press->found && !press->shading_fit) {
    press->reason =
        "placed through the circle alone (the shading did not place it): " + press->reason;
  }
}

}  // namespace

BallPress find_ball_press(const ImageU8& color, const ImageU8& reference, const GelRays& rays,
                          double radius_m, const GelModel& gel, double blend_blur_px) {
  std::vector<Eigen::Vector2d> boundary, at_edge;
  BallPress press;
  if (!change_boundary(color, reference, &boundary, &at_edge, &press)) return press;
  press = fit_press(rays, boundary, at_edge, radius_m);
  place(color, reference, rays, radius_m, gel, blend_blur_px, &press);
  return press;
}

BallPress ball_press_from_circle(const ImageU8& color, const ImageU8& reference,
                                 const GelRays& rays, const Eigen::Vector2d& centre_px,
                                 double radius_px, double radius_m, const GelModel& gel,
                                 double blend_blur_px) {
  std::vector<Eigen::Vector2d> boundary;
  const int n = 90;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * kPi * k / n;
    const Eigen::Vector2d p = centre_px + radius_px * Eigen::Vector2d(std::cos(a), std::sin(a));
    if (p.x() >= 0 && p.y() >= 0 && p.x() <= rays.width - 1 && p.y() <= rays.height - 1) {
      boundary.push_back(p);
    }
  }
  if (int(boundary.size()) < kMinBoundaryPoints) {
    BallPress outside;
    outside.reason = format(
        "the circle (radius %.1f px) lies in the image at fewer than %.0f of 90 points: too "
        "little of it to place the ball",
        radius_px, double(kMinBoundaryPoints));
    return outside;
  }
  BallPress press = fit_press(rays, boundary, {}, radius_m);
  if (!press.found) return press;
  // A circle given where the frame shows no press (a slip of frame or place) would label a ball
  // where there is none.
  int changed = 0;
  for_each_changed_pixel(color, reference, [&](int x, int y) {
    changed += (Eigen::Vector2d(x, y) - centre_px).norm() <= radius_px;
    return changed < kMinPressPixels;
  });
  if (changed < kMinPressPixels) {
    press.found = false;
    press.reason = format(
        "the frame shows no change from the no-contact reference inside the given circle (%.0f "
        "px changed, a press changes at least %.0f): does the frame show that press?",
        changed, kMinPressPixels);
    return press;
  }
  place(color, reference, rays, radius_m, gel, blend_blur_px, &press);
  return press;
}

BallLabels ball_labels(const GelRays& rays, const Eigen::Vector3d& centre_m, double radius_m,
                       const ElasticModel& elastic) {
  BallLabels labels;
  const ImageF rigid = sphere_indentation(rays, centre_m, radius_m);
  labels.depth = elastic_indentation(elastic, rays.px_per_m, rigid);
  labels.normal = gel_normals(rays, labels.depth);
  labels.mask = ImageU8(rays.width, rays.height, 1, 0);
  for (std::size_t i = 0; i < rigid.data.size(); ++i)
    if (rigid.data[i] > 0) labels.mask.data[i] = 255;
  return labels;
}

}  // namespace pg
