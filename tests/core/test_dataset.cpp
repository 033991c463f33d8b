#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "../common/test_support.h"
#include "pg/core/csv.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/json_fields.h"
#include "pg/core/module.h"
#include "pg/core/point_io.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using testing_support::TempDir;

template <typename F>
void expect_input_error(F&& f, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "expected an InputError mentioning '" << part << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos) << e.what();
  }
}

FrameImages make_frame(int w, int h, int k) {
  FrameImages f;
  f.color = ImageU8(w, h, 3);
  f.normal = ImageF(w, h, 3);
  f.depth = ImageF(w, h, 1);
  f.mask = ImageU8(w, h, 1);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      for (int c = 0; c < 3; ++c) f.color.at(x, y, c) = std::uint8_t((x * 7 + y * 3 + c + k) % 256);
      const Eigen::Vector3f n =
          Eigen::Vector3f(0.01f * x - 0.3f, 0.02f * y - 0.1f, 1.0f).normalized();
      for (int c = 0; c < 3; ++c) f.normal.at(x, y, c) = n[c];
      f.depth.at(x, y) = 1e-4f * float(x + k) + 1e-7f * y;
      f.mask.at(x, y) = ((x + y + k) % 3 == 0) ? 255 : 0;
    }
  }
  return f;
}

DatasetInfo small_info(int frames) {
  DatasetInfo info;
  info.sensor = sensor_preset("digit");
  info.sensor.camera = info.sensor.camera.resized(24, 32);
  info.frames = frames;
  info.fps = 30;
  info.outputs = {"color", "normal", "depth", "mask"};
  info.scene = "scenes/x.json";
  info.seed = 42;
  info.object_name = "cube";
  info.object_mesh = "/tmp/cube.glb";
  return info;
}

std::vector<FramePose> write_small(const std::string& dir, int frames) {
  DatasetWriter writer(dir, small_info(frames));
  std::vector<FramePose> poses;
  for (int i = frames - 1; i >= 0; --i) {  // any order
    FramePose p;
    p.frame = i;
    p.time_s = i / 30.0;
    p.T_world_object = pose_from_position_rpy({0.001 * i, -0.002, 0.003}, {0.1 * i, 0.2, -0.3});
    p.T_world_sensor = pose_from_position_rpy({0, 0.01, 0}, {0, 0, 0.5});
    p.contact = i % 2 == 0;
    writer.write_frame(p, make_frame(24, 32, i));
    poses.insert(poses.begin(), p);
  }
  writer.finish();
  return poses;
}

// A CSV line's cells: split on commas, but a quoted cell (RFC 4180, as label-ball writes its
// reasons) keeps its commas and its doubled quotes.
TEST(Csv, QuotedCellsKeepTheirCommasAndQuotes) {
  using Cells = std::vector<std::string>;
  EXPECT_EQ(csv_cells("1,2.5,,x"), (Cells{"1", "2.5", "", "x"}));
  EXPECT_EQ(csv_cells("3,,no_press,\"0 px differ, fewer than a press\""),
            (Cells{"3", "", "no_press", "0 px differ, fewer than a press"}));
  EXPECT_EQ(csv_cells("\"a \"\"b\"\", c\",d"), (Cells{"a \"b\", c", "d"}));
  EXPECT_EQ(csv_cells("\"\",1"), (Cells{"", "1"}));
  // A decimal comma stays two cells (the readers then refuse the row's extra cell).
  EXPECT_EQ(csv_cells("17,589"), (Cells{"17", "589"}));
  // A quote inside an unquoted cell is text; a line ending inside a quote ends the cell.
  EXPECT_EQ(csv_cells("5 \"in\",x"), (Cells{"5 \"in\"", "x"}));
  EXPECT_EQ(csv_cells("1,\"open, cell"), (Cells{"1", "open, cell"}));
}

TEST(Dataset, RoundTrip) {
  TempDir tmp;
  const auto poses = write_small(tmp.str("d"), 3);
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_EQ(d.frames(), 3);
  EXPECT_EQ(d.info().width(), 24);
  EXPECT_EQ(d.info().height(), 32);
  EXPECT_EQ(d.info().seed, 42u);
  EXPECT_EQ(d.info().object_name, "cube");
  EXPECT_NEAR(d.info().sensor.camera.fx, small_info(1).sensor.camera.fx, 1e-12);
  ASSERT_EQ(d.poses().size(), 3u);
  for (int i = 0; i < 3; ++i) {
    const auto& a = poses[i];
    const auto& b = d.poses()[i];
    EXPECT_EQ(b.frame, i);
    EXPECT_DOUBLE_EQ(b.time_s, a.time_s);
    EXPECT_NEAR(ominus(a.T_world_object, b.T_world_object).norm(), 0, 1e-12);
    EXPECT_NEAR(ominus(a.T_world_sensor, b.T_world_sensor).norm(), 0, 1e-12);
    EXPECT_EQ(b.contact, a.contact);
    const FrameImages want = make_frame(24, 32, i);
    EXPECT_EQ(d.color(i).data, want.color.data);
    EXPECT_EQ(d.normal(i).data, want.normal.data);  // EXR float is lossless
    EXPECT_EQ(d.depth(i).data, want.depth.data);
    EXPECT_EQ(d.mask(i).data, want.mask.data);
  }
}

TEST(Dataset, OnlyRequestedOutputsAreWritten) {
  TempDir tmp;
  DatasetInfo info = small_info(1);
  info.outputs = {"depth"};
  DatasetWriter w(tmp.str("d"), info);
  w.write_frame(FramePose{}, make_frame(24, 32, 0));
  w.finish();
  EXPECT_TRUE(fs::exists(tmp.str("d/depth/000000.exr")));
  EXPECT_FALSE(fs::exists(tmp.str("d/color")));
  const Dataset d = Dataset::open(tmp.str("d"));
  expect_input_error([&] { d.color(0); }, "no 'color' output");
}

TEST(Dataset, WriterRejectsWrongSize) {
  TempDir tmp;
  DatasetWriter w(tmp.str("d"), small_info(1));
  FrameImages f = make_frame(24, 32, 0);
  f.depth = ImageF(10, 10, 1);
  expect_input_error([&] { w.write_frame(FramePose{}, f); }, "depth/000000.exr");
}

