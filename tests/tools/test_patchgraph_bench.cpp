// `patchgraph bench --quick`: the run-time-vs-error sweep's smoke test (docs/benchmarks.md).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <tuple>

#include "../common/test_support.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using testing_support::TempDir;

using testing_support::split_csv_line;

// The cache knew a render by its scene file's name only: a second scene of that name (or the
// scene edited) was benchmarked on the first one's render.
TEST(PatchgraphBench, TwoScenesOfOneNameGetTheirOwnRenders) {
  TempDir tmp;
  const std::string meshes = std::string(PG_SOURCE_DIR) + "/meshes/";
  for (const auto& [folder, object, z] :
       {std::tuple<const char*, const char*, double>{"a", "sphere_r6mm", 0.005},
        {"b", "cube", 0.0095}}) {
    fs::create_directories(tmp.path / folder);
    std::ofstream(tmp.path / folder / "s.json")
        << R"({"frames": 4, "sensors": [{}], "objects": [{"name": ")" << object << R"(", "mesh": ")"
        << meshes << object << R"(.glb", "pose": {"position": [0, 0, )" << z << "]}}]}";
  }
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench --quick -q --no-plot --scenes " + tmp.str("a/s.json") + " " +
                           tmp.str("b/s.json") + " --out " + tmp.str("b"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream runs(tmp.str("b/runs.csv"));
  std::string line;
  std::getline(runs, line);
  std::map<std::string, int> objects;
  while (std::getline(runs, line)) ++objects[split_csv_line(line).at(2)];
  EXPECT_EQ(objects.size(), 2u) << "objects tracked: one per scene";
  EXPECT_EQ(objects["sphere_r6mm"], objects["cube"]);
}

TEST(PatchgraphBench, QuickSweepWritesTableCsvAndPlot) {
  TempDir tmp;
  const auto r =
      testing_support::run_command(PATCHGRAPH_PATH, "bench --quick -q --out " + tmp.str("b"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("| setting | median update [ms]"), std::string::npos) << r.out;

  std::ifstream csv(tmp.str("b/bench.csv"));
  std::string line;
  ASSERT_TRUE(std::getline(csv, line));
  const std::vector<std::string> header = split_csv_line(line);
  std::map<std::string, std::size_t> column;
  for (std::size_t i = 0; i < header.size(); ++i) column[header[i]] = i;
  for (const char* c : {"setting", "runs", "median_frame_ms", "median_final_translation_m",
                        "median_final_rotation_rad", "pareto_translation", "pareto_rotation",
                        "icp_symmetric", "depth_integration", "image_to_image_gate"}) {
    ASSERT_TRUE(column.count(c)) << c;
  }
  std::vector<std::string> settings;
  struct Point {
    double ms, t, r;
    bool front_t, front_r;
  };
  std::vector<Point> points;
  int on_front = 0;
  while (std::getline(csv, line)) {
    const std::vector<std::string> cells = split_csv_line(line);
    ASSERT_EQ(cells.size(), header.size()) << line;
    settings.push_back(cells[column["setting"]]);
    EXPECT_EQ(cells[column["runs"]], "2") << line;
    EXPECT_EQ(cells[column["icp_symmetric"]], "1") << line;  // ground-truth normals throughout
    EXPECT_EQ(cells[column["depth_integration"]], "parity") << line;  // the quick sweep: default
    EXPECT_EQ(cells[column["image_to_image_gate"]], "1") << line;
    for (const char* c :
         {"median_frame_ms", "median_final_translation_m", "median_final_rotation_rad"}) {
      const double v = std::stod(cells[column[c]]);
      EXPECT_TRUE(std::isfinite(v) && v >= 0) << c << " in " << line;
    }
    EXPECT_GT(std::stod(cells[column["median_frame_ms"]]), 0.0) << line;
    on_front += cells[column["pareto_translation"]] == "1";
    points.push_back({std::stod(cells[column["median_frame_ms"]]),
                      std::stod(cells[column["median_final_translation_m"]]),
                      std::stod(cells[column["median_final_rotation_rad"]]),
                      cells[column["pareto_translation"]] == "1",
                      cells[column["pareto_rotation"]] == "1"});
  }
  // The fronts, from the table's own figures: a row is on one when no other is at least as fast
  // and as accurate and better in one of the two.
  const auto dominated = [&](const Point& a, double Point::*error) {
    for (const Point& b : points) {
      if (&a != &b && b.ms <= a.ms && b.*error <= a.*error &&
          (b.ms < a.ms || b.*error < a.*error)) {
        return true;
      }
    }
    return false;
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    EXPECT_EQ(points[i].front_t, !dominated(points[i], &Point::t)) << settings[i];
    EXPECT_EQ(points[i].front_r, !dominated(points[i], &Point::r)) << settings[i];
  }
  const std::vector<std::string> expected = {
      "default",  "resolution 240x320",           "voxel 0.2 mm",
      "window 3", "registration information off", "method constvel"};
  EXPECT_EQ(settings, expected);
  EXPECT_GE(on_front, 1);
  EXPECT_TRUE(fs::exists(tmp.str("b/bench.md")));
  EXPECT_TRUE(fs::exists(tmp.str("b/runs.csv")));
  EXPECT_TRUE(fs::exists(tmp.str("b/bench.png"))) << r.out;
}

TEST(PatchgraphBench, UnknownNormalsSourceFailsBeforeTracking) {
  TempDir tmp;
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH,
      "bench --quick -q --no-plot --normals gt no_such_model.pt --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("no_such_model.pt"), std::string::npos) << r.out;
}

// bench times one sensor's tracking: a scene of several sensors is refused, naming it.
TEST(PatchgraphBench, ASceneOfSeveralSensorsIsRefused) {
  TempDir tmp;
  const std::string scene = std::string(PG_SOURCE_DIR) + "/scenes/examples/two_digits_regrasp.json";
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench -q --no-plot --quick --scenes " + scene + " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(scene + ": sensors: 2 sensors; bench times one sensor's tracking"),
            std::string::npos)
      << r.out;
}

TEST(PatchgraphBench, ASceneOrNormalsSourceGivenTwiceIsRefused) {
  TempDir tmp;
  const std::string scene = std::string(PG_SOURCE_DIR) + "/scenes/examples/sphere_press.json";
  auto r =
      testing_support::run_command(PATCHGRAPH_PATH, "bench -q --no-plot --scenes " + scene + " " +
                                                        scene + " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("given twice"), std::string::npos) << r.out;
  r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench --quick -q --no-plot --normals gt gt --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--normals: gt given twice"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
}

}  // namespace
}  // namespace pg
