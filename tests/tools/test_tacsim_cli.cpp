// The tacsim command line as a user meets it: exit codes, messages, and a real render.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

#include "../common/test_support.h"
#include "pg/core/dataset.h"
#include "pg/core/image.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using testing_support::CliRun;
using testing_support::run_command;
using testing_support::TempDir;

CliRun tacsim(const std::string& args) { return testing_support::run_command(TACSIM_PATH, args); }

const std::string kScenes = std::string(PG_SOURCE_DIR) + "/scenes/";

TEST(TacsimCli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(tacsim("").code, 2);
  const CliRun unknown = tacsim("frobnicate");
  EXPECT_EQ(unknown.code, 2);
  EXPECT_NE(unknown.out.find("unknown subcommand 'frobnicate' (known: render, info, bench, sheet, "
                             "presses, sensitivity)"),
            std::string::npos)
      << unknown.out;
  EXPECT_EQ(tacsim("render").code, 2);  // missing SCENE and --out
  EXPECT_EQ(tacsim("render x.json --out y --width 3").code, 2);
  const CliRun version = tacsim("--version");
  EXPECT_EQ(version.code, 0);
  EXPECT_EQ(version.out.rfind("tacsim 0.", 0), 0u) << version.out;
  // An --out that cannot be a folder is named as such (/proc's "disk" has no free space).
  if (fs::is_directory("/proc/self")) {
    const CliRun r = tacsim("render " + kScenes + "examples/sphere_press.json -q --out /proc/x");
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find("/proc/x: cannot create the output folder"), std::string::npos) << r.out;
  }
}

TEST(TacsimCli, HelpOnEverySubcommand) {
  for (const char* sub : {"", "render ", "info ", "bench ", "sheet ", "presses ", "sensitivity "}) {
    const CliRun r = tacsim(std::string(sub) + "--help");
    EXPECT_EQ(r.code, 0) << sub;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << r.out;
  }
  EXPECT_NE(tacsim("render --help").out.find("--outputs"), std::string::npos);
}

// sensitivity prints the bound's summary for the undeformed and the tilted gel and writes its map;
// a camera without noise, an unknown preset or a bad tilt is a usage error.
TEST(TacsimCli, SensitivityReportsTheBoundAndRefusesANoiseFreeCamera) {
  const TempDir tmp;
  const std::string map = tmp.str("bound.exr");
  const CliRun r = tacsim("sensitivity --tilt 25 --out " + map);
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* line :
       {"sensor digit: 120 x 160 px, camera noise sigma 7.00 levels",
        "clipped: ", "undeformed gel: median ", "tilted 25 deg, 8 directions: median ", "wrote "}) {
    EXPECT_NE(r.out.find(line), std::string::npos) << line << "\n" << r.out;
  }
  const ImageF bound = read_image_float(map);
  ASSERT_TRUE(bound.same_shape(120, 160, 1));
  EXPECT_TRUE(std::all_of(bound.data.begin(), bound.data.end(),
                          [](float v) { return v > 0 && v <= 1.5708f; }));
  // Twice the noise, twice the bound, in the printed median too.
  const auto median_deg = [](const std::string& out) {
    const std::size_t at = out.find("undeformed gel: median ");
    return at == std::string::npos ? -1.0 : std::stod(out.substr(at + 23));
  };
  const CliRun quiet = tacsim("sensitivity --tilt 0 --sigma 3.5");
  const CliRun loud = tacsim("sensitivity --tilt 0 --sigma 7");
  ASSERT_EQ(quiet.code, 0) << quiet.out;
  EXPECT_EQ(quiet.out.find("tilted"), std::string::npos) << quiet.out;
  EXPECT_NEAR(median_deg(loud.out), 2 * median_deg(quiet.out), 0.02) << loud.out << quiet.out;
  // A sensor file whose camera has no noise.
  const std::string sensor = tmp.str("quiet.json");
  std::ofstream(sensor) << R"({"preset": "digit", "noise": {"sigma": 0}})";
  const CliRun none = tacsim("sensitivity --sensor-file " + sensor);
  EXPECT_EQ(none.code, 2) << none.out;
  EXPECT_NE(none.out.find("noise.sigma is 0"), std::string::npos) << none.out;
  EXPECT_EQ(tacsim("sensitivity --sensor-file " + sensor + " --sigma 2").code, 0);
  EXPECT_EQ(tacsim("sensitivity --sigma 0").code, 2);
  EXPECT_EQ(tacsim("sensitivity --tilt 90").code, 2);
  EXPECT_EQ(tacsim("sensitivity --sensor nope").code, 2);
  const CliRun png = tacsim("sensitivity --out " + tmp.str("bound.png"));
  EXPECT_EQ(png.code, 2) << png.out;
  EXPECT_NE(png.out.find("give an .exr file"), std::string::npos) << png.out;
  EXPECT_FALSE(fs::exists(tmp.str("bound.png")));
  EXPECT_EQ(tacsim("sensitivity --sensor digit --sensor-file " + sensor).code, 2);
  const CliRun missing = tacsim("sensitivity --sensor-file " + tmp.str("missing.json"));
  EXPECT_EQ(missing.code, 1) << missing.out;
  EXPECT_NE(missing.out.find("missing.json"), std::string::npos) << missing.out;
}

TEST(TacsimCli, BadInputNamesTheFileAndExitsWithOne) {
  TempDir tmp;
  CliRun r = tacsim("render /no/such/scene.json --out " + tmp.str("o"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("/no/such/scene.json"), std::string::npos) << r.out;
  std::ofstream(tmp.str("bad.json")) << "{\n  \"frames\": 3,\n  oops\n}\n";
  r = tacsim("render " + tmp.str("bad.json") + " --out " + tmp.str("o"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("bad.json:3:"), std::string::npos) << r.out;
  r = tacsim("render " + kScenes + "examples/sphere_press.json --outputs color,colour --out " +
             tmp.str("o"));
  EXPECT_EQ(r.code, 2);  // a bad option value: a usage error, as CLI11's own
  EXPECT_NE(r.out.find("colour"), std::string::npos) << r.out;
  // An empty name in the list (an unset shell variable) is refused, not skipped.
  for (const char* list : {"color,,normal", "color,", ",mask"}) {
    r = tacsim("render " + kScenes + "examples/sphere_press.json --outputs " + list + " --out " +
               tmp.str("o"));
    EXPECT_EQ(r.code, 2) << list;
    EXPECT_NE(r.out.find(std::string("--outputs ") + list + ": an empty name in the list"),
              std::string::npos)
        << r.out;
  }
  EXPECT_FALSE(fs::exists(tmp.str("o")));
  r = tacsim("info " + tmp.str("nothing"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("nothing"), std::string::npos) << r.out;
  // Before the benchmark runs (the ablation's table was silently lost).
  for (const char* mode : {" --frames 2", " --ablation"}) {
    r = tacsim(std::string("bench --quick --repeats 1") + mode + " --markdown /proc/no/such.md");
    EXPECT_EQ(r.code, 1) << mode;
    EXPECT_EQ(r.out.rfind("error: /proc/no/such.md: cannot write", 0), 0u) << r.out;
    // A folder, which the report could not replace (found only after the whole run before).
    r = tacsim(std::string("bench --quick --repeats 1") + mode + " --markdown " +
               tmp.path.string());
    EXPECT_EQ(r.code, 1) << mode;
    EXPECT_NE(r.out.find("is a folder; give a file name"), std::string::npos) << r.out;
  }
  // --frames does not apply to the ablation, whose runs are timed by length.
  r = tacsim("bench --quick --ablation --frames 5");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--frames"), std::string::npos) << r.out;
}

// A mesh file used by several objects is loaded, repaired and warned about once per scale (300
// objects of one mesh had taken 10 s and 1 GB, and repeated its repair warning 300 times).
TEST(TacsimCli, AMeshOfSeveralObjectsIsLoadedOnce) {
  TempDir tmp;
  // A 1 cm cube inside out: every triangle clockwise seen from outside, turned with a warning.
  std::ofstream(tmp.str("cube.obj"))
      << "v 0 0 0\nv 0.01 0 0\nv 0.01 0.01 0\nv 0 0.01 0\nv 0 0 0.01\nv 0.01 0 0.01\n"
         "v 0.01 0.01 0.01\nv 0 0.01 0.01\nf 1 2 3\nf 1 3 4\nf 5 7 6\nf 5 8 7\nf 1 6 2\n"
         "f 1 5 6\nf 2 7 3\nf 2 6 7\nf 3 8 4\nf 3 7 8\nf 4 5 1\nf 4 8 5\n";
  std::string objects;
  for (int k = 0; k < 4; ++k) {
    objects += std::string(k ? ", " : "") + R"({"name": "c)" + std::to_string(k) +
               R"(", "mesh": "cube.obj", "scale": )" + (k < 3 ? "1" : "0.5") +
               R"(, "pose": {"position": [)" + std::to_string(0.02 * k) + ", 0, 0.05]}}";
  }
  std::ofstream(tmp.str("scene.json"))
      << R"({"frames": 1, "sensors": [{}], "render": {"seed": 1}, "objects": [)" << objects << "]}";
  const CliRun r =
      tacsim("render " + tmp.str("scene.json") + " -q --outputs mask --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string warning = "closed part(s) had every triangle facing inward";
  std::size_t count = 0;
  for (auto at = r.out.find(warning); at != std::string::npos; at = r.out.find(warning, at + 1))
    ++count;
  EXPECT_EQ(count, 2u) << r.out;  // scale 1 (three objects) and scale 0.5
}

// A mesh at a scale that makes it larger than a metre (millimetres read as metres) or smaller
// than two pixels is warned about: the render had gone through with a clamping warning or none.
TEST(TacsimCli, AnObjectOfAnImplausibleSizeIsWarnedAbout) {
  TempDir tmp;
  const auto render = [&](const std::string& scale, const std::string& z) {
    std::ofstream(tmp.str("scene.json"))
        << R"({"frames": 1, "sensors": [{}], "render": {"seed": 1}, "objects": [{"mesh": ")"
        << PG_SOURCE_DIR << R"(/meshes/cube.glb", "scale": )" << scale
        << R"(, "pose": {"position": [0, 0, )" << z << "]}}]}";
    return tacsim("render " + tmp.str("scene.json") + " -q --outputs mask --out " + tmp.str("d"));
  };
  CliRun r = render("1000", "0.011");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("objects[0] ('object0'): " + std::string(PG_SOURCE_DIR) +
                       "/meshes/cube.glb is 2e+04 x 2e+04 x 2e+04 mm at scale 1000, larger than "
                       "a metre; is its scale right"),
            std::string::npos)
      << r.out;
  r = render("0.001", "0");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("at scale 0.001, smaller than two of the sensor's pixels"),
            std::string::npos)
      << r.out;
  r = render("1", "0.011");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("scale right"), std::string::npos) << r.out;
}