TEST(Dataset, ReaderRejectsMissingFiles) {
  TempDir tmp;
  write_small(tmp.str("d"), 3);
  fs::remove(tmp.str("d/normal/000001.exr"));
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "normal/000001.exr");
  expect_input_error([&] { Dataset::open(tmp.str("nothing")); },
                     "nothing: dataset folder not found");
  // A file of the dataset given for its folder is named as a file.
  expect_input_error([&] { Dataset::open(tmp.str("d/dataset.json")); },
                     "d/dataset.json: is a file, not a dataset folder");
  fs::remove(tmp.str("d/poses.csv"));
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "poses.csv");
}

// An image size that disagrees with the sensor's camera names the field that differs (a height
// had been reported as width) and the camera's size.
TEST(Dataset, AnImageSizeOtherThanTheCamerasNamesItsField) {
  TempDir tmp;
  write_small(tmp.str("d"), 2);
  const std::string path = tmp.str("d/dataset.json");
  nlohmann::json j = parse_json_file(path);
  const int height = j["height"].get<int>();
  j["height"] = height + 8;
  std::ofstream(path) << j.dump(2);
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     path + ": height: image size " + std::to_string(j["width"].get<int>()) + "x" +
                         std::to_string(height + 8) + " disagrees with the sensor's camera");
}

// Writing a shorter dataset with fewer outputs into the folder of an earlier one leaves one
// dataset: the earlier frames past the new last one and its other outputs' frames are gone, and
// label-ball's circles.csv of them, and a background.png the new one did not write; files that
// are not a dataset's frames stay.
TEST(Dataset, WriterRemovesAnEarlierDatasetsStaleFrames) {
  TempDir tmp;
  const std::string dir = tmp.str("d");
  write_small(dir, 5);
  std::ofstream(dir + "/color/notes.txt") << "mine";
  std::ofstream(dir + "/color/4.png") << "mine";  // a number, but not a frame file's name
  std::ofstream(dir + "/normal/notes.txt") << "mine";
  std::ofstream(dir + "/circles.csv") << "frame,u_px,v_px,radius_px\n";  // label-ball's
  std::ofstream(dir + "/sources.csv") << "frame,file\n";                 // recording's
  std::ofstream(dir + "/README.txt") << "mine";
  std::ofstream(dir + "/background.png") << "the earlier dataset's";
  DatasetInfo info = small_info(2);
  info.outputs = {"color"};
  // Labelled presses are label-ball's to replace (a render's writer is refused: the labels may
  // have been corrected by hand), and with them the recording's list of its files.
  try {
    DatasetWriter render(dir, info);
    ADD_FAILURE() << "a render's writer replaced labelled presses";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(dir + ": holds presses labelled by label-ball"),
              std::string::npos)
        << e.what();
  }
  EXPECT_TRUE(fs::exists(dir + "/circles.csv"));
  EXPECT_TRUE(fs::exists(dir + "/color/000004.png"));
  DatasetWriter writer(dir, info, DatasetMaker::kLabelBall);
  for (int i = 0; i < 2; ++i) {
    FramePose p;
    p.frame = i;
    writer.write_frame(p, make_frame(24, 32, i));
  }
  writer.finish();
  EXPECT_TRUE(fs::exists(dir + "/color/000001.png"));
  EXPECT_FALSE(fs::exists(dir + "/color/000002.png"));
  EXPECT_FALSE(fs::exists(dir + "/color/000004.png"));
  EXPECT_TRUE(fs::exists(dir + "/color/notes.txt"));
  EXPECT_TRUE(fs::exists(dir + "/color/4.png"));
  EXPECT_FALSE(fs::exists(dir + "/normal/000000.exr"));
  EXPECT_TRUE(fs::exists(dir + "/normal/notes.txt"));
  EXPECT_FALSE(fs::exists(dir + "/depth"));
  EXPECT_FALSE(fs::exists(dir + "/mask"));
  EXPECT_FALSE(fs::exists(dir + "/circles.csv")) << "the earlier frames' circles";
  EXPECT_FALSE(fs::exists(dir + "/sources.csv")) << "the earlier frames' files";
  EXPECT_TRUE(fs::exists(dir + "/README.txt"));
  // This one wrote no reference image: the earlier one's would pass for it (of another size, it
  // failed `tacsim info --check`; of the same, it was silently the wrong reference).
  EXPECT_FALSE(fs::exists(dir + "/background.png"));
  EXPECT_EQ(Dataset::open(dir).frames(), 2);
}

// A folder of the user's own files is not a dataset to replace: writing one into it replaced
// their poses.csv and removed their numbered frame files.
TEST(Dataset, WriterRefusesAFolderThatHoldsSomethingElse) {
  TempDir tmp;
  const std::string dir = tmp.str("mine");
  fs::create_directories(dir + "/mask");
  std::ofstream(dir + "/poses.csv") << "my poses\n";
  std::ofstream(dir + "/mask/000007.png") << "my image";
  expect_input_error([&] { DatasetWriter(dir, small_info(2)); }, "holds no dataset");
  expect_input_error([&] { DatasetWriter::check_folder(dir); }, dir + ": is not empty");
  EXPECT_TRUE(fs::exists(dir + "/mask/000007.png"));
  std::ifstream in(dir + "/poses.csv");
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "my poses");
  // A file, or a dataset.json of another format, is refused too; an empty folder is fine.
  std::ofstream(tmp.str("file")) << "x";
  expect_input_error([&] { DatasetWriter::check_folder(tmp.str("file")); }, "not a folder");
  std::ofstream(dir + "/dataset.json") << "{\"format\": \"something-else\"}";
  expect_input_error([&] { DatasetWriter::check_folder(dir); }, "holds no dataset");
  fs::create_directories(tmp.str("empty"));
  EXPECT_NO_THROW(write_small(tmp.str("empty"), 2));
}

