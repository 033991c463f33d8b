// The local patch's fusion: a per-voxel mean on a grid fixed in the object frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <vector>

#include "pg/graph/patch_map.h"

namespace pg {
namespace {

// A flat square of points at height z, `n` x `n` samples `step` apart from (x0, y0).
PointCloud square(double x0, double y0, double z, int n, double step) {
  PointCloud c;
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < n; ++j) {
      c.push_back(Eigen::Vector3f(float(x0 + i * step), float(y0 + j * step), float(z)),
                  Eigen::Vector3f::UnitZ());
    }
  }
  return c;
}

// Distance from p to the patch's nearest fused point (its k-d tree's answer) [m].
double distance_to_patch(const PatchMap& patch, const Eigen::Vector3f& p) {
  float distance_sq = 0;
  EXPECT_GE(patch.tree().nearest(p, 1e-3f, &distance_sq), 0) << "nothing within 1 mm";
  return std::sqrt(double(distance_sq));
}

// GroundtruthPatch's model is shared, not copied: the patches of every sensor (and run) given one
// model hold its tree itself; a reset patch lets it go.
// What the patch cannot fuse is refused with the reason: a cloud without a normal a point (it
// had crashed), a NaN point or pose (fused, it had sent the tree's searches astray); and an empty
// patch has no tree to give (it had dereferenced a null pointer).
TEST(PatchMap, AKeyFrameItCannotFuseIsRefused) {
  PatchMap patch;
  EXPECT_THROW(patch.tree(), std::logic_error);
  PointCloud no_normals = square(0, 0, 0, 5, 1e-4);
  no_normals.normals.clear();
  EXPECT_THROW(patch.add_keyframe(no_normals, SE3()), std::invalid_argument);
  PointCloud few_normals = square(0, 0, 0, 5, 1e-4);
  few_normals.normals.resize(3);
  EXPECT_THROW(patch.add_keyframe(few_normals, SE3()), std::invalid_argument);
  PointCloud nan_point = square(0, 0, 0, 5, 1e-4);
  nan_point.points[4].x() = NAN;
  EXPECT_THROW(patch.add_keyframe(nan_point, SE3()), std::invalid_argument);
  EXPECT_THROW(patch.add_keyframe(square(0, 0, 0, 5, 1e-4),
                                  SE3(Eigen::Quaterniond(0, 0, 0, 0), Eigen::Vector3d::Zero())),
               std::invalid_argument);
  EXPECT_TRUE(patch.empty());
  const int k = patch.add_keyframe(square(0, 0, 0, 5, 1e-4), SE3(), true);
  EXPECT_GT(patch.tree().size(), 0u);
  EXPECT_THROW(patch.move_keyframe(k, SE3::Translation({NAN, 0, 0})), std::invalid_argument);
  patch.move_keyframe(k, SE3::Translation({1e-3, 0, 0}));  // still movable after the refusal
}

TEST(PatchMap, AModelIsSharedNotCopied) {
  const auto model = std::make_shared<const PointCloudTree>(square(0, 0, 0, 20, 1e-4));
  PatchMap a, b;
  a.set_model(model);
  b.set_model(a.model());
  for (const PatchMap* patch : {&a, &b}) {
    EXPECT_FALSE(patch->empty());
    EXPECT_EQ(&patch->tree(), model.get());
    EXPECT_EQ(&patch->cloud_object(), &model->cloud());
    EXPECT_NEAR(distance_to_patch(*patch, Eigen::Vector3f(5e-4f, 5e-4f, 2e-5f)), 2e-5, 1e-9);
  }
  a.reset();
  EXPECT_TRUE(a.empty());
  EXPECT_EQ(a.model(), nullptr);
  EXPECT_TRUE(a.cloud_object().empty());
  EXPECT_GT(model.use_count(), 1);  // b's
  b.reset();
  EXPECT_EQ(model.use_count(), 1);
  EXPECT_THROW(a.set_model(nullptr), std::invalid_argument);
}

// Distance from p to the cloud's nearest point, by brute force [m].
double distance_to(const PointCloud& cloud, const Eigen::Vector3f& p) {
  double best = INFINITY;
  for (const Eigen::Vector3f& q : cloud.points) best = std::fmin(best, double((q - p).norm()));
  return best;
}