// Whole numbers are decimal: CLI11 reads them as C's strtoll does, so --frames 010 had rendered
// 8 frames, 0x10 threads were 16 and --seed -1 wrapped to 2^64 - 1, each without a word.
TEST(TacsimCli, WholeNumbersAreDecimal) {
  TempDir tmp;
  const std::string scene = kScenes + "examples/sphere_press.json";
  for (const char* frames : {"010", "0x4", "4.0"}) {
    const CliRun r =
        tacsim("render " + scene + " -q --frames " + frames + " --out " + tmp.str("o"));
    EXPECT_EQ(r.code, 2) << frames;
    EXPECT_NE(r.out.find("--frames"), std::string::npos) << r.out;
    EXPECT_FALSE(fs::exists(tmp.str("o"))) << frames;
  }
  CliRun r = tacsim("presses " + kScenes + "../meshes/sphere_r6mm.glb --seed -1 --out " +
                    tmp.str("p.json"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--seed: must be a whole number from 0 to 18446744073709551615, got -1"),
            std::string::npos)
      << r.out;
  r = tacsim("render " + scene + " -q --frames 4 --out " + tmp.str("o"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(Dataset::open(tmp.str("o")).frames(), 4);
}

// A whole-number option given a fraction, an exponent, a number past its type or a word is
// refused naming the option and what it takes. CLI11 had said "Value 1.5 not in range 1 to
// 10000000" of --frames, and "Could not convert: --repeats = 1e300" where its range check had
// passed the value as a floating-point number.
// A real-number option given NaN or a word is refused naming it.
TEST(TacsimCli, EveryRealNumberOptionRefusesWhatIsNoNumber) {
  for (const auto& [sub, options] :
       std::vector<std::pair<std::string, std::size_t>>{{"presses", 3}, {"sensitivity", 2}}) {
    for (const std::string& problem :
         testing_support::real_number_options_refused(TACSIM_PATH, sub, options)) {
      ADD_FAILURE() << problem;
    }
  }
}

TEST(TacsimCli, EveryWholeNumberOptionRefusesWhatIsNoWholeNumber) {
  for (const auto& [sub, options] : std::vector<std::pair<std::string, std::size_t>>{
           {"render", 4}, {"bench", 3}, {"sheet", 3}, {"presses", 2}}) {
    for (const std::string& problem :
         testing_support::whole_number_options_refused(TACSIM_PATH, sub, options)) {
      ADD_FAILURE() << problem;
    }
  }
  const CliRun r = tacsim("render " + kScenes + "default.json --frames 1e300 --out x");
  EXPECT_EQ(
      r.out.rfind("error: --frames: must be a whole number from 1 to 10000000, got 1e300\n", 0), 0u)
      << r.out;
  // Its value forgotten, the next option is named as such (it had been "..., got --out").
  const CliRun forgotten = tacsim("render " + kScenes + "default.json --frames --out x");
  EXPECT_EQ(forgotten.code, 2);
  EXPECT_EQ(forgotten.out.rfind(
                "error: --frames: '--out' is an option, not a value: give --frames its value\n", 0),
            0u)
      << forgotten.out;
}

// A pose list longer than the scene's frames is said to be cut short (a frames not updated after
// the list grew); --frames, a part of a scene on purpose, is not warned about.
TEST(TacsimCli, AMotionLongerThanTheSceneIsSaid) {
  TempDir tmp;
  std::string poses;
  for (int k = 0; k < 8; ++k) {
    poses += std::string(k ? ", " : "") + "{\"position\": [0, 0, " +
             std::to_string(0.0055 - 0.00002 * k) + "]}";
  }
  std::ofstream(tmp.str("scene.json"))
      << R"({"frames": 3, "sensors": [{}], "objects": [{"mesh": ")" << PG_SOURCE_DIR
      << R"(/meshes/sphere_r6mm.glb", "trajectory": {"poses": [)" << poses << "]}}]}";
  CliRun r = tacsim("render " + tmp.str("scene.json") + " -q --outputs mask --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: " + tmp.str("scene.json") +
                       ": objects[0].trajectory.poses gives 8 frames of motion, the scene's "
                       "frames 3: the render stops at frame 2"),
            std::string::npos)
      << r.out;
  r = tacsim("render " + tmp.str("scene.json") + " -q --frames 2 --outputs mask --out " +
             tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("frames of motion"), std::string::npos) << r.out;
}

// The frames are split among threads, each frame's noise drawn from its own seed: the files are
// the same bytes whatever the thread count.
TEST(TacsimCli, ARenderIsTheSameOnAnyNumberOfThreads) {
  if (std::thread::hardware_concurrency() < 2) GTEST_SKIP() << "one core: every run has one thread";
  TempDir tmp;
  for (const char* threads : {"1", "3"}) {
    const CliRun r = tacsim("render " + kScenes + "default.json -q --frames 6 --shadows on " +
                            "--outputs color,normal,depth,mask --threads " + threads + " --out " +
                            tmp.str(threads));
    ASSERT_EQ(r.code, 0) << r.out;
  }
  int compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(tmp.path / "1")) {
    if (!entry.is_regular_file()) continue;
    const fs::path other = tmp.path / "3" / fs::relative(entry.path(), tmp.path / "1");
    std::ifstream a(entry.path(), std::ios::binary), b(other, std::ios::binary);
    ASSERT_TRUE(b.good()) << other;
    const std::string bytes_a((std::istreambuf_iterator<char>(a)),
                              std::istreambuf_iterator<char>());
    const std::string bytes_b((std::istreambuf_iterator<char>(b)),
                              std::istreambuf_iterator<char>());
    EXPECT_EQ(bytes_a, bytes_b) << entry.path();
    ++compared;
  }
  EXPECT_GE(compared, 6 * 4 + 3) << "the frames of four outputs, poses and descriptions";
}

