#pragma once
// Training labels for a real sensor from presses of a ball of known radius (the paper's section
// IV-A, after GelSight's calibration): the ball's contact is a circle in the colour image, and
// from the circle, the ball's radius and the sensor's geometry the gel's shape under it follows,
// so its normal image can be synthesised where no renderer knows the truth. Torch-free.
#include <Eigen/Core>
#include <string>

#include "pg/core/gel_rays.h"
#include "pg/core/image.h"

namespace pg {

// Fewer changed pixels than this are no press (the tracker's smallest contact at 120x160).
constexpr int kMinPressPixels = 20;

struct BallPress {
  bool found = false;
  std::string reason;  // why no press was found (when !found)
  // Not found because the frame shows no change: fewer pixels differ from the reference than a
  // press changes (a frame without contact, as the tracker takes it).
  bool no_change = false;
  Eigen::Vector2d centre_px = Eigen::Vector2d::Zero();  // the contact circle in the image [px]
  double radius_px = 0;
  Eigen::Vector3d centre_m = Eigen::Vector3d::Zero();  // the ball's centre in S [m]
  double depth_m = 0;                                  // deepest indentation of the gel [m]
  // The circle's boundary points off the ball placed through them (step 1 below, found ones;
  // not the ball placed by the shading) [px], and how many that fit used.
  double rms_px = 0;
  int boundary_points = 0;
  // Placed by the shading (below): the ball whose press the gel model and the frame's own
  // colour response show as this circle. False: the ball through the circle on the undeformed gel.
  bool shading_fit = false;
};

// Finds the press of a ball of `radius_m` in a colour frame: the largest connected region that
// differs from the no-contact `reference` beyond the camera's noise (pg/core/image_change.h),
// holes filled; its boundary, a circle. Then the ball is placed in two steps:
//  1. through the circle: its boundary's points on the undeformed gel, and the ball's centre (on
//     the object's side of the gel) that puts them all at `radius_m`. Exact for a rigid gel and
//     a sharp change, but the visible change reaches past the contact: by the camera's noise
//     threshold, and on an elastic gel by the sink-in around it (the ball then sits too deep);
//  2. by the shading: the frame's colour change against the tilt of the gel's normal, per
//     channel (a linear model fitted to the press's middle, where the gel takes the ball's shape
//     and the tilt follows from the circle alone), predicts the frame the gel (`gel`: rigid, or
//     its elastic model) would show for a ball at any place; the ball is moved until the circle
//     found in that predicted frame is the one found in the real one (its depth by bisection on
//     the radius, then its side position by the centres, then its depth again). Step 1's ball is
//     kept (shading_fit false) when the middle has too few pixels for the model, the model is
//     not finite, or no depth gives the circle's radius.
// Not found (with the reason) when nothing changed, the region is too small or not a circle, or
// the ball would be wider than its radius allows or, once placed, deeper than the gel takes
// (gel.max_indentation_m); also when a second region is a tenth of the press or more (two
// contacts; three or more: the lighting or the camera), most of the image changed (a dropout,
// the lighting), less than half of the circle lies in the image, or the press reaches the
// image's edge outside the circle fitted to its arc (its centre beyond the edge).
// `blend_blur_px`: a render blended onto a real background (TACTO's blend) shows the change
// blurred by a Gaussian of this sigma [px] (shading.background_blur_m times the image scale);
// step 2's predicted frame is then blurred by it too. 0 for frames without a known blur.
BallPress find_ball_press(const ImageU8& color, const ImageU8& reference, const GelRays& rays,
                          double radius_m, const GelModel& gel, double blend_blur_px = 0.0);
// The same from a circle given by hand (image pixels, as BallPress::centre_px and radius_px):
// the edge of the visible change, as the search finds it.
BallPress ball_press_from_circle(const ImageU8& color, const ImageU8& reference,
                                 const GelRays& rays, const Eigen::Vector2d& centre_px,
                                 double radius_px, double radius_m, const GelModel& gel,
                                 double blend_blur_px = 0.0);

// What the renderer would write for the ball at `centre_m` pressed into the gel (`elastic`, as
// the renderer deforms it; rigid when off): the indentation (depth image), its normals (central
// differences, as a rendered frame's) and the contact mask (0/255, the pixels the ball itself
// indents, as the renderer's mask).
struct BallLabels {
  ImageF normal, depth;
  ImageU8 mask;
};
BallLabels ball_labels(const GelRays& rays, const Eigen::Vector3d& centre_m, double radius_m,
                       const ElasticModel& elastic);

}  // namespace pg
