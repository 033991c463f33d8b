// Stress: bad data. A dataset on disk with non-finite poses, duplicated or missing frames, a
// corrupted image or one of the wrong size must fail with an InputError that names the file;
// bad values inside the tracker's inputs (non-finite pixels, poses or points, as a live sensor
// could deliver) must not poison the estimate.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "../common/test_support.h"
#include "pg/core/json_fields.h"
#include "pg/graph/track_dataset.h"
#include "pg/sim/scene_renderer.h"
#include "stress_support.h"

namespace pg::stress {
namespace {

namespace fs = std::filesystem;
using testing_support::expect_input_error;
using testing_support::TempDir;

// The default scene's first 30 frames, normals only, rendered once for the suite; each test
// works on its own copy.
class StressData : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    source_ = fs::temp_directory_path() / ("pg_stress_data_" + std::to_string(::getpid()));
    fs::remove_all(source_);
    nlohmann::json scene = parse_json_file(std::string(PG_SOURCE_DIR) + "/scenes/default.json");
    scene["frames"] = 30;
    scene["render"]["outputs"] = {"normal"};
    const SceneRenderer renderer(
        scene_from_json(scene, "stress scene", std::string(PG_SOURCE_DIR) + "/scenes"));
    render_scene_to_dataset(renderer, source_.string());
  }
  static void TearDownTestSuite() { fs::remove_all(source_); }

  // A fresh copy of the dataset in the test's temporary folder.
  std::string copy() {
    const fs::path dir = tmp_.path / "data";
    fs::copy(source_, dir, fs::copy_options::recursive);
    return dir.string();
  }
  static std::vector<std::string> lines(const std::string& path) {
    std::ifstream in(path);
    std::vector<std::string> out;
    for (std::string line; std::getline(in, line);) out.push_back(line);
    return out;
  }
  static void write_lines(const std::string& path, const std::vector<std::string>& lines) {
    std::ofstream out(path);
    for (const auto& l : lines) out << l << "\n";
  }

  TempDir tmp_;
  static fs::path source_;
};
fs::path StressData::source_;

TEST_F(StressData, IntactCopyTracks) {
  const Dataset d = Dataset::open(copy());
  const TrackRun run = track_dataset(d, TrackOptions());
  EXPECT_LT(run.summary.final_translation_error_m, 1e-3);
}

TEST_F(StressData, NonFinitePoseIsRejectedWithTheRow) {
  for (const char* bad : {"nan", "inf", "-inf"}) {
    SCOPED_TRACE(bad);
    fs::remove_all(tmp_.path / "data");
    const std::string dir = copy();
    auto rows = lines(dir + "/poses.csv");
    std::vector<std::string> cells = testing_support::split_csv_line(rows[6]);  // frame 5
    cells[3] = bad;                                                             // obj_y
    std::string joined;
    for (const auto& c : cells) joined += (joined.empty() ? "" : ",") + c;
    rows[6] = joined;
    write_lines(dir + "/poses.csv", rows);
    expect_input_error([&] { Dataset::open(dir); }, {"poses.csv", "line 7", "non-finite"});
  }
}

TEST_F(StressData, DuplicatedOrMissingFrameRowsAreRejected) {
  const std::string dir = copy();
  auto rows = lines(dir + "/poses.csv");
  auto duplicated = rows;
  duplicated.insert(duplicated.begin() + 11, rows[10]);  // frame 9 twice
  write_lines(dir + "/poses.csv", duplicated);
  expect_input_error([&] { Dataset::open(dir); }, {"poses.csv", "line 12", "expected frame 10"});
  auto missing = rows;
  missing.erase(missing.begin() + 11);  // no frame 10
  write_lines(dir + "/poses.csv", missing);
  expect_input_error([&] { Dataset::open(dir); }, {"poses.csv", "line 12", "expected frame 10"});
  auto short_file = rows;
  short_file.pop_back();  // the last frame's row lost
  write_lines(dir + "/poses.csv", short_file);
  expect_input_error([&] { Dataset::open(dir); }, {"poses.csv", "29 frames"});
}

TEST_F(StressData, MissingImageIsNamed) {
  const std::string dir = copy();
  fs::remove(dataset_frame_path(dir, "normal", 7));
  expect_input_error([&] { Dataset::open(dir); }, {"normal/000007.exr", "missing frame file"});
  fs::create_directory(dataset_frame_path(dir, "normal", 7));  // a folder in its place
  expect_input_error([&] { Dataset::open(dir); },
                     {"normal/000007.exr", "not a file (a frame file is expected here)"});
}