TEST(TacsimCli, RenderWritesADatasetThatInfoDescribes) {
  TempDir tmp;
  const CliRun r = tacsim("render " + kScenes + "examples/sphere_press.json --out " + tmp.str("d") +
                          " --threads 2 --width 60 --height 80");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("frames/s"), std::string::npos);  // progress and summary
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_EQ(d.info().width(), 60);
  EXPECT_EQ(d.info().height(), 80);
  EXPECT_GT(d.frames(), 0);
  for (const auto& p : d.poses()) EXPECT_TRUE(p.contact);
  const CliRun info = tacsim("info " + tmp.str("d"));
  EXPECT_EQ(info.code, 0);
  EXPECT_NE(info.out.find("60x80"), std::string::npos) << info.out;
  EXPECT_EQ(r.out.find("another shape"), std::string::npos) << r.out;
  // Another shape than the sensor's stretches its pixels: rendered, with a warning.
  const CliRun wide = tacsim("render " + kScenes + "examples/sphere_press.json -q --out " +
                             tmp.str("wide") + " --width 80 --height 60");
  ASSERT_EQ(wide.code, 0) << wide.out;
  EXPECT_NE(wide.out.find("warning: --width 80 --height 60: sensor digit is 120x160 px, another "
                          "shape; its pixels become 0.562 times as wide as tall"),
            std::string::npos)
      << wide.out;
}

// A sensor over-exposed into white (or dark into black) over much of its image cannot show a press
// there, and one whose camera sees past the gel shows gel that is not there: the render warns,
// naming the sensor; the preset's does not.
TEST(TacsimCli, AnOverExposedOrWideSensorIsWarnedAbout) {
  TempDir tmp;
  const std::string mesh = std::string(PG_SOURCE_DIR) + "/meshes/sphere_r6mm.glb";
  // One frame of the sphere pressed 0.5 mm into a sensor named `name` (`sensor`: its JSON).
  const auto render_sensor = [&](const std::string& name, const std::string& sensor,
                                 const std::string& output) {
    std::ofstream(tmp.str(name + ".json"))
        << R"({"frames": 1, "sensors": [{"name": ")" << name << R"(", "sensor": )" << sensor
        << R"(}], "objects": [{"mesh": ")" << mesh
        << R"(", "pose": {"position": [0, 0, 0.0055]}}], "render": {"outputs": [")" << output
        << R"("]}})";
    return tacsim("render " + tmp.str(name + ".json") + " -q --out " + tmp.str(name));
  };
  // The presets, over-exposed, and one red light (a sensor file's `lights` replaces all three):
  // its green and blue channels are black everywhere, which every channel clipped at once had not
  // counted.
  const std::vector<std::pair<std::string, bool>> sensors = {
      {R"({"shading": {"exposure": 0.9}})", false},
      {R"({"preset": "gelsight_mini"})", false},
      {R"({"preset": "digit_240x320"})", false},
      {R"({"shading": {"exposure": 5.0}})", true},
      {R"({"lights": [{"position_m": [0, -0.02, -0.017], "color": [1, 0, 0], "intensity": 1}]})",
       true}};
  for (const auto& [sensor, warned] : sensors) {
    const CliRun r = render_sensor("left", sensor, "color");
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(r.out.find("warning: sensor left's no-contact image (background.png): ") !=
                  std::string::npos,
              warned)
        << sensor << ": " << r.out;
    EXPECT_EQ(r.out.find("of its pixels are clipped (at most one colour channel between 0 and "
                         "255)") != std::string::npos,
              warned)
        << sensor << ": " << r.out;
    EXPECT_EQ(r.out.find("past the gel"), std::string::npos) << r.out;
  }
  // A camera whose view reaches past the gel (a field of view of 1.4 rad, the DIGIT's 1.05):
  // the render draws gel where a real sensor shows its housing.
  const CliRun r = render_sensor("wide", R"({"camera": {"fov_y_rad": 1.4}})", "mask");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: sensor wide's camera sees past its gel's edges, by 2.8 mm along "
                       "x and 0.5 mm along y (gel.width_m 20.0 mm, gel.height_m 30.0 mm)"),
            std::string::npos)
      << r.out;
}

// tools/pg_dataset.py, the Python reader of the format (numpy and Pillow), reads a render's
// files as the C++ reader does: the same deepest indentation and count of contact points, unit
// normals and 16-bit PNG normals within 1e-4 of them (its own checks); a damaged normal, points
// or colour file is named with exit 1.
TEST(TacsimCli, ThePythonReaderReadsARender) {
  const std::string python = "/usr/bin/python3";
  if (run_command(python, "-c 'import numpy, PIL'").code != 0) {
    GTEST_SKIP() << "no numpy or Pillow for " << python << " (python3-matplotlib brings both)";
  }
  TempDir tmp;
  ASSERT_EQ(tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs " +
                   "color,normal,normal_png,depth,mask,points --out " + tmp.str("d"))
                .code,
            0);
  const std::string reader = std::string(PG_SOURCE_DIR) + "/tools/pg_dataset.py ";
  const CliRun r = run_command(python, reader + tmp.str("d") + " 5");
  ASSERT_EQ(r.code, 0) << r.out;
  const Dataset d = Dataset::open(tmp.str("d"));
  const ImageF depth = d.depth(5);
  char deepest[64];
  std::snprintf(deepest, sizeof deepest, "deepest %.6f mm",
                1e3 * *std::max_element(depth.data.begin(), depth.data.end()));
  EXPECT_NE(r.out.find(deepest), std::string::npos) << deepest << "\n" << r.out;
  EXPECT_NE(r.out.find("points    frame 5: " + std::to_string(d.contact_points(5).size()) + "\n"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("normal    frame 5: unit"), std::string::npos) << r.out;
  // Its own 16-bit PNG reader (Pillow's gives 8 bits) decodes normal_png to the EXR's normals.
  EXPECT_NE(r.out.find("normal_png frame 5: within"), std::string::npos) << r.out;
  const std::string victim = dataset_frame_path(tmp.str("d"), "normal", 5);
  fs::resize_file(victim, fs::file_size(victim) / 2);
  const CliRun damaged = run_command(python, reader + tmp.str("d") + " 5");
  EXPECT_EQ(damaged.code, 1) << damaged.out;
  EXPECT_NE(damaged.out.find(victim + ": damaged or cut short"), std::string::npos) << damaged.out;
  // So is a cut contact-point file (numpy's complaint named none).
  const std::string points = dataset_frame_path(tmp.str("d"), "points", 4);
  fs::resize_file(points, fs::file_size(points) - 10);
  const CliRun cut = run_command(python, reader + tmp.str("d") + " 4");
  EXPECT_EQ(cut.code, 1) << cut.out;
  EXPECT_NE(cut.out.find(points + ": cut short: "), std::string::npos) << cut.out;
  // And a cut colour frame (it had not been read at all).
  EXPECT_NE(r.out.find("color     frame 5: mean level"), std::string::npos) << r.out;
  const std::string color = dataset_frame_path(tmp.str("d"), "color", 3);
  fs::resize_file(color, fs::file_size(color) / 2);
  const CliRun cut_color = run_command(python, reader + tmp.str("d") + " 3");
  EXPECT_EQ(cut_color.code, 1) << cut_color.out;
  EXPECT_NE(cut_color.out.find(color + ": damaged or cut short"), std::string::npos)
      << cut_color.out;
}

