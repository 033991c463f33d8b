// `patchgraph bench --quick`: the run-time-vs-error sweep's smoke test (docs/benchmarks.md).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "../common/test_support.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using testing_support::TempDir;

using testing_support::read_csv_table;
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

// A scene whose tracked object hovers while another presses is said to be so when the bench
// renders it, as tacsim render says it; a cached render is not rendered again, nor warned again.
TEST(PatchgraphBench, OtherObjectsTouchingWithoutTheTrackedOneAreWarnedAbout) {
  TempDir tmp;
  const std::string meshes = std::string(PG_SOURCE_DIR) + "/meshes/";
  std::ofstream(tmp.str("hover.json"))
      << R"({"frames": 4, "sensors": [{}],
             "objects": [{"name": "cube", "mesh": ")"
      << meshes << R"(cube.glb", "pose": {"position": [0.0, 0.0, 0.015]}},
             {"name": "sphere", "mesh": ")"
      << meshes << R"(sphere_r6mm.glb", "pose": {"position": [0.0, 0.0, 0.005]}}],
             "tracked_object": "cube"})";
  const std::string command = "bench --quick -q --no-plot --scenes " + tmp.str("hover.json") +
                              " --cache " + tmp.str("cache") + " --out " + tmp.str("out");
  const std::string warning = "warning: " + tmp.str("hover.json") +
                              ": in 4 of the 4 contact frames only objects other than the tracked "
                              "one ('cube', tracked_object) touch the gel";
  auto r = testing_support::run_command(PATCHGRAPH_PATH, command);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(warning), std::string::npos) << r.out;
  r = testing_support::run_command(PATCHGRAPH_PATH, command);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find(warning), std::string::npos) << "the cached render\n" << r.out;
}