TEST_F(StressData, CorruptedImageIsNamedWhenTracking) {
  const std::string dir = copy();
  const std::string victim = dataset_frame_path(dir, "normal", 10);
  fs::resize_file(victim, fs::file_size(victim) / 3);  // truncated mid-file
  const Dataset d = Dataset::open(dir);                // the files exist
  expect_input_error([&] { track_dataset(d, TrackOptions()); }, {"normal/000010.exr"});
  std::ofstream(victim, std::ios::binary | std::ios::trunc) << "not an image at all";
  expect_input_error([&] { track_dataset(d, TrackOptions()); }, {"normal/000010.exr"});
}

TEST_F(StressData, WrongSizeFrameIsNamedWhenTracking) {
  const std::string dir = copy();
  write_image(dataset_frame_path(dir, "normal", 3), ImageF(60, 80, 3, 0.5f));
  const Dataset d = Dataset::open(dir);
  expect_input_error([&] { track_dataset(d, TrackOptions()); },
                     {"normal/000003.exr", "60x80", "120x160"});
}

// Non-finite, zero and reversed normals inside the contact (a corrupted frame from a network or
// a camera): those pixels are rejected and counted; the tracker keeps going.
TEST(StressDataInMemory, NonFinitePixelsInTheNormals) {
  const ClosedLoop& loop = cube_loop();
  StressHooks hooks;
  hooks.corrupt_normals = [](int frame, ImageF& n) {
    if (frame < 20 || frame >= 40) return;
    const float bad[][3] = {{NAN, NAN, NAN}, {INFINITY, 0, 1}, {0, 0, 0}, {0, 0, -1}};
    for (int y = 60; y < 100; ++y) {
      for (int x = 40; x < 80; x += 2) {
        for (int k = 0; k < 3; ++k) n.at(x, y, k) = bad[(x / 2 + y + frame) % 4][k];
      }
    }
  };
  const StressRun run = loop.track(cube_rocking(60), {}, hooks);
  run.print("NonFinitePixelsInTheNormals");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_GT(run.frames[25].rejected_normals, 0);
  std::printf("max error %.3f mm\n", run.max_translation_error_m() * 1e3);
  EXPECT_LT(run.max_translation_error_m(), 1e-3);
}

// A whole frame of NaN normals: unreadable, so the frame is predicted and flagged, and the
// contact episode goes on through it (no new episode, no new vision prior, the patch kept).
TEST(StressDataInMemory, WholeFrameOfNaN) {
  const ClosedLoop& loop = cube_loop();
  StressHooks hooks;
  hooks.corrupt_normals = [](int frame, ImageF& n) {
    if (frame == 30) std::fill(n.data.begin(), n.data.end(), NAN);
  };
  const StressRun run = loop.track(cube_rocking(60), {}, hooks);
  run.print("WholeFrameOfNaN");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_FALSE(run.frames[30].estimate.contact);
  EXPECT_TRUE(run.frames[30].estimate.invalid_input);
  EXPECT_TRUE(run.frames[29].estimate.contact && run.frames[31].estimate.contact);
  EXPECT_FALSE(run.frames[31].estimate.new_episode);
  EXPECT_TRUE(run.frames[31].estimate.image_to_patch) << "registered against the kept patch";
  EXPECT_LT(run.last().translation_error_m, 1e-3);
}

// Non-finite sensor poses (and zero quaternions), vision priors and cloud points handed to the
// tracker directly (the
// dataset reader rejects them; a live pipeline might not): skipped and reported, never
// propagated into the estimate.
TEST(StressDataInMemory, NonFiniteTrackerInputs) {
  const ClosedLoop& loop = cube_loop();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<SE3> poses = cube_rocking(90);
  for (int f = 50; f < 60; ++f) poses[f] = shifted(poses[f], {0, 0, 0.003});  // a gap
  StressHooks hooks;
  hooks.corrupt_input = [&](int frame, TrackerInput& in) {
    if (frame >= 20 && frame < 23) in.T_world_sensor_measured = SE3::Translation({nan, 0, 0});
    if (frame == 60) in.T_world_object_prior = SE3::Translation({0, nan, 0});
    // A zero quaternion, ROS's unset pose: finite, yet no rotation (it had been taken, and the
    // estimate's quaternion was zero from there to the next episode).
    if (frame == 25 || frame == 26) {
      in.T_world_sensor_measured = SE3(Eigen::Quaterniond(0, 0, 0, 0), Eigen::Vector3d::Zero());
    }
    if (frame >= 30 && frame < 33 && !in.cloud_sensor.empty()) {
      for (std::size_t i = 0; i < in.cloud_sensor.size(); i += 7)
        in.cloud_sensor.points[i].x() = NAN;
      in.cloud_sensor.normals[1].y() = INFINITY;
    }
  };
  const StressRun run = loop.track(poses, {}, hooks);
  run.print("NonFiniteTrackerInputs");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  for (int f : {20, 21, 22, 25, 26, 30, 60}) EXPECT_TRUE(run.frames[f].estimate.invalid_input) << f;
  EXPECT_FALSE(run.frames[27].estimate.invalid_input);
  EXPECT_LT(run.frames[45].translation_error_m, 1e-3);
  // The episode at frame 60 starts from the prediction instead of a prior: off by what the
  // object moved while out of contact, but tracked from there.
  EXPECT_TRUE(run.frames[60].estimate.new_episode);
  std::printf("episode without a prior: error %.3f mm at its start, %.3f mm at the end\n",
              run.frames[60].translation_error_m * 1e3, run.last().translation_error_m * 1e3);
  EXPECT_LT(run.last().translation_error_m, 5e-3);
}