// `info --check` reads every frame file: a truncated one, which `info` alone (and opening the
// dataset) takes for present, is named with exit 1; an intact dataset reports what it read.
TEST(TacsimCli, InfoCheckReadsEveryFrame) {
  TempDir tmp;
  const CliRun r =
      tacsim("render " + kScenes + "examples/sphere_press.json -q --out " + tmp.str("d") +
             " --width 60 --height 80 --outputs color,normal,normal_png,points");
  ASSERT_EQ(r.code, 0) << r.out;
  const CliRun intact = tacsim("info --check " + tmp.str("d"));
  EXPECT_EQ(intact.code, 0) << intact.out;
  // 10 frames x 4 outputs, and background.png.
  EXPECT_NE(intact.out.find("checked   41 frame files: each reads, at 60x80"), std::string::npos)
      << intact.out;
  // The normals as 16-bit PNG, (n + 1) / 2: the EXR's to a 65535th.
  const Dataset d = Dataset::open(tmp.str("d"));
  const ImageF exact = d.normal(5), coded = d.normal_png(5);
  ASSERT_EQ(coded.data.size(), exact.data.size());
  float worst = 0, tilted = 0;
  for (std::size_t i = 0; i < exact.data.size(); ++i) {
    worst = std::max(worst, std::abs(coded.data[i] - exact.data[i]));
    if (i % 3 == 2) tilted = std::max(tilted, 1 - exact.data[i]);
  }
  EXPECT_LT(worst, 5e-5f);
  EXPECT_GT(tilted, 0.05f);  // the press's slopes (up to 25 deg) are in it
  EXPECT_EQ(read_image_shape(dataset_frame_path(tmp.str("d"), "normal_png", 5)).channels, 3);
  // A normal that is no number decodes as well as one; --check names it (it had passed).
  ImageF not_finite = d.normal(7);
  not_finite.at(9, 2, 1) = std::numeric_limits<float>::quiet_NaN();
  write_image(dataset_frame_path(tmp.str("d"), "normal", 7), not_finite);
  const CliRun nan = tacsim("info --check " + tmp.str("d"));
  EXPECT_EQ(nan.code, 1) << nan.out;
  EXPECT_NE(nan.out.find(dataset_frame_path(tmp.str("d"), "normal", 7) +
                         ": pixel (9, 2) is not a finite number"),
            std::string::npos)
      << nan.out;
  const std::string victim = dataset_frame_path(tmp.str("d"), "normal", 4);
  fs::resize_file(victim, fs::file_size(victim) / 2);
  EXPECT_EQ(tacsim("info " + tmp.str("d")).code, 0) << "the file exists";
  const CliRun damaged = tacsim("info --check " + tmp.str("d"));
  EXPECT_EQ(damaged.code, 1) << damaged.out;
  EXPECT_NE(damaged.out.find("normal/000004.exr"), std::string::npos) << damaged.out;
  // A mask that decodes but disagrees with poses.csv's contact (an empty one where the frame is
  // marked in contact: a mask copied from another frame, or an edited poses.csv).
  ASSERT_EQ(tacsim("render " + kScenes + "examples/sphere_press.json -q --out " + tmp.str("m") +
                   " --width 60 --height 80 --outputs mask")
                .code,
            0);
  ASSERT_EQ(tacsim("info --check " + tmp.str("m")).code, 0);
  const Dataset masked = Dataset::open(tmp.str("m"));
  int touched = 0;
  while (touched < masked.frames() && !masked.poses()[std::size_t(touched)].contact) ++touched;
  ASSERT_LT(touched, masked.frames());
  write_image(dataset_frame_path(tmp.str("m"), "mask", touched), ImageU8(60, 80, 1));
  const CliRun emptied = tacsim("info --check " + tmp.str("m"));
  EXPECT_EQ(emptied.code, 1) << emptied.out;
  EXPECT_NE(emptied.out.find(dataset_frame_path(tmp.str("m"), "mask", touched) +
                             ": shows no contact, but poses.csv marks frame " +
                             std::to_string(touched) + " as in contact"),
            std::string::npos)
      << emptied.out;
}

// dataset.json describes the frames: the sensor's noise sigma is 0 when the scene renders
// without noise, its model's sigma when with.
TEST(TacsimCli, DatasetJsonSaysWhetherTheFramesAreNoisy) {
  TempDir tmp;
  std::ifstream in(kScenes + "examples/sphere_press.json");
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto replace = [&](const std::string& from, const std::string& to) {
    const std::size_t at = text.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    text.replace(at, from.size(), to);
  };
  replace("../../meshes/", std::string(PG_SOURCE_DIR) + "/meshes/");
  replace("\"noise\": true", "\"noise\": false");
  std::ofstream(tmp.str("quiet.json")) << text;
  for (const auto& [scene, sigma] :
       {std::pair<std::string, double>{kScenes + "examples/sphere_press.json", 7.0},
        {tmp.str("quiet.json"), 0.0}}) {
    const CliRun r = tacsim("render " + scene + " -q --outputs mask --out " + tmp.str("d"));
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_EQ(Dataset::open(tmp.str("d")).info().sensor.noise.sigma, sigma) << scene;
    EXPECT_FALSE(Dataset::open(tmp.str("d")).info().shadows);
    EXPECT_EQ(Dataset::open(tmp.str("d")).info().background, "");
  }
  // So do tacsim render's overrides of the scene's shading: shadows and a real background.
  const std::string background = tmp.str("bg.png");
  write_image(background, ImageU8(120, 160, 3));
  const CliRun r =
      tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs mask" +
             " --shadows on --elastic off --background " + background + " --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  const DatasetInfo info = Dataset::open(tmp.str("d")).info();
  EXPECT_TRUE(info.shadows);
  EXPECT_EQ(info.background, fs::absolute(background).lexically_normal().string());
  const CliRun described = tacsim("info " + tmp.str("d"));
  EXPECT_NE(described.out.find("render    rigid gel, noise sigma 7, shadows on, " +
                               info.background + " background"),
            std::string::npos)
      << described.out;
  // And of the camera noise, both ways: off for a noisy scene, on for a quiet one.
  for (const auto& [scene, noise, sigma] : {std::tuple<std::string, std::string, double>{
                                                kScenes + "examples/sphere_press.json", "off", 0.0},
                                            {tmp.str("quiet.json"), "on", 7.0}}) {
    const CliRun run = tacsim("render " + scene + " -q --outputs color --frames 2 --noise " +
                              noise + " --out " + tmp.str("d"));
    ASSERT_EQ(run.code, 0) << run.out;
    const Dataset d = Dataset::open(tmp.str("d"));
    EXPECT_EQ(d.info().sensor.noise.sigma, sigma) << scene;
    // The press is still: its two frames differ by the camera noise alone.
    EXPECT_EQ(d.color(0).data == d.color(1).data, noise == "off") << scene;
  }
  // The words a scene's render.background takes work on the command line too: a scene with a
  // real background rendered with the synthetic one (they had been taken for file names).
  const std::string real_scene = tmp.str("real_bg.json");
  std::ofstream(real_scene) << R"({"frames": 1, "sensors": [{}], "objects": [{"mesh": ")"
                            << PG_SOURCE_DIR << R"(/meshes/cube.glb"}], "render": {"background": ")"
                            << background << R"("}})";
  for (const char* word : {"synthetic", "none"}) {
    const CliRun synthetic = tacsim("render " + real_scene + " -q --outputs color --background " +
                                    word + " --out " + tmp.str(std::string("bg_") + word));
    ASSERT_EQ(synthetic.code, 0) << synthetic.out;
    EXPECT_EQ(Dataset::open(tmp.str(std::string("bg_") + word)).info().background, "") << word;
    // A scene without render.seed draws seed 0's noise, as every such scene: said.
    EXPECT_NE(synthetic.out.find("note: " + real_scene + " has no render.seed"), std::string::npos)
        << synthetic.out;
  }
  const CliRun seeded = tacsim("render " + kScenes + "examples/sphere_press.json -q --frames 1 " +
                               "--outputs color --out " + tmp.str("seeded"));
  ASSERT_EQ(seeded.code, 0) << seeded.out;
  EXPECT_EQ(seeded.out.find("has no render.seed"), std::string::npos) << seeded.out;
  // A render's dataset.json from before these were recorded: not taken for "off".
  const std::string json_path = tmp.str("d") + "/dataset.json";
  std::ifstream json_in(json_path);
  std::string json((std::istreambuf_iterator<char>(json_in)), std::istreambuf_iterator<char>());
  json_in.close();
  const std::size_t at = json.find(",\n  \"render\"");
  ASSERT_NE(at, std::string::npos) << json;
  json.erase(at, json.find('}', at) + 1 - at);
  std::ofstream(json_path) << json;
  EXPECT_FALSE(Dataset::open(tmp.str("d")).info().render_known);
  const CliRun older = tacsim("info " + tmp.str("d"));
  EXPECT_NE(older.out.find("shadows and background not recorded"), std::string::npos) << older.out;
}