// GroundtruthPatch's patch.ply is the part of its model that its key frames touched: every model
// point within a cell's edge of a touched point, none farther than two cells' diagonal, not the
// whole sampled surface.
TEST(PatchMap, AModelExportsThePartThatWasTouched) {
  const PointCloud surface = square(0, 0, 0, 100, 1e-4);  // 10 x 10 mm
  const auto model = std::make_shared<const PointCloudTree>(surface);
  PatchMap patch;
  EXPECT_THROW(patch.mark_touched(surface, SE3()), std::logic_error) << "no model";
  patch.set_model(model);
  EXPECT_TRUE(patch.exported().empty()) << "nothing touched yet";

  const PointCloud contact = square(-5e-4, -5e-4, 0, 11, 1e-4);  // 1 x 1 mm about the sensor
  const SE3 T_object_sensor(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                            Eigen::Vector3d(3e-3, 4e-3, 0));
  patch.mark_touched(contact, T_object_sensor);
  const PointCloud touched = transform_cloud(T_object_sensor, contact);
  const PointCloud part = patch.exported();
  ASSERT_FALSE(part.empty());
  EXPECT_LT(part.size(), surface.size() / 20);
  const double cell = PatchMap::kTouchedCellM;
  for (std::size_t i = 0; i < part.size(); ++i) {
    EXPECT_LT(distance_to(touched, part.points[i]), 2 * std::sqrt(3.0) * cell);
    EXPECT_EQ(distance_to(surface, part.points[i]), 0.0) << "a model point, as it is";
    EXPECT_EQ(part.normals[i], Eigen::Vector3f::UnitZ());
  }
  std::size_t near = 0;
  for (const Eigen::Vector3f& p : surface.points) {
    if (distance_to(touched, p) > cell) continue;
    ++near;
    EXPECT_EQ(distance_to(part, p), 0.0) << "a model point near the touch left out";
  }
  EXPECT_GT(near, 100u);

  // Marks add up: the same touch again adds nothing, one elsewhere adds its part.
  patch.mark_touched(contact, T_object_sensor);
  EXPECT_EQ(patch.exported().size(), part.size());
  patch.mark_touched(contact, SE3::Translation({7e-3, 7e-3, 0}));
  EXPECT_GT(patch.exported().size(), part.size() + part.size() / 2);
  // A new model starts with none; a patch of key frames exports what it fused.
  patch.set_model(model);
  EXPECT_TRUE(patch.exported().empty());
  PatchMap fused;
  fused.add_keyframe(contact, T_object_sensor);
  EXPECT_EQ(fused.exported().points, fused.cloud_object().points);
}

TEST(PatchMap, EachVoxelHoldsTheMeanOfEveryKeyFrame) {
  // Three key frames of one surface at heights 0, 30 and 30 um, in and out of order: every
  // voxel's point is at their mean, 20 um, however many key frames came before. (Re-voxelising
  // the fused points with each key frame gave the newest one half the weight: 22.5 or 15 um.)
  const PatchMapOptions options{10, 1e-4};
  const double step = 1e-4, x0 = 0.5e-4;  // one sample per voxel, at its centre
  for (const auto& heights : {std::array{0.0, 30e-6, 30e-6}, std::array{30e-6, 30e-6, 0.0}}) {
    PatchMap patch(options);
    for (double z : heights) patch.add_keyframe(square(x0, x0, z, 10, step), SE3());
    ASSERT_EQ(patch.keyframes(), 3);
    ASSERT_EQ(patch.cloud_object().size(), 100u);
    for (const auto& p : patch.cloud_object().points) EXPECT_NEAR(p.z(), 20e-6, 1e-9);
  }
}

TEST(PatchMap, TheGridStaysFixedAsThePatchGrows) {
  // Samples 50 um apart, two by two to a 0.1 mm voxel: the fused points are the means of four.
  // The same surface again, with a few points far to the side, adds four samples to each of
  // those voxels, so their means stay where they were. (The old grid, placed at the cloud's
  // corner, moved by 0.3 of a voxel with those points and re-paired every sample.)
  const PatchMapOptions options{10, 1e-4};
  const PointCloud surface = square(2.5e-5, 2.5e-5, 5e-5, 8, 5e-5);
  PatchMap patch(options);
  patch.add_keyframe(surface, SE3());
  const PointCloud before = patch.cloud_object();
  ASSERT_EQ(before.size(), 16u);
  PointCloud again = surface;
  const PointCloud far = square(-3.03e-3, -2.07e-3, 1.05e-3, 3, 5e-5);  // 2 x 2 voxels
  again.points.insert(again.points.end(), far.points.begin(), far.points.end());
  again.normals.insert(again.normals.end(), far.normals.begin(), far.normals.end());
  patch.add_keyframe(again, SE3());
  EXPECT_EQ(patch.cloud_object().size(), before.size() + 4u);
  for (const auto& p : before.points) EXPECT_LT(distance_to_patch(patch, p), 1e-9);
}