// A run that stops between the writer's start and finish() (a crash, Ctrl-C) left the new
// dataset.json over the earlier dataset's poses and frames, which opened as a valid dataset.
TEST(Dataset, AnUnfinishedRewriteDoesNotOpenAsADataset) {
  TempDir tmp;
  const std::string dir = tmp.str("d");
  write_small(dir, 5);
  {
    DatasetWriter writer(dir, small_info(3));
    FramePose p;
    writer.write_frame(p, make_frame(24, 32, 0));
  }  // never finished
  expect_input_error([&] { Dataset::open(dir); },
                     "poses.csv: missing: the dataset was never finished");
  // It is still a dataset's folder: writing again replaces it.
  write_small(dir, 3);
  EXPECT_EQ(Dataset::open(dir).frames(), 3);
}

TEST(Dataset, ReaderRejectsWrongImageSize) {
  TempDir tmp;
  write_small(tmp.str("d"), 2);
  write_image(tmp.str("d/color/000001.png"), ImageU8(12, 16, 3));
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_NO_THROW(d.color(0));
  expect_input_error([&] { d.color(1); }, "12x16x3");
}

// A PNG saved under a normal or depth image's .exr name reads (OpenImageIO goes by content) as
// plausible numbers in [0, 1]; it is refused, naming the file, instead of tracked as normals.
TEST(Dataset, ReaderRejectsAnEightBitFileAsNormalsOrDepth) {
  TempDir tmp;
  write_small(tmp.str("d"), 2);
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_NO_THROW(d.normal(1));
  write_image(tmp.str("n.png"), make_frame(24, 32, 1).normal);
  fs::copy_file(tmp.str("n.png"), tmp.str("d/normal/000001.exr"),
                fs::copy_options::overwrite_existing);
  expect_input_error([&] { d.normal(1); }, "normal/000001.exr: is a png file of uint8 pixels");
  write_image(tmp.str("z.png"), make_frame(24, 32, 0).depth);
  fs::copy_file(tmp.str("z.png"), tmp.str("d/depth/000000.exr"),
                fs::copy_options::overwrite_existing);
  expect_input_error([&] { d.depth(0); }, "depth/000000.exr: is a png file");
  EXPECT_NO_THROW(d.normal(0));
}

TEST(Dataset, ReaderRejectsNanPosesAndBadRows) {
  TempDir tmp;
  write_small(tmp.str("d"), 2);
  const std::string csv = tmp.str("d/poses.csv");
  std::ifstream in(csv);
  std::string header, row0, row1;
  std::getline(in, header);
  std::getline(in, row0);
  std::getline(in, row1);
  in.close();
  auto rewrite = [&](const std::string& second_row) {
    std::ofstream(csv) << header << "\n" << row0 << "\n" << second_row << "\n";
  };
  rewrite(row1.replace(row1.find(','), 1, ",nan,"));
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "line 3");
  rewrite("1,0,0,0,0,0,0,0,2,0,0,0,0,0,0,1,1");  // quaternion of norm 2
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "unit length");
  rewrite("1,0,0,0,0,0,0,0,1");
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "17 columns");
  std::ofstream(csv) << header << "\n" << row0 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "has 1 frames");
}

// The rows of a dataset's poses.csv, header first, without line ends.
std::vector<std::string> csv_lines(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

void write_lines(const std::string& path, const std::vector<std::string>& lines,
                 const std::string& end = "\n") {
  std::ofstream out(path, std::ios::binary);
  for (const auto& line : lines) out << line << end;
}

TEST(Dataset, ReaderRejectsHugeQuaternionsAndPositions) {
  TempDir tmp;
  write_small(tmp.str("d"), 2);
  const std::string csv = tmp.str("d/poses.csv");
  const std::vector<std::string> lines = csv_lines(csv);
  ASSERT_EQ(lines.size(), 3u);
  const auto with_cells = [&](std::vector<std::pair<int, std::string>> edits) {
    std::vector<std::string> cells = testing_support::split_csv_line(lines[2]);
    for (const auto& [column, text] : edits) cells[column] = text;
    std::string row;
    for (const auto& c : cells) row += (row.empty() ? "" : ",") + c;
    if (lines[2].back() == ',') row += ",";  // an empty contact cell
    write_lines(csv, {lines[0], lines[1], row});
  };
  // Squared, 1e200 overflows to an infinite norm; the message gives the norm itself.
  with_cells({{5, "1e200"}, {6, "0"}, {7, "0"}, {8, "0"}});
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 3: obj quaternion is not unit length (norm 1e+200;");
  with_cells({{12, "0"}, {13, "1e-200"}, {14, "0"}, {15, "0"}});
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "line 3: sensor quaternion is not unit");
  // Rounded to four decimals (norm 0.99995 here), as a spreadsheet writes it: read and
  // normalised (refused before, as "norm 0.99995" and at six digits "norm 1").
  with_cells({{12, "0.7071"}, {13, "0"}, {14, "0"}, {15, "0.7071"}});
  const SE3 sensor = Dataset::open(tmp.str("d")).poses()[1].T_world_sensor;
  EXPECT_NEAR(sensor.rotation().norm(), 1.0, 1e-12);
  EXPECT_NEAR(Eigen::AngleAxisd(sensor.rotation()).angle(), 1.5707963267948966, 1e-9);
  with_cells({{12, "0.7"}, {13, "0"}, {14, "0"}, {15, "0.7"}});  // norm 0.98995: some mistake
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 3: sensor quaternion is not unit length (norm 0.989949494; within "
                     "0.001 of 1 it is normalised)");
  // Finite but absurd positions made the tracker's output inf/NaN.
  with_cells({{2, "1e300"}});
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 3: obj_x = 1e+300 is out of range: positions must be within +-1000 m");
  with_cells({{11, "-1.7e308"}});
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "line 3: sensor_z = -1.7e+308");
  with_cells({{3, "inf"}});
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 3: non-finite value in column 4 (obj_y)");
  with_cells({{3, std::string(100000, '9') + "x"}});
  try {
    Dataset::open(tmp.str("d"));
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_LT(std::string(e.what()).size(), csv.size() + 200) << "the cell is quoted whole";
  }
  with_cells({{2, "999.5"}, {11, "-1000"}});
  EXPECT_DOUBLE_EQ(Dataset::open(tmp.str("d")).poses()[1].T_world_object.translation().x(), 999.5);
}