TEST(TacsimCli, TwoSensorsPinchingWriteADatasetEach) {
  TempDir tmp;
  const CliRun r =
      tacsim("render " + kScenes +
             "examples/two_digits_pinch.json -q --outputs mask,points --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  // The sensors' folders, listed in the scene's order in sensors.json.
  const std::vector<std::string> dirs = sensor_dataset_dirs(tmp.str("d"));
  EXPECT_EQ(dirs, (std::vector<std::string>{tmp.str("d") + "/digit_bottom",
                                            tmp.str("d") + "/digit_top"}));
  int datasets = 0;
  for (const std::string& dir : dirs) {
    const fs::path entry = dir;  // (named as in a directory listing, for the messages below)
    const Dataset d = Dataset::open(dir);
    ++datasets;
    for (int i = 0; i < d.frames(); ++i) {
      EXPECT_TRUE(d.poses()[i].contact) << entry << " frame " << i;
      // The pinched cube's contact points lie on its faces (|coordinate| = 10 mm on one axis).
      const auto pts = d.contact_points(i);
      ASSERT_GT(pts.size(), 20u);
      for (const auto& p : pts) EXPECT_NEAR(p.cwiseAbs().maxCoeff(), 0.010, 2e-5);
    }
  }
  EXPECT_EQ(datasets, 2);
  // info describes each sensor's dataset of the render (it had refused the render's folder).
  const CliRun info = tacsim("info " + tmp.str("d"));
  EXPECT_EQ(info.code, 0) << info.out;
  EXPECT_NE(info.out.find("render    " + tmp.str("d") +
                          ": 2 sensors (sensors.json): digit_bottom, digit_top\n"),
            std::string::npos)
      << info.out;
  EXPECT_NE(info.out.find("dataset   " + tmp.str("d") + "/digit_top\n"), std::string::npos)
      << info.out;
  // A dataset reader, given the render's folder, names its sensors' folders.
  try {
    Dataset::open(tmp.str("d"));
    ADD_FAILURE() << "the render's folder opened as one dataset";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(tmp.str("d") +
                                         ": is not a dataset, but a render of several sensors "
                                         "(sensors.json): digit_bottom, digit_top; give one of "
                                         "those folders (patchgraph track takes " +
                                         tmp.str("d") + " itself"),
              std::string::npos)
        << e.what();
  }
  // Rendered again with a sensor of another name: the new one's folder is listed, the earlier
  // one's is left as it was and said so (it had stayed without a word).
  std::string scene = testing_support::file_text(kScenes + "examples/two_digits_pinch.json");
  for (std::size_t at; (at = scene.find("\"digit_top\"")) != std::string::npos;)
    scene.replace(at, 11, "\"digit_upper\"");
  std::string meshes = kScenes + "../meshes/";
  for (std::size_t at = 0; (at = scene.find("\"../../meshes/", at)) != std::string::npos;)
    scene.replace(at + 1, 13, meshes), at += meshes.size();
  std::ofstream(tmp.str("renamed.json")) << scene;
  const CliRun again =
      tacsim("render " + tmp.str("renamed.json") + " -q --outputs mask --out " + tmp.str("d"));
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_EQ(
      sensor_dataset_dirs(tmp.str("d")),
      (std::vector<std::string>{tmp.str("d") + "/digit_bottom", tmp.str("d") + "/digit_upper"}));
  EXPECT_NE(again.out.find("note: " + tmp.str("d") + "/digit_top, from an earlier render into " +
                           tmp.str("d") + ", is not a sensor of this scene: left as it was"),
            std::string::npos)
      << again.out;
  EXPECT_EQ(Dataset::open(tmp.str("d") + "/digit_top").frames(), Dataset::open(dirs[0]).frames());
}