TEST(PatchMap, KeyFramesAreFusedInTheObjectFrame) {
  // One surface seen from two sensor poses: in the object frame the samples coincide, so the
  // patch is the surface once, not twice.
  const SE3 a(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(1e-3, -2e-3, 5e-3));
  const SE3 b = a * SE3::Translation({2e-4, 1e-4, 0});
  const PointCloud surface_object = square(0.5e-4, 0.5e-4, 0.5e-4, 10, 1e-4);
  PatchMap patch(PatchMapOptions{10, 1e-4});
  for (const SE3& T_object_sensor : {a, b}) {
    patch.add_keyframe(transform_cloud(T_object_sensor.inverse(), surface_object), T_object_sensor);
  }
  ASSERT_EQ(patch.cloud_object().size(), surface_object.size());
  for (const auto& p : surface_object.points) EXPECT_LT(distance_to_patch(patch, p), 1e-8);
  patch.reset();
  EXPECT_TRUE(patch.empty());
  patch.add_keyframe(surface_object, SE3());
  EXPECT_EQ(patch.keyframes(), 1);
}

// The fused points of two patches, each with its normal, are the same within `tol`, in
// whichever order (a point without a voxel of its own is numbered in the order it came).
void expect_same_patch(const PatchMap& a, const PatchMap& b, double tol) {
  const auto sorted = [](const PointCloud& c) {
    std::vector<std::array<float, 6>> v;
    for (std::size_t i = 0; i < c.size(); ++i) {
      const auto& p = c.points[i];
      const auto& n = c.normals[i];
      v.push_back({p.x(), p.y(), p.z(), n.x(), n.y(), n.z()});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  const auto va = sorted(a.cloud_object()), vb = sorted(b.cloud_object());
  ASSERT_EQ(va.size(), vb.size());
  for (std::size_t i = 0; i < va.size(); ++i) {
    for (int k = 0; k < 6; ++k) EXPECT_NEAR(va[i][k], vb[i][k], k < 3 ? tol : 1e-6) << i;
  }
}

TEST(PatchMap, AMovedKeyFrameIsAsIfFusedThereInTheFirstPlace) {
  // Key frame 0 fused at a pose 50 um and 20 mrad off, key frame 1 at its own; then key frame 0
  // moved to its true pose: the patch is the one fused at the true poses, voxel for voxel, for
  // a grid (half its voxels shared by both key frames) and for voxel_m 0 (every point its own).
  const PointCloud surface = square(0.25e-4, 0.25e-4, 0.5e-4, 20, 0.5e-4);
  const SE3 truth = SE3::Translation({1e-4, -2e-4, 0});
  const SE3 off(Eigen::Quaterniond(Eigen::AngleAxisd(0.02, Eigen::Vector3d::UnitX())),
                Eigen::Vector3d(1.5e-4, -2e-4, 0));
  const PointCloud second = square(0.5e-3, 0.25e-4, 0.5e-4, 20, 0.5e-4);
  for (double voxel_m : {1e-4, 0.0}) {
    SCOPED_TRACE(voxel_m);
    const PatchMapOptions options{10, voxel_m};
    PatchMap moved(options), reference(options);
    ASSERT_EQ(moved.add_keyframe(surface, off, true), 0);
    ASSERT_EQ(moved.add_keyframe(second, SE3()), 1);
    const std::size_t before = moved.cloud_object().size();
    moved.move_keyframe(0, truth);
    reference.add_keyframe(surface, truth);
    reference.add_keyframe(second, SE3());
    EXPECT_EQ(moved.keyframes(), 2);
    // The off pose put key frame 0's points in other voxels than the true one does.
    if (voxel_m > 0) {
      EXPECT_NE(before, moved.cloud_object().size());
    }
    expect_same_patch(moved, reference, 1e-12);
    EXPECT_EQ(moved.tree().size(), reference.tree().size());
  }
}

TEST(PatchMap, OnlyAMovableKeyFrameMovesAndOnlyOnce) {
  const PointCloud surface = square(0.5e-4, 0.5e-4, 0.5e-4, 5, 1e-4);
  PatchMap patch;
  patch.add_keyframe(surface, SE3());                            // 0: not movable
  const int movable = patch.add_keyframe(surface, SE3(), true);  // 1
  EXPECT_THROW(patch.move_keyframe(0, SE3()), std::invalid_argument);
  EXPECT_THROW(patch.move_keyframe(7, SE3()), std::invalid_argument);
  patch.move_keyframe(movable, SE3::Translation({1e-3, 0, 0}));
  EXPECT_EQ(patch.cloud_object().size(), 2 * surface.size());
  EXPECT_THROW(patch.move_keyframe(movable, SE3()), std::invalid_argument);
  patch.reset();
  patch.add_keyframe(surface, SE3(), true);
  patch.reset();  // forgets what it could move
  EXPECT_THROW(patch.move_keyframe(0, SE3()), std::invalid_argument);
}

}  // namespace
}  // namespace pg