TEST(Dataset, ReaderAcceptsCrlfLineEndsAndNamesADirectory) {
  TempDir tmp;
  const auto poses = write_small(tmp.str("d"), 3);
  const std::string csv = tmp.str("d/poses.csv");
  write_lines(csv, csv_lines(csv), "\r\n");
  const Dataset d = Dataset::open(tmp.str("d"));
  ASSERT_EQ(d.poses().size(), 3u);
  EXPECT_NEAR(ominus(d.poses()[2].T_world_object, poses[2].T_world_object).norm(), 0, 1e-12);
  EXPECT_EQ(d.poses()[1].contact, poses[1].contact);
  // A carriage return alone (an old Mac export) made the whole file one line, reported as a
  // header whose 17th column was 'contact0'.
  std::vector<std::string> lines = csv_lines(csv);
  for (std::string& line : lines) line.pop_back();  // the CRLF's '\r'
  write_lines(csv, lines, "\r");
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "poses.csv: its lines end in a carriage return alone");

  fs::remove(csv);
  fs::create_directory(csv);
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "poses.csv: is a directory");
  fs::remove(csv);
  std::ofstream(csv) << "frame;time\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "found 'frame;time'");
}

// "frames": 0 used to open as an empty dataset, whose tracking "succeeded" with a final error of
// 0.000 mm and passed any accuracy gate.
TEST(Dataset, ReaderRejectsZeroFrames) {
  TempDir tmp;
  write_small(tmp.str("d"), 1);
  const std::string info = tmp.str("d/dataset.json");
  nlohmann::json j = parse_json_file(info);
  j["frames"] = 0;
  std::ofstream(info) << j.dump(2);
  write_lines(tmp.str("d/poses.csv"), {csv_lines(tmp.str("d/poses.csv"))[0]});
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "dataset.json: frames: must be >= 1");
  fs::remove(info);
  fs::create_directory(info);
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "dataset.json: is a directory");
}

TEST(Dataset, ARecordingMayLeaveTheObjectPoseAndTheContactUnknown) {
  TempDir tmp;
  write_small(tmp.str("d"), 3);
  const std::string csv = tmp.str("d/poses.csv");
  std::vector<FramePose> poses = read_poses_csv(csv);
  poses[1].object_known = false;   // written as seven empty cells
  poses[2].contact_known = false;  // an empty last cell
  write_poses_csv(csv, poses);
  std::ifstream in(csv);
  std::string header, row0, row1, row2;
  std::getline(in, header);
  std::getline(in, row0);
  std::getline(in, row1);
  std::getline(in, row2);
  EXPECT_NE(row1.find(",,,,,,,,"), std::string::npos) << row1;
  EXPECT_EQ(row2.back(), ',') << row2;
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_TRUE(d.poses()[0].object_known && d.poses()[0].contact_known);
  EXPECT_FALSE(d.poses()[1].object_known);
  EXPECT_TRUE(d.poses()[1].contact_known);
  EXPECT_TRUE(d.poses()[2].object_known);
  EXPECT_FALSE(d.poses()[2].contact_known);
  EXPECT_NEAR(ominus(d.poses()[1].T_world_sensor, poses[1].T_world_sensor).norm(), 0, 1e-12);
  in.close();

  // Part of an object pose is an error, as is an empty sensor cell.
  const std::size_t first = row1.find(',', row1.find(',') + 1);  // after frame and time
  std::string partial = row1;
  partial.replace(first, 1, ",0.001");
  std::ofstream(csv) << header << "\n" << row0 << "\n" << partial << "\n" << row2 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "line 3: the object pose");
  std::string no_sensor = row0;
  no_sensor.replace(no_sensor.rfind(','), 1, ",,");  // shifts the cells: 18 columns
  std::ofstream(csv) << header << "\n" << no_sensor << "\n" << row1 << "\n" << row2 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "line 2: expected 17 columns");
  std::string empty_sensor = row0;
  const std::size_t sensor_x = [&] {
    std::size_t at = 0;
    for (int c = 0; c < 9; ++c) at = empty_sensor.find(',', at) + 1;
    return at;
  }();
  empty_sensor.erase(sensor_x, empty_sensor.find(',', sensor_x) - sensor_x);
  std::ofstream(csv) << header << "\n" << empty_sensor << "\n" << row1 << "\n" << row2 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 2: sensor_x: '' is not a decimal number");
  // strtod's hexadecimal ("0x10" read as 16 m) is not a number of this format either.
  std::string hex = row0;
  hex.replace(sensor_x, hex.find(',', sensor_x) - sensor_x, "0x10");
  std::ofstream(csv) << header << "\n" << hex << "\n" << row1 << "\n" << row2 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 2: sensor_x: '0x10' is not a decimal number");
  // A header with a column missing, one more or another name says which column parts.
  const std::string no_contact = header.substr(0, header.rfind(','));
  std::ofstream(csv) << no_contact << "\n" << row0 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "column 17 is missing, expected 'contact'");
  std::ofstream(csv) << header << ",note\n" << row0 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "column 18 is 'note', expected no more columns");
  std::string renamed = header;
  renamed.replace(renamed.find("sensor_qw"), 9, "sensor_w");
  std::ofstream(csv) << renamed << "\n" << row0 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "is 'sensor_w', expected 'sensor_qw'");
  // Time never goes back; a spreadsheet's byte-order mark before the header is fine.
  std::ofstream(csv) << "\xEF\xBB\xBF" << header << "\n"
                     << row0 << "\n"
                     << row1 << "\n"
                     << row2 << "\n";
  EXPECT_EQ(Dataset::open(tmp.str("d")).frames(), 3);
  std::ofstream(csv) << header << "\n"
                     << row0 << "\n"
                     << "1,-0.5" << row1.substr(row1.find(',', row1.find(',') + 1)) << "\n"
                     << row2 << "\n";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "line 3: time -0.5 s is before the previous row's");
}

