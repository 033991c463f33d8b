#pragma once
// Which directions a registration constrains (the paper's stated limitation: flat patches and
// sphere rotations are unobservable), and a Gauss-Newton step that leaves the others alone.
//
// The analysis runs where translations and rotations are comparable: twists are taken about a
// centre c (the source cloud's centroid, in the target frame) and the rotation part is scaled by
// the cloud's extent about each axis, a symmetric matrix Lambda:
//   x = [rho_c; Lambda phi],  exp(delta) = T_c exp([rho_c; phi]) T_c^-1,  T_c = translation by c,
// Lambda = J^(1/2), J = mean over the points r = p - c of |r|^2 I - r r^T, so a unit turn about an
// axis a in x moves the points by their RMS distance from that axis: for a long strip of contact
// the turn about its own axis is scaled by the strip's width, not by its length. A point-to-plane
// term then contributes at most about 1 per direction, and an eigenvalue of the scaled Hessian
// below a ratio of the largest means the data leave that direction free.
#include <Eigen/Core>
#include <vector>

#include "pg/core/se3.h"
#include "pg/tracker/point_cloud.h"

namespace pg {

// At most 6 columns, stored inline (no heap allocation).
using Matrix6Xd = Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::ColMajor, 6, 6>;

// A contact's shape about its centroid: the mean of its normals and the shape operator
// K = dn/dp, the normals fitted as linear in position (exact for a sphere, K = I / R about any
// point, and for a cylinder, (I - a a^T) / r; zero for a plane). The sign of the normals does
// not matter where it is used: n x (K rho) is the same for -n and -K.
struct ContactShape {
  Eigen::Vector3d mean_normal = Eigen::Vector3d::Zero();     // not normalised; zero: unknown
  Eigen::Matrix3d shape_operator = Eigen::Matrix3d::Zero();  // K [1/m]
  // The same shape in a frame rotated by R (points and normals mapped by R).
  ContactShape rotated(const Eigen::Matrix3d& R) const {
    return {R * mean_normal, R * shape_operator * R.transpose()};
  }
};

// The least-squares shape of `points` with `normals` (one per point) about their centroid.
ContactShape fit_contact_shape(const std::vector<Eigen::Vector3f>& points,
                               const std::vector<Eigen::Vector3f>& normals);

struct DegeneracyReport {
  Eigen::Vector3d centre_target = Eigen::Vector3d::Zero();         // c [m]
  Eigen::Matrix3d rotation_scale_m = Eigen::Matrix3d::Identity();  // Lambda [m]
  Vector6d eigenvalues = Vector6d::Zero();  // of the scaled Hessian, ascending [-]
  // Columns, in scaled coordinates [rho_c; Lambda phi].
  Matrix6d eigenvectors = Matrix6d::Identity();
  int unconstrained = 6;            // how many of the first eigenvalues fall below the ratio
  double min_eigenvalue_ratio = 0;  // the ratio they were compared with [-]
  // Three free directions that roll the contact about a centre farther than this are read as a
  // flat face's two slides and spin (unconstrained_twists); 0: never [m].
  double flat_radius_m = 0;
  // The contact's shape in the target frame (ContactShape), when the analysis was given it.
  ContactShape shape;

  bool degenerate() const { return unconstrained > 0; }
  // The unconstrained directions as twists [rho_c; phi] about c ([m; rad]), one per column: a
  // basis of the span of the first `unconstrained` eigenvectors, less the rotation slivers (a
  // constrained rotation the span holds so little of that removing it leaves the direction
  // unconstrained; degeneracy.cpp). Divided by Lambda to become a twist, a sliver grows hundreds of
  // times: an edge's slide would carry 0.3 rad of rotation per metre, which a consumer pinning
  // every other direction holds fixed, reading the slide from that rotation's noise. A rotation
  // the contact's curvature explains is no sliver: a sphere's roll about its far centre carries
  // as little rotation as an edge's sliver (Lambda / R), but dropping it hands on a slide, which
  // the data do see, and leaves the roll's tilt to be pinned at the guess, where the registration
  // left it (a still 30 cm ball then spun away from its prediction, 15 % a frame). So the
  // rotation a free direction's slide predicts by rolling, kappa n x rho_c (the normal curvature
  // kappa along the slide, from `shape`), is kept when it explains all but a tenth of the
  // direction's constrained rotation and the directions then fit the data at least twice as
  // well; without a shape, every sliver is removed as before.
  // With flat_radius_m set, three free directions whose tilt (rotation across the contact's mean
  // normal) is less than their slide along the contact over flat_radius_m lose that tilt: they
  // are then the two slides and the spin of a flat face. Learned normals bend a flat face into a
  // dome of several centimetres' radius, whose rolls turn every frame's tilt error into a slide
  // (an option for them: a real ball that large has such rolls).
  Matrix6Xd unconstrained_twists() const;
  // The same directions as twists [rho; phi] about the target frame's origin.
  Matrix6Xd unconstrained_twists_at_origin() const;
};

// Eigen-decomposes H_scaled (the Hessian in [rho_c; Lambda phi]); eigenvalues below
// min_eigenvalue_ratio times the largest (or not positive) are unconstrained. flat_radius_m: see
// DegeneracyReport.
DegeneracyReport analyse_degeneracy(const Matrix6d& H_scaled, const Eigen::Vector3d& centre_target,
                                    const Eigen::Matrix3d& rotation_scale_m,
                                    double min_eigenvalue_ratio, const ContactShape& shape = {},
                                    double flat_radius_m = 0);

// What a registration of `cloud` could constrain at best: the degeneracy of its point-to-plane
// Hessian at perfect alignment with itself (each point's residual along its own normal), about
// its centroid and scaled as above. A plane leaves 3 directions free (two slides and the turn
// about its normal), a sphere cap 3 (the rotations), a cylinder 2 (the slide along it and the turn
// about it), a corner of three faces none. Fewer than one point: all 6 free.
DegeneracyReport analyse_cloud_degeneracy(const PointCloud& cloud, double min_eigenvalue_ratio);

// Lambda for points about their centroid c (degeneracy.h's header comment), each principal extent
// floored at 1e-3 of the largest (and 1e-9 m) so that a line of points stays invertible.
Eigen::Matrix3d rotation_scale(const Eigen::Matrix3d& mean_outer_product_about_c);

// The Gauss-Newton step for H_scaled x = -g_scaled restricted to the constrained eigenvectors,
// returned as a twist [rho_c; phi] about c. The data say nothing about the unconstrained
// directions N (unconstrained_twists, slivers removed), so every step + N a fits them equally
// well; of those, the one with the least rotation (and then the least translation of c) is
// returned, so that a sphere keeps its initial orientation and a flat patch its initial in-plane
// position and yaw. With the slivers left in, an edge's slide would cancel the measured turn
// about the edge: 20 mrad of turn traded for 2.4 mm of slide in one step.
Vector6d constrained_step(const DegeneracyReport& report, const Vector6d& g_scaled);

// How many dimensions the spans of `twists` have in common, each a basis of the directions one
// registration left free (unconstrained_twists_at_origin) about the same frame's origin: what
// none of them constrains (several sensors on one object). Rotations are weighed at 1 cm (a
// fingertip contact's size), so that a turn and a slide compare where they move the contact
// alike; spans within about 3 degrees of each other count as common. 6 for no twists.
int common_unconstrained_directions(const std::vector<Matrix6Xd>& twists);

}  // namespace pg