TEST(PatchgraphBench, QuickSweepWritesTableCsvAndPlot) {
  TempDir tmp;
  const auto r =
      testing_support::run_command(PATCHGRAPH_PATH, "bench --quick -q --out " + tmp.str("b"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("| setting | median update [ms]"), std::string::npos) << r.out;

  const auto csv = read_csv_table(tmp.str("b/bench.csv"));
  for (const char* c :
       {"setting", "runs", "median_frame_ms", "median_final_translation_m",
        "median_final_rotation_rad", "pareto_translation", "pareto_rotation", "icp_symmetric",
        "icp_max_normal_angle_rad", "depth_integration", "image_to_image_gate"}) {
    ASSERT_TRUE(csv.column.count(c)) << c;
  }
  std::vector<std::string> settings;
  struct Point {
    double ms, t, r;
    bool front_t, front_r;
  };
  std::vector<Point> points;
  int on_front = 0;
  for (std::size_t i = 0; i < csv.rows.size(); ++i) {
    ASSERT_EQ(csv.rows[i].size(), csv.column.size()) << "row " << i;
    const auto cell = [&](const char* name) { return csv.cell(i, name); };
    settings.push_back(cell("setting"));
    SCOPED_TRACE(settings.back());
    EXPECT_EQ(cell("runs"), "2");
    EXPECT_EQ(cell("icp_symmetric"), "1");                // ground-truth normals throughout
    EXPECT_EQ(cell("icp_max_normal_angle_rad"), "0.25");  // the quick sweep does not turn it off
    EXPECT_EQ(cell("keyframe_settle"), "0");         // the default; the full sweep's row sets 4
    EXPECT_EQ(cell("depth_integration"), "parity");  // the quick sweep: default
    EXPECT_EQ(cell("image_to_image_gate"), "1");
    for (const char* c :
         {"median_frame_ms", "median_final_translation_m", "median_final_rotation_rad"}) {
      const double v = std::stod(cell(c));
      EXPECT_TRUE(std::isfinite(v) && v >= 0) << c;
    }
    EXPECT_GT(std::stod(cell("median_frame_ms")), 0.0);
    on_front += cell("pareto_translation") == "1";
    points.push_back({std::stod(cell("median_frame_ms")),
                      std::stod(cell("median_final_translation_m")),
                      std::stod(cell("median_final_rotation_rad")),
                      cell("pareto_translation") == "1", cell("pareto_rotation") == "1"});
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
  EXPECT_TRUE(fs::exists(tmp.str("b/bench.png"))) << r.out;

  // Every run names the render and seed it tracked, and `track` of them with the setting's option
  // gives its errors: the settings of one resolution read its frames once (the first decodes
  // them, the rest take them from memory) and each tracks as a run of its own.
  const auto runs = read_csv_table(tmp.str("b/runs.csv"));
  ASSERT_EQ(runs.rows.size(), 12u);
  const std::map<std::string, std::string> option = {
      {"default", ""},
      {"window 3", " --window 3"},
      {"registration information off", " --no-registration-information"},
      {"method constvel", " --method constvel"}};
  int checked = 0;
  for (std::size_t i = 0; i < runs.rows.size(); ++i) {
    const auto it = option.find(runs.cell(i, "setting"));
    if (it == option.end() || runs.cell(i, "scene") != "cube_00") continue;
    SCOPED_TRACE(it->first);
    const std::string dataset = runs.cell(i, "dataset");
    EXPECT_NE(dataset.find("cube_00_"), std::string::npos) << dataset;
    const auto t = testing_support::run_command(
        PATCHGRAPH_PATH, "track -q " + dataset + " --seed " + runs.cell(i, "seed") + it->second +
                             " --out " + tmp.str("track_" + std::to_string(i)));
    ASSERT_EQ(t.code, 0) << t.out;
    std::ifstream in(tmp.str("track_" + std::to_string(i)) + "/summary.json");
    const auto summary = nlohmann::json::parse(in);
    for (const char* c : {"final_translation_error_m", "final_rotation_error_rad"}) {
      const double expected = std::stod(runs.cell(i, c));
      EXPECT_NEAR(summary.at(c).get<double>(), expected, 1e-8 * std::abs(expected) + 1e-15) << c;
    }
    ++checked;
  }
  EXPECT_EQ(checked, 4);
}

// (--no-plots, eval's spelling, is bench's --no-plot too.)
TEST(PatchgraphBench, UnknownNormalsSourceFailsBeforeTracking) {
  TempDir tmp;
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH,
      "bench --quick -q --no-plots --normals gt no_such_model.pt --out " + tmp.str("b"));
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
  EXPECT_EQ(r.code, 2) << r.out;  // a usage error, as in track and eval
  EXPECT_NE(r.out.find("given twice"), std::string::npos) << r.out;
  r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench --quick -q --no-plot --normals gt gt --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--normals: gt given twice"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
  // One model file written two ways.
  const std::string model = std::string(PG_SOURCE_DIR) + "/models/normals_unet.pt";
  r = testing_support::run_command(PATCHGRAPH_PATH, "bench --quick -q --no-plot --normals " +
                                                        model + " " + std::string(PG_SOURCE_DIR) +
                                                        "/models/../models/normals_unet.pt --out " +
                                                        tmp.str("b"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("given twice (also as " + model + ")"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
}

// Every scene is read, and every model loaded, before anything renders: a missing second scene
// failed after the whole sweep on the first.
TEST(PatchgraphBench, ABadSceneOrModelFailsBeforeAnyRender) {
  TempDir tmp;
  const std::string scene = std::string(PG_SOURCE_DIR) + "/scenes/benchmark/cube_00.json";
  auto r = testing_support::run_command(PATCHGRAPH_PATH,
                                        "bench -q --no-plot --frames 10 --scenes " + scene + " " +
                                            tmp.str("no_such.json") + " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("no_such.json"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b"))) << "rendered before the check";
  std::ofstream(tmp.str("lost_mesh.json"))
      << R"({"frames": 4, "sensors": [{}], "objects": [{"name": "o", "mesh": "gone.glb"}]})";
  r = testing_support::run_command(PATCHGRAPH_PATH, "bench -q --no-plot --frames 10 --scenes " +
                                                        scene + " " + tmp.str("lost_mesh.json") +
                                                        " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("lost_mesh.json: objects[0].mesh: " + tmp.str("gone.glb")),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
  // A mesh that does not load, a background image that is not there: what a render refuses.
  std::ofstream(tmp.str("bad.glb")) << "not a glTF file";
  std::ofstream(tmp.str("bad_mesh.json"))
      << R"({"frames": 4, "sensors": [{}], "objects": [{"name": "o", "mesh": "bad.glb"}]})";
  std::ofstream(tmp.str("lost_background.json"))
      << R"({"frames": 4, "sensors": [{}], "objects": [{"name": "o", "mesh": ")"
      << std::string(PG_SOURCE_DIR)
      << R"(/meshes/cube.glb"}], "render": {"background": "gone.png"}})";
  for (const char* bad : {"bad_mesh.json", "lost_background.json"}) {
    r = testing_support::run_command(PATCHGRAPH_PATH, "bench -q --no-plot --frames 10 --scenes " +
                                                          scene + " " + tmp.str(bad) + " --out " +
                                                          tmp.str("b"));
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(tmp.str(bad) + ": "), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(tmp.str("b"))) << bad << ": rendered before the check";
  }
  r = testing_support::run_command(PATCHGRAPH_PATH,
                                   "bench -q --no-plot --frames 10 --scenes " + scene +
                                       " --normals gt no_such_model.pt --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("no_such_model.pt"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
  // More frames than a scene has were cut to its length without a word, the table's head still
  // reading --frames 301.
  r = testing_support::run_command(PATCHGRAPH_PATH, "bench -q --no-plot --frames 301 --scenes " +
                                                        scene + " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--frames 301: " + scene + " has 300 frames"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
  // A cache in a dataset's folder would put the renders among its files.
  fs::create_directories(tmp.str("dataset"));
  std::ofstream(tmp.str("dataset/dataset.json")) << "{}";
  r = testing_support::run_command(PATCHGRAPH_PATH, "bench -q --no-plot --frames 10 --scenes " +
                                                        scene + " --cache " + tmp.str("dataset") +
                                                        " --out " + tmp.str("b"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--cache " + tmp.str("dataset") + " holds a dataset (dataset.json)"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("b")));
  EXPECT_EQ(std::vector<fs::path>(fs::directory_iterator(tmp.str("dataset")), {}).size(), 1u);
}

// A learned-normals row records the settings `track` gives a model (no image-to-image gate, the
// target's normals in the ICP, the averaged integration), not the ground-truth rows' ones.
TEST(PatchgraphBench, ALearnedRowRecordsItsOwnSettings) {
  TempDir tmp;
  const std::string scene = std::string(PG_SOURCE_DIR) + "/scenes/benchmark/cube_00.json";
  const std::string model = std::string(PG_SOURCE_DIR) + "/models/normals_unet.pt";
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench --quick -q --no-plot --frames 10 --scenes " + scene +
                           " --normals gt " + model + " --out " + tmp.str("b"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto csv = read_csv_table(tmp.str("b/bench.csv"));
  int learned = 0;
  for (std::size_t i = 0; i < csv.rows.size(); ++i) {
    SCOPED_TRACE(csv.cell(i, "setting"));
    const bool model_row = csv.cell(i, "normals") == model;
    learned += model_row;
    EXPECT_EQ(csv.cell(i, "image_to_image_gate"), model_row ? "0" : "1");
    EXPECT_EQ(csv.cell(i, "icp_symmetric"), model_row ? "0" : "1");
    EXPECT_EQ(csv.cell(i, "depth_integration"), model_row ? "averaged" : "parity");
  }
  EXPECT_EQ(learned, 1);
}

// A row MODEL+shading:W tracks with the model's normals averaged with the shading's inverse
// (`track --normals MODEL --blend-shading W`): a row of its own, with the model's settings and
// other errors than the model alone; a weight outside (0, 1] or a blend without a model is a
// usage error.
TEST(PatchgraphBench, ABlendRowIsTheModelAveragedWithTheShadingsInverse) {
  TempDir tmp;
  const std::string scene = std::string(PG_SOURCE_DIR) + "/scenes/benchmark/cube_00.json";
  const std::string model = std::string(PG_SOURCE_DIR) + "/models/normals_unet.pt";
  const std::string blend = model + "+shading:0.5";
  const auto r = testing_support::run_command(
      PATCHGRAPH_PATH, "bench --quick -q --no-plot --frames 10 --scenes " + scene +
                           " --normals gt " + model + " " + blend + " --out " + tmp.str("b"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto csv = read_csv_table(tmp.str("b/bench.csv"));
  std::map<std::string, std::size_t> row_of;
  for (std::size_t i = 0; i < csv.rows.size(); ++i) row_of[csv.cell(i, "normals")] = i;
  ASSERT_TRUE(row_of.count(blend) && row_of.count(model)) << r.out;
  // The model's settings (no image-to-image gate, the averaged integration), its own errors.
  EXPECT_EQ(csv.cell(row_of[blend], "image_to_image_gate"), "0");
  EXPECT_EQ(csv.cell(row_of[blend], "depth_integration"), "averaged");
  EXPECT_NE(csv.cell(row_of[blend], "median_final_translation_m"),
            csv.cell(row_of[model], "median_final_translation_m"));
  for (const std::string& bad : {model + "+shading:0", model + "+shading:1.5", model + "+shading:x",
                                 std::string("shading+shading:0.5")}) {
    const auto refused = testing_support::run_command(
        PATCHGRAPH_PATH, "bench --quick -q --no-plot --normals " + bad + " --out " + tmp.str("x"));
    EXPECT_EQ(refused.code, 2) << bad << "\n" << refused.out;
    EXPECT_NE(refused.out.find("--normals " + bad + ": "), std::string::npos) << refused.out;
  }
}

// The cache knows a render by the contents of the files its scene names: the same scene however
// its path is written hits, a mesh replaced under the same name renders anew; a cache entry that
// no longer reads is named, with what to do.
TEST(PatchgraphBench, TheCacheSeesAReplacedMeshAndNamesADamagedRender) {
  TempDir tmp;
  const std::string meshes = std::string(PG_SOURCE_DIR) + "/meshes/";
  fs::copy_file(meshes + "cube.glb", tmp.path / "obj.glb");
  std::ofstream(tmp.str("s.json"))
      << R"({"frames": 12, "sensors": [{}], "objects": [{"name": "o", "mesh": "obj.glb",
            "pose": {"position": [0, 0, 0.0095]}}]})";
  const std::string bench = "bench --quick -q --no-plot --frames 10 --scenes " + tmp.str("s.json") +
                            " --cache " + tmp.str("cache") + " --out " + tmp.str("b");
  ASSERT_EQ(testing_support::run_command(PATCHGRAPH_PATH, bench).code, 0);
  const auto entries = [&] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(tmp.path / "cache")) n += e.is_directory();
    return n;
  };
  const auto entry_names = [&] {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(tmp.path / "cache")) {
      if (e.is_directory()) names.insert(e.path().filename().string());
    }
    return names;
  };
  const int first = entries();
  ASSERT_GT(first, 0);
  // The same scene written another way (the key is the files' contents, not their paths).
  fs::create_directories(tmp.path / "sub");
  ASSERT_EQ(testing_support::run_command(
                PATCHGRAPH_PATH, "bench --quick -q --no-plot --frames 10 --scenes " +
                                     tmp.str("sub/../s.json") + " --cache " + tmp.str("cache") +
                                     " --out " + tmp.str("b"))
                .code,
            0);
  EXPECT_EQ(entries(), first) << "the same scene rendered again";
  const std::set<std::string> before = entry_names();
  fs::copy_file(meshes + "sphere_r6mm.glb", tmp.path / "obj.glb",
                fs::copy_options::overwrite_existing);
  ASSERT_EQ(testing_support::run_command(PATCHGRAPH_PATH, bench).code, 0);
  EXPECT_EQ(entries(), 2 * first) << "the replaced mesh's scene was not rendered anew";
  // Cut short a frame of a render the replaced mesh made.
  fs::path fresh;
  for (const std::string& name : entry_names()) {
    if (!before.count(name)) fresh = tmp.path / "cache" / name;
  }
  ASSERT_FALSE(fresh.empty());
  const fs::path frame = fresh / "normal" / "000005.exr";
  ASSERT_TRUE(fs::exists(frame)) << frame;
  fs::resize_file(frame, fs::file_size(frame) / 3);
  const auto r = testing_support::run_command(PATCHGRAPH_PATH, bench);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("a render in the bench's cache: remove "), std::string::npos) << r.out;
}

}  // namespace
}  // namespace pg