TEST(Dataset, ReaderRejectsBadInfo) {
  TempDir tmp;
  write_small(tmp.str("d"), 1);
  std::ofstream(tmp.str("d/dataset.json")) << "{\"format\": \"patchgraph-dataset\", ";
  expect_input_error([&] { Dataset::open(tmp.str("d")); }, "dataset.json:1:");
  // A number beyond a double is no syntax error to nlohmann, which then named no file.
  std::ofstream(tmp.str("d/dataset.json"))
      << "{\"format\": \"patchgraph-dataset\", \"fps\": 1e400}";
  expect_input_error([&] { Dataset::open(tmp.str("d")); },
                     "dataset.json: malformed JSON: number overflow parsing '1e400'");
}

TEST(Dataset, ContactPointsRoundTripAsPly) {
  TempDir tmp;
  DatasetInfo info = small_info(2);
  info.outputs = {"mask", "points"};
  DatasetWriter w(tmp.str("d"), info);
  for (int i = 0; i < 2; ++i) {
    FramePose p;
    p.frame = i;
    FrameImages f = make_frame(24, 32, i);
    for (int k = 0; k < 5 * i; ++k) f.contact_points.push_back({0.001f * k, -0.002f, 0.0003f * i});
    w.write_frame(p, f);
  }
  w.finish();
  const Dataset d = Dataset::open(tmp.str("d"));
  EXPECT_TRUE(d.contact_points(0).empty());
  const auto pts = d.contact_points(1);
  ASSERT_EQ(pts.size(), 5u);
  EXPECT_EQ(pts[3], Eigen::Vector3f(0.003f, -0.002f, 0.0003f));
  expect_input_error([&] { d.color(0); }, "no 'color' output");
}

// A JPEG cut short decodes with the missing rows made up (grey): it must be refused like a PNG
// cut short, naming the file, in one line (libpng's reader gave three, the cause twice and "PNG
// library error").
TEST(ImageIo, AnImageCutShortIsRefused) {
  TempDir tmp;
  ImageU8 image(64, 48, 3);
  for (std::size_t i = 0; i < image.data.size(); ++i) image.data[i] = std::uint8_t(i * 7 % 251);
  for (const char* name : {"whole.jpg", "whole.png"}) {
    write_image(tmp.str(name), image);
    EXPECT_EQ(read_image_u8(tmp.str(name)).width, 64) << name;
    const std::string cut = std::string("cut_") + name;
    std::filesystem::copy_file(tmp.str(name), tmp.str(cut));
    std::filesystem::resize_file(tmp.str(cut), std::filesystem::file_size(tmp.str(cut)) / 2);
    expect_input_error([&] { read_image_u8(tmp.str(cut)); }, cut + ": cannot decode image");
    try {
      read_image_u8(tmp.str(cut));
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
}

TEST(PointIo, PlyRoundTripWithNormalsAndErrors) {
  TempDir tmp;
  std::vector<Eigen::Vector3f> p = {{1, 2, 3}, {-1, 0.5f, 1e-6f}}, n = {{0, 0, 1}, {1, 0, 0}};
  write_ply(tmp.str("a.ply"), p, &n);
  std::vector<Eigen::Vector3f> n2;
  EXPECT_EQ(read_ply(tmp.str("a.ply"), &n2), p);
  EXPECT_EQ(n2, n);
  expect_input_error([&] { read_ply(tmp.str("none.ply")); }, "none.ply");
  std::ofstream(tmp.str("t.ply"), std::ios::binary)
      << "ply\nformat binary_little_endian 1.0\nelement vertex 9\nproperty float x\n"
         "property float y\nproperty float z\nend_header\nabc";
  expect_input_error([&] { read_ply(tmp.str("t.ply")); }, "truncated");
  std::ofstream(tmp.str("x.ply")) << "solid\n";
  expect_input_error([&] { read_ply(tmp.str("x.ply")); }, "not a PLY");
  std::vector<Eigen::Vector3f> bad = {{NAN, 0, 0}};
  write_ply(tmp.str("nan.ply"), bad);
  expect_input_error([&] { read_ply(tmp.str("nan.ply")); }, "not finite");
}

// A write that does not reach the disk is an error naming the file and the cause, never a short
// file taken for a whole one (/dev/full fails every write as a full disk does); a failed atomic
// write leaves the earlier file and no temporary.
TEST(FileIo, AFailedWriteNamesTheFileAndTheCause) {
  TempDir tmp;
  if (!std::filesystem::is_character_file("/dev/full")) GTEST_SKIP() << "no /dev/full here";
  expect_input_error([] { write_text_file("/dev/full", std::string(100000, 'x')); },
                     "/dev/full: cannot write (No space left on device");
  expect_input_error([] { write_text_file("/dev/full", "short, so buffered until closed"); },
                     "No space left on device");
  expect_input_error([&] { write_ply(tmp.str("none/a.ply"), {Eigen::Vector3f::Ones()}); },
                     "none/a.ply: cannot write (No such file or directory)");
  expect_input_error([&] { write_text_file(tmp.str("none/a.txt"), "x"); },
                     "none/a.txt: cannot write (No such file or directory)");
  write_text_atomically(tmp.str("a.txt"), "earlier");
  // The next temporary name (this one's count plus one) made a folder: it cannot be written.
  const std::string name = temporary_path_for(tmp.str("a.txt"));
  const std::size_t dot = name.rfind('.');
  const std::string next =
      name.substr(0, dot + 1) + std::to_string(std::stoi(name.substr(dot + 1)) + 1);
  fs::create_directory(next);
  std::ofstream(next + "/keep") << "x";
  expect_input_error([&] { write_text_atomically(tmp.str("a.txt"), "new"); },
                     tmp.str("a.txt") + ": cannot write");
  std::ifstream in(tmp.str("a.txt"));
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "earlier");
}

// Two writers of one file at once (two runs given the same --out): each write is whole and none
// fails (they shared one temporary name, and one's rename took the other's file away).
TEST(FileIo, ConcurrentAtomicWritesOfOneFileEachLandWhole) {
  TempDir tmp;
  const std::string path = tmp.str("summary.json");
  const std::string a(20000, 'a'), b(30000, 'b');
  std::atomic<int> failures{0};
  const auto writer = [&](const std::string& text) {
    for (int i = 0; i < 200; ++i) {
      try {
        write_text_atomically(path, text);
      } catch (const InputError&) {
        ++failures;
      }
    }
  };
  std::thread first(writer, a), second(writer, b);
  first.join();
  second.join();
  EXPECT_EQ(failures.load(), 0);
  std::ifstream in(path);
  const std::string text(std::istreambuf_iterator<char>(in), {});
  EXPECT_TRUE(text == a || text == b) << text.size();
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()), 1);
}