// --out into a folder that is not a dataset, or a two-sensor scene into a dataset's folder or one
// of other files, is refused before anything is written; an earlier dataset is replaced.
TEST(TacsimCli, RenderReplacesOnlyADataset) {
  TempDir tmp;
  const std::string mine = tmp.str("mine");
  fs::create_directories(mine + "/color");
  std::ofstream(mine + "/poses.csv") << "my poses\n";
  std::ofstream(mine + "/color/000005.png") << "my image";
  CliRun r = tacsim("render " + kScenes + "examples/sphere_press.json -q --out " + mine);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(mine + ": is not empty and holds no dataset"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(mine + "/color/000005.png"));
  EXPECT_EQ(fs::file_size(mine + "/poses.csv"), 9u);
  EXPECT_FALSE(fs::exists(mine + "/dataset.json"));

  const std::string d = tmp.str("d");
  ASSERT_EQ(
      tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs mask --out " + d).code,
      0);
  r = tacsim("render " + kScenes + "examples/two_digits_pinch.json -q --outputs mask --out " + d);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("holds a dataset; a scene of 2 sensors"), std::string::npos) << r.out;
  EXPECT_EQ(Dataset::open(d).frames(), 10);  // untouched
  // A one-sensor scene into a render of several: refused by what the folder holds (it had read
  // "holds no dataset").
  const std::string pinch = tmp.str("pinch");
  ASSERT_EQ(tacsim("render " + kScenes + "examples/two_digits_pinch.json -q --outputs mask --out " +
                   pinch)
                .code,
            0);
  r = tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs mask --out " + pinch);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(pinch + ": holds a render of several sensors (sensors.json)"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(sensor_dataset_dirs(pinch).size(), 2u);
  EXPECT_FALSE(fs::exists(pinch + "/dataset.json"));
  // A folder of datasets is named as such (it had said "one per sensor" of any).
  r = tacsim("info " + tmp.path.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(tmp.path.string() + ": is not a dataset, but holds datasets: d; give one "
                                           "of those folders"),
            std::string::npos)
      << r.out;
  r = tacsim("render " + kScenes + "examples/no_contact.json -q --outputs mask --out " + d);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(Dataset::open(d).frames(), 5);
  // A real sensor's recording (patchgraph recording's sources.csv) or presses labelled by
  // label-ball (circles.csv) is no render's to replace: their frames or labels would be lost.
  for (const auto& [file, what] : std::vector<std::pair<std::string, std::string>>{
           {"sources.csv", "holds a recording of a real sensor (sources.csv)"},
           {"circles.csv", "holds presses labelled by label-ball (circles.csv"}}) {
    std::ofstream(d + "/" + file) << "frame,file\n";
    r = tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs mask --out " + d);
    EXPECT_EQ(r.code, 1) << r.out;
    EXPECT_NE(r.out.find(d + ": " + what), std::string::npos) << r.out;
    EXPECT_EQ(Dataset::open(d).frames(), 5);
    EXPECT_TRUE(fs::exists(d + "/" + file));
    fs::remove(d + "/" + file);
  }

  // A two-sensor scene into a folder of other files, one of them a sensors.json of its own
  // (the render's index has that name): refused, nothing written (it had been replaced).
  const std::string project = tmp.str("project");
  fs::create_directories(project);
  std::ofstream(project + "/README.txt") << "my notes\n";
  std::ofstream(project + "/sensors.json") << "{\"sensors\": [\"my own\"]}\n";
  r = tacsim("render " + kScenes + "examples/two_digits_pinch.json -q --outputs mask --out " +
             project);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(project + ": is not empty and holds no earlier render of several sensors"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(testing_support::file_text(project + "/sensors.json"), "{\"sensors\": [\"my own\"]}\n");
  EXPECT_FALSE(fs::exists(project + "/digit_bottom"));
  EXPECT_FALSE(fs::exists(project + "/digit_top"));

  // A link to a folder that is not there (it had read "cannot create the output folder: File
  // exists").
  fs::create_symlink(tmp.str("gone"), tmp.str("link"));
  r = tacsim("render " + kScenes + "examples/sphere_press.json -q --outputs mask --out " +
             tmp.str("link"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(tmp.str("link") + ": cannot create the output folder: a symbolic link to " +
                       tmp.str("gone") + ", which does not exist"),
            std::string::npos)
      << r.out;
}

// Ctrl-C stops a render at its next frame: exit 130 and a message naming the unfinished dataset,
// which does not open (no poses.csv) and which a render replaces.
TEST(TacsimCli, CtrlCStopsARenderAndSaysWhatItLeaves) {
  TempDir tmp;
  const std::string d = tmp.str("d");
  const CliRun r = testing_support::run_and_signal(
      TACSIM_PATH,
      // One thread: the render lasts about a second after it starts, on a machine of any size.
      "render " + kScenes + "benchmark/cube_00.json --threads 1 --outputs color,mask --out " + d,
      "rendering ", SIGINT, tmp.str("log"));
  EXPECT_EQ(r.code, 130) << r.out;
  EXPECT_NE(
      r.out.find("error: interrupted (SIGINT, Ctrl-C): " + d + " holds an unfinished dataset"),
      std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(d + "/poses.csv"));
  testing_support::expect_input_error([&] { Dataset::open(d); }, {"poses.csv"});
  ASSERT_EQ(tacsim("render " + kScenes + "benchmark/cube_00.json -q --frames 3 --out " + d).code,
            0);
  EXPECT_EQ(Dataset::open(d).frames(), 3);
}

// A benchmark stopped part-way leaves an earlier report as it was (the file was emptied as the
// benchmark started); a finished one replaces it whole.
TEST(TacsimCli, AStoppedBenchmarkLeavesTheEarlierReport) {
  TempDir tmp;
  const std::string md = tmp.str("bench.md");
  std::ofstream(md) << "the earlier report\n";
  const std::string bench = "bench --quick --frames 100 --repeats 2 --threads 1 --markdown " + md;
  const CliRun stopped =
      testing_support::run_and_signal(TACSIM_PATH, bench, "| (a)", SIGINT, tmp.str("log"));
  ASSERT_NE(stopped.out.find("| (a)"), std::string::npos) << stopped.out;
  EXPECT_NE(stopped.code, 0) << "the benchmark ended before the signal came";
  EXPECT_EQ(testing_support::file_text(md), "the earlier report\n");
  const CliRun done = tacsim("bench --quick --frames 2 --repeats 1 --markdown " + md);
  ASSERT_EQ(done.code, 0) << done.out;
  const std::string report = testing_support::file_text(md);
  EXPECT_EQ(report.rfind("Command: `tacsim bench", 0), 0u) << report;
  EXPECT_NE(report.find("| (d) 200k-triangle sphere pressed 1 mm | 240x320 | on |"),
            std::string::npos)
      << report;
}

// A render that the disk cannot hold is refused before anything is written (it would stop
// half-way with a full disk); an earlier dataset in the folder stays whole. The render line says
// how much a render wrote.
TEST(TacsimCli, ARenderTheDiskCannotHoldIsRefusedBeforeWriting) {
  TempDir tmp;
  const std::string d = tmp.str("d");
  CliRun r = tacsim("render " + kScenes + "examples/sphere_press.json -q --out " + d);
  ASSERT_EQ(r.code, 0) << r.out;
  std::uintmax_t bytes = 0;
  for (const auto& entry : fs::recursive_directory_iterator(d)) {
    if (entry.is_regular_file()) bytes += entry.file_size();
  }
  char written[32];
  std::snprintf(written, sizeof written, "(%.1f MB)", bytes / 1e6);
  EXPECT_NE(r.out.find(d + " " + written), std::string::npos) << r.out;
  // Ten million frames of the same press at 240x320, all outputs: about 10 TB.
  std::string scene;
  {
    std::ifstream in(kScenes + "examples/sphere_press.json");
    scene.assign(std::istreambuf_iterator<char>(in), {});
  }
  const auto replace = [&scene](const std::string& from, const std::string& to) {
    scene.replace(scene.find(from), from.size(), to);
  };
  replace("\"frames\": 10", "\"frames\": 10000000");
  replace("../../meshes/", std::string(PG_SOURCE_DIR) + "/meshes/");
  std::ofstream(tmp.str("long.json")) << scene;
  if (fs::space(tmp.str("")).available > 5'000'000'000'000ull) {
    GTEST_SKIP() << "this disk could hold the render";
  }
  const std::string outputs =
      " -q --width 240 --height 320 --outputs color,normal,depth,mask,points";
  r = tacsim("render " + tmp.str("long.json") + outputs + " --out " + tmp.str("new"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(tmp.str("new") + ": the render needs about "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(10000000 frames x 1 sensor(s)) and the disk holding it has "),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("new")));
  r = tacsim("render " + tmp.str("long.json") + outputs + " --out " + d);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("free, with the earlier dataset's frames it would replace"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(Dataset::open(d).frames(), 10);
  EXPECT_EQ(Dataset::open(d).info().width(), 120);
  EXPECT_NO_THROW(Dataset::open(d).color(9));
}

TEST(TacsimCli, OverridesAreCheckedAndFileErrorsSayWhereTheSceneNamesTheFile) {
  TempDir tmp;
  const std::string scene = kScenes + "examples/sphere_press.json";
  // One side alone would scale only that side's focal length: stretched pixels.
  CliRun r = tacsim("render " + scene + " --width 240 --out " + tmp.str("d"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--width requires --height"), std::string::npos) << r.out;
  EXPECT_EQ(tacsim("sheet " + scene + " --height 80 --out " + tmp.str("s.png")).code, 2);
  // --frames renders the scene's first frames, as the whole render has them; no more than it has.
  ASSERT_EQ(
      tacsim("render " + scene + " -q --frames 3 --outputs color --out " + tmp.str("f3")).code, 0);
  ASSERT_EQ(tacsim("render " + scene + " -q --outputs color --out " + tmp.str("all")).code, 0);
  EXPECT_EQ(Dataset::open(tmp.str("f3")).frames(), 3);
  EXPECT_EQ(Dataset::open(tmp.str("f3")).color(2).data,
            Dataset::open(tmp.str("all")).color(2).data);
  EXPECT_EQ(Dataset::open(tmp.str("f3")).poses()[2].T_world_object.translation(),
            Dataset::open(tmp.str("all")).poses()[2].T_world_object.translation());
  r = tacsim("render " + scene + " --frames 11 --out " + tmp.str("f11"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--frames 11: " + scene + " has 10 frames"), std::string::npos) << r.out;
  EXPECT_EQ(tacsim("render " + scene + " --frames 0 --out " + tmp.str("f0")).code, 2);
  r = tacsim("render " + scene + " --outputs '' --out " + tmp.str("d"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--outputs: an empty value"), std::string::npos) << r.out;
  r = tacsim("render " + scene + " --out ''");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--out: an empty value"), std::string::npos) << r.out;
  r = tacsim("render " + scene + " --outputs mask,mask --out " + tmp.str("d"));
  EXPECT_NE(r.out.find("--outputs: output 'mask' is given twice"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("d")));

  std::ofstream(tmp.str("scene.json"))
      << R"({"frames": 2, "sensors": [{}], "objects": [{"mesh": "missing.glb"}],
             "render": {"background": "Synthetic"}})";
  r = tacsim("render " + tmp.str("scene.json") + " --out " + tmp.str("d"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find(tmp.str("scene.json") + ": objects[0].mesh: " + tmp.str("missing.glb") +
                       ": file not found"),
            std::string::npos)
      << r.out;
  // A background missing, or one the renderer cannot use (grey), is named where the scene gives
  // it: render.background.
  // A float image with a NaN had been clamped to black and rendered as a mostly clipped one.
  write_image(tmp.str("grey.png"), ImageU8(160, 120, 1));
  ImageF not_finite(120, 160, 3);
  std::fill(not_finite.data.begin(), not_finite.data.end(), 0.5f);
  not_finite.at(7, 3, 1) = std::numeric_limits<float>::quiet_NaN();
  write_image(tmp.str("nan.exr"), not_finite);
  for (const auto& [background, complaint] :
       {std::pair<std::string, std::string>{"Synthetic",
                                            ": no such image file (give an image, or synthetic "
                                            "or none)"},
        {"grey.png", ": 1 channel (grey); a background image must be RGB"},
        {"nan.exr", ": pixel (7, 3) channel 1 is not a finite number"}}) {
    std::ofstream(tmp.str("scene.json"))
        << R"({"frames": 2, "sensors": [{}], "objects": [{"mesh": ")" << PG_SOURCE_DIR
        << R"(/meshes/cube.glb"}], "render": {"background": ")" << background << R"("}})";
    r = tacsim("render " + tmp.str("scene.json") + " --out " + tmp.str("d"));
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.out.find(tmp.str("scene.json") + ": render.background: " + tmp.str(background) +
                         complaint),
              std::string::npos)
        << r.out;
    EXPECT_FALSE(fs::exists(tmp.str("d")));
  }
}

TEST(TacsimCli, NoContactSceneRendersBackgroundAndSaysSoOnce) {
  TempDir tmp;
  const CliRun r =
      tacsim("render " + kScenes + "examples/no_contact.json -q --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string warning = "no object touches the gel";
  const auto first = r.out.find(warning);
  ASSERT_NE(first, std::string::npos) << r.out;
  EXPECT_EQ(r.out.find(warning, first + 1), std::string::npos) << "said more than once";
  const Dataset d = Dataset::open(tmp.str("d"));
  for (const auto& p : d.poses()) EXPECT_FALSE(p.contact);
}

// The dataset's poses are the tracked object's: a frame where only another object touches the
// gel would be tracked as its motion. Said, with the count (a cube hovering 5 mm above the gel
// while a sphere presses in 4 of 6 frames); not said when the tracked object is the one pressing.
// Another object pressing beside the tracked one is said too.
TEST(TacsimCli, OtherObjectsTouchingWithoutTheTrackedOneAreWarnedAbout) {
  TempDir tmp;
  const std::string meshes = std::string(PG_SOURCE_DIR) + "/meshes/";
  const auto scene = [&](const std::string& tracked) {
    std::ofstream(tmp.str(tracked + ".json"))
        << R"({"frames": 6, "sensors": [{}], "render": {"outputs": ["normal"]},
               "objects": [{"name": "cube", "mesh": ")"
        << meshes << R"(cube.glb", "pose": {"position": [0.0, 0.0, 0.015]}},
               {"name": "sphere", "mesh": ")"
        << meshes << R"(sphere_r6mm.glb", "trajectory": {"poses": [
                 {"position": [0.0, 0.0, 0.007]}, {"position": [0.0, 0.0, 0.007]},
                 {"position": [0.0, 0.0, 0.005]}, {"position": [0.0, 0.0, 0.005]},
                 {"position": [0.0, 0.0, 0.005]}, {"position": [0.0, 0.0, 0.005]}]}}],
               "tracked_object": ")"
        << tracked << R"("})";
    return tacsim("render " + tmp.str(tracked + ".json") + " -q --out " + tmp.str(tracked));
  };
  const std::string warning = "warning: " + tmp.str("cube.json") +
                              ": in 4 of the 4 contact frames only objects other than the tracked "
                              "one ('cube', tracked_object) touch the gel";
  CliRun r = scene("cube");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(warning), std::string::npos) << r.out;
  r = scene("sphere");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("only objects other than"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("along with the tracked one"), std::string::npos) << r.out;
  // Two spheres pressing side by side: the tracker would take both for the tracked one (it had
  // not been said).
  std::ofstream(tmp.str("two.json"))
      << R"({"frames": 3, "sensors": [{}], "render": {"outputs": ["mask"]},
             "objects": [{"name": "a", "mesh": ")"
      << meshes << R"(sphere_r4mm.glb", "pose": {"position": [-0.005, 0.0, 0.0035]}},
             {"name": "b", "mesh": ")"
      << meshes << R"(sphere_r4mm.glb", "pose": {"position": [0.005, 0.0, 0.0035]}}]})";
  r = tacsim("render " + tmp.str("two.json") + " -q --out " + tmp.str("two"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: " + tmp.str("two.json") +
                       ": in 3 of the 3 contact frames another object ('b') touches the gel along "
                       "with the tracked one ('a')"),
            std::string::npos)
      << r.out;
  // Two sensors, each pressed by one sphere: the second sensor's dataset holds only the other
  // sphere's contact, said of that sensor (it had been said of no sensor: the tracked one touched
  // the first sensor in the same frames).
  std::ofstream(tmp.str("apart.json"))
      << R"({"frames": 3, "render": {"outputs": ["mask"]},
             "sensors": [{"name": "near"}, {"name": "far", "pose": {"position": [0.1, 0.0, 0.0]}}],
             "objects": [{"name": "a", "mesh": ")"
      << meshes << R"(sphere_r4mm.glb", "pose": {"position": [0.0, 0.0, 0.0035]}},
             {"name": "b", "mesh": ")"
      << meshes << R"(sphere_r4mm.glb", "pose": {"position": [0.1, 0.0, 0.0035]}}]})";
  r = tacsim("render " + tmp.str("apart.json") + " -q --out " + tmp.str("apart"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: " + tmp.str("apart.json") +
                       ": sensor 'far': in 3 of its 3 contact frames only objects other than the "
                       "tracked one ('a', tracked_object) touch its gel ('b')"),
            std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find("sensor 'near'"), std::string::npos) << r.out;
}