// A second sensor's bad inputs (several sensors on one object): a second sensor seeing what the
// first sees, whose pose is NaN for three frames, whose cloud has NaN points for three, whose
// images are missing for five and which lets go for ten. Each is reported and left out; the first
// sensor holds the object throughout (one episode) and the track stays as good as it was.
TEST(StressDataInMemory, ASecondSensorsBadInputsLeaveTheTrackAlone) {
  const ClosedLoop& loop = cube_loop();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  StressHooks hooks;
  hooks.corrupt_input = [&](int frame, TrackerInput& in) {
    SensorInput second = in;  // the first sensor's part
    if (frame >= 20 && frame < 23) second.T_world_sensor_measured = SE3::Translation({nan, 0, 0});
    if (frame >= 30 && frame < 33 && !second.cloud_sensor.empty()) {
      for (std::size_t i = 0; i < second.cloud_sensor.size(); i += 5) {
        second.cloud_sensor.points[i].z() = NAN;
      }
    }
    if (frame >= 40 && frame < 45) second.measurement_missing = true;
    if (frame >= 60 && frame < 70) second.cloud_sensor.clear();
    in.other_sensors = {second};
  };
  const std::vector<SE3> poses = cube_rocking(90);
  const StressRun alone = loop.track(poses, {}, {});
  const StressRun run = loop.track(poses, {}, hooks);
  run.print("ASecondSensorsBadInputs");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_EQ(run.episodes, 1);
  EXPECT_EQ(run.lost_frames, 0);
  for (int f : {20, 22, 30, 32, 40, 44}) EXPECT_TRUE(run.frames[f].estimate.invalid_input) << f;
  for (int f : {10, 25, 35, 50, 65}) EXPECT_FALSE(run.frames[f].estimate.invalid_input) << f;
  EXPECT_EQ(run.frames[65].estimate.contact_sensors, 1);
  EXPECT_EQ(run.frames[75].estimate.contact_sensors, 2);
  EXPECT_LT(run.max_translation_error_m(), 2 * alone.max_translation_error_m() + 1e-4);
  EXPECT_LT(run.last().translation_error_m, 1e-3);
  EXPECT_LT(run.last().rotation_error_rad, 0.02);
}

// No vision prior at all (non-finite at the first frame): the tracker starts from the identity,
// reports it, and tracks the motion relative to that start without diverging.
TEST(StressDataInMemory, NoVisionPriorAtTheStart) {
  const ClosedLoop& loop = cube_loop();
  StressHooks hooks;
  hooks.corrupt_input = [&](int frame, TrackerInput& in) {
    if (frame == 0) in.T_world_object_prior = SE3(in.T_world_object_prior.rotation(), {NAN, 0, 0});
  };
  const std::vector<SE3> poses = cube_rocking(60);
  const StressRun run = loop.track(poses, {}, hooks);
  run.print("NoVisionPriorAtTheStart");
  ASSERT_TRUE(run.all_finite) << "frame " << run.first_non_finite;
  EXPECT_TRUE(run.frames[0].estimate.invalid_input);
  // The motion is still tracked: registrations constrain o_t^-1 e_t, so o_t = truth_t X with a
  // fixed offset X, and the world-frame motion since frame 0, o_t o_0^-1, matches the truth's.
  for (const auto& f : run.frames) {
    const SE3 moved = f.estimate.T_world_object * run.frames[0].estimate.T_world_object.inverse();
    const SE3 truth = f.T_world_object_gt * poses[0].inverse();
    EXPECT_LT(rotation_distance(moved, truth), 0.05);
    EXPECT_LT(translation_distance(moved, truth), 1e-3);
  }
}

}  // namespace
}  // namespace pg::stress