// A pipe (as /dev/stdout or /dev/null) given as an output is written to, never replaced by a
// plain file (which, as root, would have replaced /dev/null itself); a symbolic link stays a link
// to the replaced file; a file written whole over a device or pipe is refused, naming it.
TEST(FileIo, DevicesAndPipesAreWrittenToAndLinksStayLinks) {
  TempDir tmp;
  const std::string fifo = tmp.str("pipe");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const int reader = open(fifo.c_str(), O_RDONLY | O_NONBLOCK);  // so the writer's open returns
  ASSERT_GE(reader, 0);
  write_text_atomically(fifo, "{\"a\": 1}\n");
  char got[64] = {};
  const ssize_t n = read(reader, got, sizeof got - 1);
  close(reader);
  EXPECT_TRUE(fs::is_fifo(fifo));
  EXPECT_EQ(std::string(got, n > 0 ? std::size_t(n) : 0), "{\"a\": 1}\n");
  testing_support::expect_input_error([&] { replaceable_file(fifo); }, {fifo, "device or pipe"});

  const std::string file = tmp.str("real.json"), link = tmp.str("link.json");
  std::ofstream(file) << "old";
  fs::create_symlink(file, link);
  write_text_atomically(link, "new");
  EXPECT_TRUE(fs::is_symlink(link));
  std::ifstream in(file);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), "new");
  EXPECT_EQ(std::distance(fs::directory_iterator(tmp.path), fs::directory_iterator()), 3);
}

// A pipe with no writer given as an input file: opening it to read would block for ever (a
// poses.csv did). Each reader refuses it by name instead, as it refuses a folder.
TEST(FileIo, APipeToReadFromIsRefusedNotWaitedOn) {
  TempDir tmp;
  const std::string fifo = tmp.str("pipe");
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string not_regular = "is not a regular file (a device, pipe or socket), not ";
  testing_support::expect_input_error([&] { read_poses_csv(fifo); },
                                      {fifo, not_regular + "a poses.csv file"});
  testing_support::expect_input_error([&] { read_image_u8(fifo); },
                                      {fifo, not_regular + "an image file"});
  testing_support::expect_input_error([&] { parse_json_file(fifo); },
                                      {fifo, not_regular + "a JSON file"});
  testing_support::expect_input_error([&] { read_ply(fifo, nullptr); },
                                      {fifo, not_regular + "a PLY file"});
  testing_support::expect_input_error([&] { read_poses_csv(tmp.path.string()); },
                                      {"is a directory, not a poses.csv file"});
  testing_support::expect_input_error([&] { read_image_u8(tmp.str("missing.png")); },
                                      {"missing.png: image file not found"});
}

TEST(Image, FormatsRoundTrip) {
  TempDir tmp;
  ImageF f(5, 4, 3);
  for (std::size_t i = 0; i < f.data.size(); ++i) f.data[i] = float(i) / f.data.size();
  write_image(tmp.str("a.exr"), f);
  EXPECT_EQ(read_image_float(tmp.str("a.exr")).data, f.data);
  write_image(tmp.str("a.png"), f);  // quantised to 8 bits
  const ImageF p = read_image_float(tmp.str("a.png"));
  ASSERT_TRUE(p.same_shape(5, 4, 3));
  for (std::size_t i = 0; i < f.data.size(); ++i)
    EXPECT_NEAR(p.data[i], f.data[i], 0.5 / 255 + 1e-6);
  ImageU8 u(6, 3, 1);
  for (std::size_t i = 0; i < u.data.size(); ++i) u.data[i] = std::uint8_t(40 * i);
  write_image(tmp.str("g.png"), u);
  EXPECT_EQ(read_image_u8(tmp.str("g.png")).data, u.data);
  ImageU8 rgb(16, 16, 3, 128);
  write_image(tmp.str("c.jpg"), rgb);
  const ImageShape s = read_image_shape(tmp.str("c.jpg"));
  EXPECT_EQ(s.width, 16);
  EXPECT_EQ(s.channels, 3);
  EXPECT_NEAR(read_image_u8(tmp.str("c.jpg")).data[0], 128, 2);
}

TEST(Image, ExrFilesCarryNoWriteTime) {
  // Two renders of one scene must give byte-identical files; OpenImageIO's default EXR header
  // holds the time of writing in "capDate". Ours must hold an empty one.
  TempDir tmp;
  write_image(tmp.str("a.exr"), ImageF(3, 2, 1, 0.5f));
  std::ifstream in(tmp.str("a.exr"), std::ios::binary);
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string attribute("capDate\0string\0", 15);  // name, type, then a 4-byte size
  const std::size_t at = bytes.find(attribute);
  if (at == std::string::npos) return;  // no date at all is as good
  ASSERT_LE(at + attribute.size() + 4, bytes.size());
  EXPECT_EQ(bytes.substr(at + attribute.size(), 4), std::string(4, '\0'))
      << "the capDate attribute is not empty";
}