// Scenes whose sensors differ in image size share one sheet: every cell is as large as the
// largest image (the sheet was sized from the first scene and a larger image overran it).
TEST(TacsimCli, SheetOfScenesWithDifferentImageSizes) {
  TempDir tmp;
  std::ifstream in(kScenes + "examples/sphere_press.json");
  std::string scene((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string digit = "\"sensor\": \"digit\"";
  ASSERT_NE(scene.find(digit), std::string::npos);
  scene.replace(scene.find(digit), digit.size(), "\"sensor\": \"gelsight_mini\"");
  const std::string mesh = "../../meshes/";
  scene.replace(scene.find(mesh), mesh.size(), std::string(PG_SOURCE_DIR) + "/meshes/");
  std::ofstream(tmp.str("mini.json")) << scene;

  const CliRun r =
      tacsim("sheet " + kScenes + "examples/sphere_press.json " + tmp.str("mini.json") + " " +
             kScenes + "examples/sphere_press.json --out " + tmp.str("s.png"));
  ASSERT_EQ(r.code, 0) << r.out;
  const ImageU8 sheet = read_image_u8(tmp.str("s.png"));
  const int gap = 4;  // cells of 240x320 (gelsight_mini), three columns, three rows
  ASSERT_EQ(sheet.width, 3 * 240 + 2 * gap);
  ASSERT_EQ(sheet.height, 3 * 320 + 2 * gap);
  // The 120x160 DIGIT image sits centred in its cell: white around it, the image inside.
  EXPECT_EQ(sheet.at(10, 10, 0), 255);
  EXPECT_EQ(sheet.at(10, 10, 1), 255);
  const std::uint8_t* centre = &sheet.at(120, 160, 0);
  EXPECT_FALSE(centre[0] == 255 && centre[1] == 255 && centre[2] == 255);
  // An --out that cannot be written is refused before any scene is rendered.
  for (const auto& [out, text] :
       {std::pair<std::string, std::string>{tmp.str("s.txt"), "no image writer"},
        {tmp.str("none/s.png"), "is not a folder"},
        {tmp.str(), "is a folder"}}) {
    const CliRun bad = tacsim("sheet " + kScenes + "examples/sphere_press.json --out " + out);
    EXPECT_EQ(bad.code, 1) << out;
    EXPECT_NE(bad.out.find(text), std::string::npos) << bad.out;
    EXPECT_EQ(bad.out.find("frame 0"), std::string::npos) << "rendered first: " << bad.out;
  }
}

TEST(TacsimCli, BackgroundThatIsADirectorySaysSo) {
  TempDir tmp;
  const CliRun r = tacsim("render " + kScenes + "examples/sphere_press.json -q --background " +
                          tmp.str() + " --out " + tmp.str("d"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("is a directory, not an image file"), std::string::npos) << r.out;
}

// `tacsim presses` writes a scene of random presses that renders one press per frame, of the
// asked depth and inside the image; one seed writes one file; bad options are named.
// A file output inside a dataset (a contact sheet over one of its frames, a presses scene over its
// poses.csv) is refused before anything is written, as patchgraph refuses one: it had replaced
// the dataset's file with exit 0. A presses scene is a .json. A file of another kind at the
// output's path is left as it is.
TEST(TacsimCli, AFileOutputInsideADatasetIsRefused) {
  TempDir tmp;
  ASSERT_EQ(tacsim("render " + kScenes + "default.json -q --frames 3 --out " + tmp.str("d")).code,
            0);
  const std::string mesh = std::string(PG_SOURCE_DIR) + "/meshes/cube.glb";
  const auto bytes = [&](const std::string& file) {
    return testing_support::file_text(tmp.str("d/" + file));
  };
  const std::string poses = bytes("poses.csv"), frame = bytes("color/000001.png"),
                    normal = bytes("normal/000001.exr");
  for (const auto& [args, where] : std::vector<std::pair<std::string, std::string>>{
           {"presses " + mesh + " --frames 2 --out " + tmp.str("d/poses.json"),
            " is in a folder that holds a dataset (dataset.json)"},
           {"sheet " + kScenes + "examples/sphere_press.json --out " +
                tmp.str("d/color/000001.png"),
            " is inside " + tmp.str("d") + ", which holds a dataset (dataset.json)"},
           {"sensitivity --out " + tmp.str("d/normal/000001.exr"),
            " is inside " + tmp.str("d") + ", which holds a dataset"}}) {
    const CliRun r = tacsim(args);
    EXPECT_EQ(r.code, 1) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(where), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("write the outputs to another folder"), std::string::npos) << r.out;
  }
  EXPECT_EQ(bytes("poses.csv"), poses);
  EXPECT_EQ(bytes("color/000001.png"), frame);
  EXPECT_EQ(bytes("normal/000001.exr"), normal);
  EXPECT_FALSE(fs::exists(tmp.str("d/poses.json")));
  EXPECT_EQ(tacsim("info --check " + tmp.str("d")).code, 0);
  const CliRun csv = tacsim("presses " + mesh + " --frames 2 --out " + tmp.str("p.csv"));
  EXPECT_EQ(csv.code, 2) << csv.out;
  EXPECT_NE(csv.out.find("a scene file is JSON; give a .json file"), std::string::npos) << csv.out;
  EXPECT_FALSE(fs::exists(tmp.str("p.csv")));
  // Beside a dataset, not in it: written, and written again over itself.
  EXPECT_EQ(tacsim("presses " + mesh + " --frames 2 --out " + tmp.str("p.json")).code, 0);
  EXPECT_EQ(tacsim("presses " + mesh + " --frames 3 --out " + tmp.str("p.json")).code, 0);
  // The benchmark's report is a file output too (it had replaced a dataset's poses.csv).
  const CliRun md =
      tacsim("bench --quick --repeats 1 --frames 2 --markdown " + tmp.str("d/poses.csv"));
  EXPECT_EQ(md.code, 1) << md.out;
  EXPECT_NE(
      md.out.find("--markdown " + tmp.str("d/poses.csv") + " is in a folder that holds a dataset"),
      std::string::npos)
      << md.out;
  EXPECT_EQ(bytes("poses.csv"), poses);
  // A file of another kind than the command writes is left as it is (a scene written over a
  // trained model, a bound map over a PNG); one of its own kind is replaced (above).
  fs::copy_file(std::string(PG_SOURCE_DIR) + "/models/normals_mlp.pt", tmp.str("model.json"));
  fs::copy_file(tmp.str("d/color/000001.png"), tmp.str("frame.exr"));
  for (const auto& [args, held] : std::vector<std::pair<std::string, std::string>>{
           {"presses " + mesh + " --frames 2 --out " + tmp.str("model.json"), "a zip archive"},
           {"sensitivity --out " + tmp.str("frame.exr"), "a PNG image"},
           {"bench --quick --repeats 1 --frames 2 --markdown " + tmp.str("model.json"),
            "a zip archive"}}) {
    const CliRun r = tacsim(args);
    EXPECT_EQ(r.code, 1) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(": holds " + held), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("It is left as it is"), std::string::npos) << r.out;
  }
  EXPECT_EQ(testing_support::file_text(tmp.str("model.json")),
            testing_support::file_text(std::string(PG_SOURCE_DIR) + "/models/normals_mlp.pt"));
  // A contact sheet's name without an extension, which chooses the format: said so (it had
  // read as OpenImageIO's "could not find a format writer").
  const CliRun sheet =
      tacsim("sheet " + kScenes + "examples/sphere_press.json --out " + tmp.str("sheet"));
  EXPECT_EQ(sheet.code, 1) << sheet.out;
  EXPECT_NE(sheet.out.find("no file extension to choose the image format by"), std::string::npos)
      << sheet.out;
}

TEST(TacsimCli, PressesWriteASceneOfOnePressPerFrame) {
  TempDir tmp;
  // The mesh beside the scenes' folder, which does not exist yet: made, and the mesh named
  // relative to it, as the repository's scenes name theirs.
  fs::create_directories(tmp.str("meshes"));
  fs::copy_file(std::string(PG_SOURCE_DIR) + "/meshes/toy_brick.glb",
                tmp.str("meshes/toy_brick.glb"));
  const std::string mesh = tmp.str("meshes/toy_brick.glb");
  const std::string args = "presses " + mesh + " --frames 8 --min-depth 0.0005 --max-depth 0.001";
  CliRun r = tacsim(args + " --seed 3 --out " + tmp.str("scenes/brick.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("8 random presses"), std::string::npos) << r.out;
  // A progress line (a million presses take about 90 minutes), which -q leaves out.
  EXPECT_NE(r.out.find("presses 8/8 presses"), std::string::npos) << r.out;
  EXPECT_EQ(tacsim(args + " -q --out " + tmp.str("quiet.json")).out.find("8/8"), std::string::npos);
  r = tacsim("render " + tmp.str("scenes/brick.json") +
             " -q --elastic off --outputs depth,mask --out " + tmp.str("d"));
  ASSERT_EQ(r.code, 0) << r.out;
  const Dataset d = Dataset::open(tmp.str("d"));
  ASSERT_EQ(d.frames(), 8);
  EXPECT_EQ(d.info().object_name, "toy_brick");
  for (int f = 0; f < d.frames(); ++f) {
    const ImageF depth = d.depth(f);
    const ImageU8 mask = d.mask(f);
    float deepest = 0;
    int touched = 0, at_edge = 0;
    for (int y = 0; y < depth.height; ++y) {
      for (int x = 0; x < depth.width; ++x) {
        deepest = std::max(deepest, depth.at(x, y, 0));
        if (mask.at(x, y, 0) == 0) continue;
        ++touched;
        at_edge += x == 0 || y == 0 || x == depth.width - 1 || y == depth.height - 1;
      }
    }
    // The render's indentation is along the camera's rays, a little longer than along z.
    EXPECT_GT(deepest, 0.5e-3 - 2e-5) << "frame " << f;
    EXPECT_LT(deepest, 1.0e-3 * 1.1) << "frame " << f;
    EXPECT_GT(touched, 20) << "frame " << f;
    EXPECT_EQ(at_edge, 0) << "frame " << f;
  }
  // One seed, one file; another seed, other presses.
  ASSERT_EQ(tacsim(args + " --seed 3 --out " + tmp.str("scenes/again.json")).code, 0);
  ASSERT_EQ(tacsim(args + " --seed 4 --out " + tmp.str("scenes/other.json")).code, 0);
  const auto text = [&](const std::string& name) {
    std::ifstream in(tmp.str(name));
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  };
  EXPECT_NE(text("scenes/brick.json").find("\"mesh\": \"../meshes/toy_brick.glb\""),
            std::string::npos);
  EXPECT_EQ(text("scenes/again.json"), text("scenes/brick.json"));
  EXPECT_NE(text("scenes/other.json"), text("scenes/brick.json"));
  // The default depths follow the gel (0.3-1.5 mm on the DIGIT's 2 mm); only --max-depth
  // given: the shallowest press follows it (a fifth of it).
  r = tacsim("presses " + mesh + " --frames 2 --out " + tmp.str("default_depths.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("mm deep (asked 0.30-1.50)"), std::string::npos) << r.out;
  r = tacsim("presses " + mesh + " --frames 2 --max-depth 0.0002 --out " + tmp.str("shallow.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("mm deep (asked 0.04-0.20)"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("reach only"), std::string::npos) << r.out;
  // A sensor that sees little of its gel: deep presses of a 12 mm sphere leave its view and are
  // drawn again, so the presses are shallower than asked; said so.
  std::ofstream(tmp.str("narrow.json")) << R"({"camera": {"fov_y_rad": 0.35}})";
  r = tacsim("presses " + std::string(PG_SOURCE_DIR) + "/meshes/sphere_r6mm.glb --frames 30 " +
             "--sensor-file " + tmp.str("narrow.json") + " --out " + tmp.str("narrow_scene.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: the presses reach only"), std::string::npos) << r.out;
  // Another sensor is the scene's.
  ASSERT_EQ(tacsim(args + " --sensor gelsight_mini --out " + tmp.str("mini.json")).code, 0);
  EXPECT_NE(text("mini.json").find("\"sensor\": \"gelsight_mini\""), std::string::npos);
  // The command it suggests runs as printed, whatever the scene's name.
  r = tacsim(args + " --out \"" + tmp.str("it's mine.json") + "\"");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(
      r.out.find("render it: tacsim render '" + tmp.str("it'\\''s mine.json") + "' --out DIR"),
      std::string::npos)
      << r.out;

  // Bad option values are usage errors (exit 2), a file that cannot be read an input error (1).
  for (const auto& [bad, says, code] : std::vector<std::tuple<std::string, std::string, int>>{
           {" --max-depth 1.5", "--max-depth = 1.5: must be from 1e-06 to 0.002 [m]", 2},
           {" --min-depth 0.002 --max-depth 0.001", "--min-depth = 0.002", 2},
           {" --sensor digit2", "--sensor: unknown sensor preset 'digit2'", 2},
           {" --sensor-file " + tmp.str("none.json"), "none.json", 1}}) {
    r = tacsim("presses " + mesh + bad + " --out " + tmp.str("bad.json"));
    EXPECT_EQ(r.code, code) << bad;
    EXPECT_NE(r.out.find(says), std::string::npos) << r.out;
  }
  r = tacsim("presses " + tmp.str("none.glb") + " --out " + tmp.str("bad.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("none.glb"), std::string::npos) << r.out;
  r = tacsim("presses " + mesh + " --out " + tmp.str());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("is a folder"), std::string::npos) << r.out;
  r = tacsim("presses " + mesh + " --out " + mesh);
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("is the mesh"), std::string::npos) << r.out;
  // A scale slip: the object thinner than the deepest press.
  r = tacsim("presses " + mesh + " --scale 1e-4 --out " + tmp.str("bad.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("no thicker than the deepest press"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("bad.json")));
  // The other slip, millimetres read as metres (a 12 m sphere's presses had reached past the
  // image's edges while the tool reported them inside).
  r = tacsim("presses " + mesh + " --scale 1000 --out " + tmp.str("bad.json"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("31.8 x 15.8 x 11.3 m, larger than a metre"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(tmp.str("bad.json")));
  EXPECT_EQ(tacsim("presses " + mesh + " --sensor digit --sensor-file x.json --out " +
                   tmp.str("bad.json"))
                .code,
            2);
}

}  // namespace
}  // namespace pg