// Dataset images are EXR files run-length compressed (image_codec.cpp says why): lossless, the
// header says RLE, and a mostly untouched depth image (zeros) comes out far below its raw size.
TEST(Image, ExrFilesAreLosslessAndRunLengthCompressed) {
  TempDir tmp;
  ImageF normals(160, 120, 3);
  ImageF depth(160, 120, 1, 0.0f);
  std::uint32_t state = 12345;
  for (float& v : normals.data) {
    state = state * 1664525u + 1013904223u;
    v = float(state >> 8) / float(1u << 24) * 2.0f - 1.0f;  // every bit of the mantissa in use
  }
  for (int y = 50; y < 70; ++y) {
    for (int x = 60; x < 90; ++x) depth.at(x, y) = 1e-4f * float(x + y);
  }
  for (const auto& [name, image] : {std::pair{"normal.exr", &normals}, {"depth.exr", &depth}}) {
    SCOPED_TRACE(name);
    write_image(tmp.str(name), *image);
    const ImageF back = read_float_file(tmp.str(name));
    ASSERT_TRUE(back.same_shape(image->width, image->height, image->channels));
    EXPECT_EQ(back.data, image->data);
    std::ifstream in(tmp.str(name), std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // The header's attribute: name, type, a 4-byte size (1), then OpenEXR's code (RLE: 1; zip: 3).
    const std::string attribute("compression\0compression\0\x01\0\0\0", 28);
    const std::size_t at = bytes.find(attribute);
    ASSERT_NE(at, std::string::npos) << "no compression attribute in the header";
    ASSERT_LT(at + attribute.size(), bytes.size());
    EXPECT_EQ(int(bytes[at + attribute.size()]), 1) << "not run-length compressed";
  }
  const auto raw = std::uintmax_t(depth.data.size() * sizeof(float));
  EXPECT_LT(fs::file_size(tmp.str("depth.exr")), raw / 10);
}

// 1 codec thread is the calling one: no pool of OpenEXR's threads stays behind (its pool of one
// worker, OpenImageIO's 1, took twice as long to read a frame).
TEST(Image, OneCodecThreadIsTheCallingOne) {
  TempDir tmp;
  write_image(tmp.str("a.exr"), ImageF(16, 16, 3, 0.25f));
  const auto threads = [] {
    std::size_t n = 0;
    for ([[maybe_unused]] const auto& task : fs::directory_iterator("/proc/self/task")) ++n;
    return n;
  };
  set_image_codec_threads(4);
  read_float_file(tmp.str("a.exr"));
  const std::size_t with_pool = threads();
  {
    const ScopedImageCodecThreads one(1);
    EXPECT_EQ(image_codec_threads(), 1);
    EXPECT_EQ(read_float_file(tmp.str("a.exr")).data, std::vector<float>(16 * 16 * 3, 0.25f));
    // A joined thread can stay listed in /proc/self/task for a moment after the join returns
    // (the kernel reaps it after waking the joiner): allow it a few seconds on a busy machine.
    std::size_t now = threads();
    for (int wait = 0; wait < 500 && now + 4 > with_pool; ++wait) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      now = threads();
    }
    EXPECT_LE(now + 4, with_pool) << "the decoding pool's threads are still there";
  }
  EXPECT_EQ(image_codec_threads(), 4);
  set_image_codec_threads(0);
}

TEST(Image, ErrorsNameThePath) {
  TempDir tmp;
  expect_input_error([&] { read_image_u8(tmp.str("none.png")); }, "none.png");
  std::ofstream(tmp.str("junk.png")) << "not a png";
  expect_input_error([&] { read_image_u8(tmp.str("junk.png")); }, "junk.png");
  expect_input_error([&] { write_image(tmp.str("x.unknownext"), ImageU8(2, 2, 1)); },
                     "x.unknownext");
  expect_input_error([&] { read_image_u8(tmp.str()); }, "is a directory, not an image file");
}

// OpenImageIO comes in a module loaded with the first image read or written (ctest runs this test
// in a process of its own, so here: by four threads at once). Codec threads asked for before then
// hold once it is loaded.
TEST(Image, TheCodecModuleComesWithTheFirstImage) {
  // Neither OpenImageIO's default (0) nor what it reports for the default (the cores: 2 here).
  const int asked = int(std::thread::hardware_concurrency()) + 1;
  set_image_codec_threads(asked);
  EXPECT_EQ(image_codec_threads(), asked);
  TempDir tmp;
  const std::string pixels = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  std::ofstream(tmp.str("a.pgm"), std::ios::binary) << "P5\n4 3\n255\n" << pixels;
  std::atomic<int> read_right{0};
  std::vector<std::thread> readers;
  for (int k = 0; k < 4; ++k) {
    readers.emplace_back([&] {
      const ImageU8 image = read_image_u8(tmp.str("a.pgm"));
      if (image.same_shape(4, 3, 1) &&
          image.data == std::vector<std::uint8_t>(pixels.begin(), pixels.end())) {
        ++read_right;
      }
    });
  }
  for (auto& r : readers) r.join();
  EXPECT_EQ(read_right, 4);
  EXPECT_EQ(image_codec_threads(), asked);  // OpenImageIO's own setting now
  std::ifstream maps("/proc/self/maps");
  const std::string mapped((std::istreambuf_iterator<char>(maps)),
                           std::istreambuf_iterator<char>());
  EXPECT_NE(mapped.find("libpg_image_codec"), std::string::npos);
  EXPECT_NE(mapped.find("libOpenImageIO"), std::string::npos);
  set_image_codec_threads(0);
}

// A module is found where it was built or, in a build folder moved as a whole, in the folder of
// that name beside the program's (this test runs from build/tests, the codec is in build/core);
// one in neither place is an error that names what and where.
TEST(Module, FoundWhereBuiltOrBesideTheProgram) {
  const fs::path build = fs::read_symlink("/proc/self/exe").parent_path().parent_path();
  ASSERT_TRUE(fs::exists(build / "core" / "libpg_image_codec.so")) << build;
  EXPECT_NE(module_entry("/moved/away/core/libpg_image_codec.so", "pg_image_codec_table",
                         "the image codecs"),
            nullptr);
  try {
    module_entry("/moved/away/core/libpg_none.so", "pg_none", "the nothing codecs");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cannot load the nothing codecs"), std::string::npos) << what;
    EXPECT_NE(what.find("/moved/away/core/libpg_none.so"), std::string::npos) << what;
    EXPECT_NE(what.find((build / "core" / "libpg_none.so").string()), std::string::npos) << what;
  }
  try {  // there, but without the function asked for
    module_entry((build / "core" / "libpg_image_codec.so").string(), "pg_none", "the codecs");
    ADD_FAILURE() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("no function pg_none"), std::string::npos) << e.what();
  }
}

TEST(Dataset, BackgroundIsTheWrittenReferenceOrTheMedianOfFramesWithoutContact) {
  TempDir tmp;
  // Frames 0, 2, 4 have contact: without background.png, frames 1 and 3 make the reference, the
  // mean of the two middle values of an even count.
  write_small(tmp.str("a"), 5);
  const Dataset a = Dataset::open(tmp.str("a"));
  EXPECT_EQ(a.reference_frames(), (std::vector<int>{1, 3}));
  const ImageU8 one = a.color(1), three = a.color(3), two_mean = a.background();
  ASSERT_NE(one.data, three.data);
  for (std::size_t i = 0; i < two_mean.data.size(); ++i) {
    ASSERT_EQ(two_mean.data[i], (one.data[i] + three.data[i] + 1) / 2) << "byte " << i;
  }
  // A frame whose contact is not known is not taken: frame 3 alone is.
  std::vector<FramePose> poses = read_poses_csv(tmp.str("a/poses.csv"));
  poses[1].contact_known = false;
  write_poses_csv(tmp.str("a/poses.csv"), poses);
  EXPECT_EQ(Dataset::open(tmp.str("a")).background().data, a.color(3).data);

  DatasetWriter w(tmp.str("b"), small_info(1));
  ImageU8 bg(24, 32, 3, 77);
  w.write_background(bg);
  FramePose p;
  p.contact = true;
  w.write_frame(p, make_frame(24, 32, 0));
  w.finish();
  const Dataset b = Dataset::open(tmp.str("b"));
  EXPECT_EQ(b.background().data, bg.data);

  // Neither a reference nor a frame without contact; and a reference of the wrong size.
  fs::remove(tmp.str("b") + "/background.png");
  expect_input_error([&] { b.background(); }, "no frame that poses.csv marks as without");
  // A pipe there is named as such, not taken for a missing reference (nor waited on).
  ASSERT_EQ(mkfifo((tmp.str("b") + "/background.png").c_str(), 0600), 0);
  expect_input_error([&] { b.background(); },
                     "background.png: is not a regular file (a device, pipe or socket)");
  EXPECT_THROW(w.write_background(ImageU8(10, 10, 3)), InputError);
}

// A render of several sensors lists their folders in sensors.json; a malformed list is an error
// naming the file and the field, never a folder outside the render.
TEST(Dataset, ASensorIndexListsTheSensorsFolders) {
  TempDir tmp;
  const std::string dir = tmp.str("render");
  fs::create_directories(dir);
  EXPECT_TRUE(sensor_dataset_dirs(dir).empty()) << "neither a dataset nor a render of sensors";
  write_sensor_index(dir, {"left", "right"});
  fs::create_directories(dir + "/left");
  fs::create_directories(dir + "/right");
  EXPECT_EQ(sensor_dataset_dirs(dir), (std::vector<std::string>{dir + "/left", dir + "/right"}));
  fs::remove(dir + "/left");
  fs::remove(dir + "/right");
  const auto refused = [&](const std::string& text) {
    std::ofstream(dir + "/sensors.json") << text;
    try {
      sensor_dataset_dirs(dir);
    } catch (const InputError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  for (const char* text :
       {R"({"sensors": "left"})", R"({"sensors": []})", R"({"sensors": ["left"], "extra": 1})",
        R"({"sensors": ["../x"]})", R"({"sensors": ["a/b"]})", R"({"sensors": [".."]})"}) {
    const std::string message = refused(text);
    EXPECT_NE(message.find(dir + "/sensors.json"), std::string::npos) << text << ": " << message;
  }
  EXPECT_NE(refused(R"({"sensors": ["left"], "extra": 1})").find("extra"), std::string::npos);
  EXPECT_NE(refused(R"({"sensors": ["../x"]})").find("'../x' is not a folder name"),
            std::string::npos);
  // A sensor listed twice would count double; a listed folder must be there.
  fs::create_directories(dir + "/left");
  EXPECT_EQ(refused(R"({"sensors": ["left", "left"]})"),
            dir +
                "/sensors.json: sensors: 'left' listed twice (one sensor's measurements would "
                "count double)");
  EXPECT_EQ(refused(R"({"sensors": ["left", "right"]})"),
            dir + "/sensors.json: sensors: 'right': no such folder next to it (" + dir + "/right)");
}

// Sensor poses that move further between rows than a hand does are jumps: 5 cm or 0.5 rad, each
// alone; at the bounds they are not. describe() names the first and, given the header's offset,
// its lines.
TEST(Dataset, SensorPoseJumpsAreFoundAtTheirBounds) {
  std::vector<FramePose> poses(6);
  EXPECT_EQ(sensor_jumps(poses).count, 0);
  EXPECT_EQ(sensor_jumps({}).count, 0);
  poses[2].T_world_sensor = SE3::Translation(Eigen::Vector3d(0, 0.0499, 0));  // 49.9 mm, and back
  EXPECT_EQ(sensor_jumps(poses).count, 0);
  poses[2].T_world_sensor = SE3::Translation(Eigen::Vector3d(0, 0.0501, 0));
  SensorJumps jumps = sensor_jumps(poses);
  EXPECT_EQ(jumps.count, 2);  // there and back
  EXPECT_EQ(jumps.first, 2);
  EXPECT_NEAR(jumps.first_m, 0.0501, 1e-12);
  EXPECT_EQ(jumps.first_rad, 0.0);
  Vector6d turn = Vector6d::Zero();
  turn(5) = 0.51;  // a turn alone, and no translation
  poses[2] = FramePose{};
  poses[5].T_world_sensor = SE3::exp(turn);
  jumps = sensor_jumps(poses);
  EXPECT_EQ(jumps.count, 1);
  EXPECT_EQ(jumps.first, 5);
  EXPECT_NEAR(jumps.first_rad, 0.51, 1e-9);
  EXPECT_EQ(describe(jumps),
            "the sensor pose jumps by more than 50 mm or 0.5 rad from one frame to the next 1 "
            "time(s), first from frame 4 to 5 (0.0 mm, 0.510 rad)");
  EXPECT_EQ(describe(jumps, 2),
            "the sensor pose jumps by more than 50 mm or 0.5 rad from one frame to the next 1 "
            "time(s), first from frame 4 to 5 (lines 6-7: 0.0 mm, 0.510 rad)");
}

}  // namespace
}  // namespace pg
