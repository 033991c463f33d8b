#include "pg/core/dataset.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>

#include "pg/core/csv.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/image_change.h"
#include "pg/core/json_fields.h"
#include "pg/core/point_io.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

const char* kPosesHeader =
    "frame,time,obj_x,obj_y,obj_z,obj_qx,obj_qy,obj_qz,obj_qw,"
    "sensor_x,sensor_y,sensor_z,sensor_qx,sensor_qy,sensor_qz,sensor_qw,contact";
constexpr int kPosesColumns = 17;
constexpr int kObjectFirst = 2;     // obj_x
constexpr int kSensorFirst = 9;     // sensor_x
constexpr int kContactColumn = 16;  // contact
constexpr int kFormatVersion = 1;

// The header's name of column c (0-based), for messages.
std::string column_name(int c) {
  std::stringstream header(kPosesHeader);
  std::string name;
  for (int i = 0; i <= c; ++i) std::getline(header, name, ',');
  return name;
}

// obj_x, obj_y, obj_z and sensor_x, sensor_y, sensor_z.
bool is_position_column(int c) {
  return (c >= kObjectFirst && c < kObjectFirst + 3) || (c >= kSensorFirst && c < kSensorFirst + 3);
}

std::string extension_of(const std::string& output) {
  if (output == "points") return ".ply";
  if (output == "normal_png") return ".png";
  return (output == "normal" || output == "depth") ? ".exr" : ".png";
}

int channels_of(const std::string& output) {
  return (output == "color" || output == "normal" || output == "normal_png") ? 3 : 1;
}

void check_shape(const std::string& path, const ImageShape& got, int w, int h, int c) {
  if (got.width != w || got.height != h || got.channels != c) {
    throw InputError(path + ": image is " + std::to_string(got.width) + "x" +
                     std::to_string(got.height) + "x" + std::to_string(got.channels) +
                     ", dataset.json says " + std::to_string(w) + "x" + std::to_string(h) + "x" +
                     std::to_string(c));
  }
}

template <typename T>
void check_image(const std::string& path, const Image<T>& image, int w, int h, int c) {
  check_shape(path, {image.width, image.height, image.channels}, w, h, c);
}

nlohmann::json info_to_json(const DatasetInfo& info) {
  nlohmann::json j = {
      {"format", "patchgraph-dataset"},
      {"version", kFormatVersion},
      {"sensor", sensor_to_json(info.sensor)},
      {"width", info.width()},
      {"height", info.height()},
      {"frames", info.frames},
      {"fps", info.fps},
      {"outputs", info.outputs},
      {"scene", info.scene},
      {"seed", info.seed},
      {"object",
       {{"name", info.object_name}, {"mesh", info.object_mesh}, {"scale", info.object_scale}}}};
  if (info.render_known) {
    j["render"] = {{"shadows", info.shadows},
                   {"background", info.background.empty() ? "synthetic" : info.background}};
  }
  return j;
}

DatasetInfo info_from_json(const nlohmann::json& j, const std::string& path) {
  JsonFields f(j, path);
  if (f.required<std::string>("format") != "patchgraph-dataset") {
    throw InputError(f.field("format") + ": expected \"patchgraph-dataset\"");
  }
  const int version = f.required<int>("version");
  if (version != kFormatVersion) {
    throw InputError(f.field("version") + ": unsupported version " + std::to_string(version));
  }
  DatasetInfo info;
  info.sensor = sensor_from_json(f.at("sensor"), f.field("sensor"));
  const int w = f.required<int>("width"), h = f.required<int>("height");
  if (w != info.width() || h != info.height()) {
    throw InputError(f.field(w != info.width() ? "width" : "height") + ": image size " +
                     std::to_string(w) + "x" + std::to_string(h) +
                     " disagrees with the sensor's camera (sensor.camera: " +
                     std::to_string(info.width()) + "x" + std::to_string(info.height()) + ")");
  }
  info.frames = f.required<int>("frames");
  // A dataset without frames has nothing to track, and the tracker's summary of it would be a
  // vacuous "final error 0.000 mm" that passes any accuracy gate.
  if (info.frames < 1) {
    throw InputError(f.field("frames") + ": must be >= 1, got " + std::to_string(info.frames));
  }
  info.fps = f.required_number_in("fps", 1e-6, 1e6);
  info.outputs = f.required<std::vector<std::string>>("outputs");
  check_output_names(info.outputs, f.field("outputs"));
  info.scene = f.optional<std::string>("scene", "");
  info.seed = f.optional<std::uint64_t>("seed", 0);
  if (f.has("object")) {
    JsonFields o(f.at("object"), f.field("object"));
    info.object_name = o.optional<std::string>("name", "");
    info.object_mesh = o.optional<std::string>("mesh", "");
    info.object_scale = o.number_in("scale", 1e-9, 1e9, 1.0);
    o.finish();
  }
  info.render_known = f.has("render");
  if (info.render_known) {
    JsonFields r(f.at("render"), f.field("render"));
    info.shadows = r.optional<bool>("shadows", false);
    info.background = r.optional<std::string>("background", "synthetic");
    if (info.background == "synthetic") info.background.clear();
    r.finish();
  }
  f.finish();
  return info;
}

}  // namespace

const std::vector<std::string>& dataset_output_names() {
  static const std::vector<std::string> names = {"color", "normal", "normal_png",
                                                 "depth", "mask",   "points"};
  return names;
}

void check_output_names(const std::vector<std::string>& names, const std::string& where) {
  const auto& known = dataset_output_names();
  std::string list;  // the names, as the messages give them
  for (const auto& n : known) list += (list.empty() ? "" : ", ") + n;
  if (names.empty()) {  // a dataset of poses alone, which nothing can track
    throw InputError(where + ": empty; name at least one of " + list);
  }
  for (auto name = names.begin(); name != names.end(); ++name) {
    if (std::find(known.begin(), known.end(), *name) == known.end()) {
      throw InputError(where + ": unknown output '" + *name + "' (known: " + list + ")");
    }
    if (std::find(names.begin(), name, *name) != name) {
      throw InputError(where + ": output '" + *name + "' is given twice");
    }
  }
}

bool DatasetInfo::has_output(const std::string& name) const {
  return std::find(outputs.begin(), outputs.end(), name) != outputs.end();
}

bool DatasetInfo::has_normals() const { return has_output("normal") || has_output("normal_png"); }

std::string dataset_frame_path(const std::string& dir, const std::string& output, int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d", frame);
  return (fs::path(dir) / output / (name + extension_of(output))).string();
}

void write_poses_csv(const std::string& path, const std::vector<FramePose>& poses) {
  std::ostringstream out;
  out.precision(std::numeric_limits<double>::max_digits10);
  out << kPosesHeader << "\n";
  for (const auto& p : poses) {
    const auto& to = p.T_world_object.translation();
    const auto& qo = p.T_world_object.rotation();
    const auto& ts = p.T_world_sensor.translation();
    const auto& qs = p.T_world_sensor.rotation();
    out << p.frame << "," << p.time_s << ",";
    if (p.object_known) {
      out << to.x() << "," << to.y() << "," << to.z() << "," << qo.x() << "," << qo.y() << ","
          << qo.z() << "," << qo.w() << ",";
    } else {
      out << ",,,,,,,";
    }
    out << ts.x() << "," << ts.y() << "," << ts.z() << "," << qs.x() << "," << qs.y() << ","
        << qs.z() << "," << qs.w() << ",";
    if (p.contact_known) out << (p.contact ? 1 : 0);
    out << "\n";
  }
  write_text_atomically(path, out.str());
}

std::vector<FramePose> read_poses_csv(const std::string& path) {
  require_regular_file(path, "a poses.csv file");
  std::ifstream in(path);
  if (!in) throw InputError(path + ": cannot read the file (missing or not readable)");
  std::string line;
  const bool has_line = static_cast<bool>(std::getline(in, line));
  // A file saved on Windows ends its lines with "\r\n"; the rows drop the '\r' below. A
  // spreadsheet's UTF-8 byte-order mark before the header is dropped too.
  clean_csv_line(line, true);
  if (line.find('\r') != std::string::npos) {  // the header ran into the next rows
    throw InputError(path +
                     ": its lines end in a carriage return alone (an old Mac 'CSV (Macintosh)' "
                     "export?); save it with LF or CRLF line endings");
  }
  if (!has_line || line != kPosesHeader) {
    // Where the two part, so that a missing, extra or swapped column past the excerpt shows.
    const std::vector<std::string> found = csv_cells(line), expected = csv_cells(kPosesHeader);
    std::size_t k = 0;
    while (k < found.size() && k < expected.size() && found[k] == expected[k]) ++k;
    std::string where;
    if (has_line && !line.empty()) {
      where = "; column " + std::to_string(k + 1) + " is " +
              (k < found.size() ? "'" + excerpt(found[k]) + "'" : "missing") + ", expected " +
              (k < expected.size() ? "'" + expected[k] + "'" : "no more columns");
    }
    throw InputError(path + ": line 1: expected the header '" + std::string(kPosesHeader) +
                     "', found '" + excerpt(line) + "'" + where);
  }
  std::vector<FramePose> poses;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty()) continue;
    const std::string where = path + ": line " + std::to_string(line_no);
    const std::vector<std::string> cells = csv_cells(line);
    if (int(cells.size()) != kPosesColumns) {
      throw InputError(where + ": expected " + std::to_string(kPosesColumns) + " columns, got " +
                       std::to_string(cells.size()));
    }
    // Empty cells are allowed for the object pose (all seven, columns 3-9) and the contact.
    const auto is_object_column = [&](int c) { return c >= kObjectFirst && c < kObjectFirst + 7; };
    int empty_object_cells = 0;
    std::vector<double> v(kPosesColumns, 0.0);
    for (int c = 0; c < kPosesColumns; ++c) {
      const std::string& cell = cells[c];
      if (cell.empty() && (is_object_column(c) || c == kContactColumn)) {
        empty_object_cells += is_object_column(c);
        continue;
      }
      const std::optional<double> number = decimal_number(cell);
      if (!number) {
        throw InputError(where + ": " + column_name(c) + ": '" + excerpt(cell) +
                         "' is not a decimal number");
      }
      v[c] = *number;
      if (!std::isfinite(v[c])) {
        throw InputError(where + ": non-finite value in column " + std::to_string(c + 1) + " (" +
                         column_name(c) + ")");
      }
      if (is_position_column(c) && std::abs(v[c]) > kMaxPositionM) {
        std::ostringstream msg;
        msg << where << ": " << column_name(c) << " = " << v[c] << " is out of range: positions "
            << "must be within +-" << kMaxPositionM << " m";
        throw InputError(msg.str());
      }
    }
    const bool object_known = empty_object_cells == 0;
    if (!object_known && empty_object_cells != 7) {
      throw InputError(where +
                       ": the object pose (columns 3-9) must be given in full or left "
                       "empty, not in part");
    }
    Eigen::Quaterniond qo =
        object_known ? Eigen::Quaterniond(v[8], v[5], v[6], v[7]) : Eigen::Quaterniond::Identity();
    Eigen::Quaterniond qs(v[15], v[12], v[13], v[14]);
    for (auto* q : {&qo, &qs}) {
      // stableNorm: the plain norm squares the components and overflows for 1e155 and above.
      const double norm = q->coeffs().stableNorm();
      // Within rounding of unit length (a file written with 4 decimals is off by up to 1e-4; the
      // tolerance had been 1e-6), normalised; beyond, a quaternion of some other meaning.
      if (!(std::abs(norm - 1.0) <= kUnitQuaternionTolerance)) {
        std::ostringstream msg;
        msg.precision(9);
        msg << where << ": " << (q == &qo ? "obj" : "sensor")
            << " quaternion is not unit length (norm " << norm << "; within "
            << kUnitQuaternionTolerance << " of 1 it is normalised)";
        throw InputError(msg.str());
      }
      q->normalize();
    }
    FramePose p;
    p.object_known = object_known;
    p.contact_known = !cells[kContactColumn].empty();
    p.frame = int(v[0]);
    if (p.frame != int(poses.size()) || v[0] != double(p.frame)) {
      throw InputError(where + ": expected frame " + std::to_string(poses.size()));
    }
    p.time_s = v[1];
    // Rows in the order the frames were taken (a sorted or shuffled file is not); a clock too
    // coarse to tell two frames apart may repeat a time.
    if (!poses.empty() && p.time_s < poses.back().time_s) {
      std::ostringstream msg;
      msg << where << ": time " << p.time_s << " s is before the previous row's "
          << poses.back().time_s << " s: the rows must be in the order the frames were taken";
      throw InputError(msg.str());
    }
    p.T_world_object = SE3(qo, Eigen::Vector3d(v[2], v[3], v[4]));
    p.T_world_sensor = SE3(qs, Eigen::Vector3d(v[9], v[10], v[11]));
    if (v[16] != 0.0 && v[16] != 1.0) throw InputError(where + ": contact must be 0, 1 or empty");
    p.contact = v[16] == 1.0;
    poses.push_back(p);
  }
  return poses;
}

SensorJumps sensor_jumps(const std::vector<FramePose>& poses) {
  SensorJumps jumps;
  for (std::size_t i = 1; i < poses.size(); ++i) {
    const SE3& before = poses[i - 1].T_world_sensor;
    const SE3& after = poses[i].T_world_sensor;
    const double m = translation_distance(before, after), rad = rotation_distance(before, after);
    if (m > kSensorJumpM || rad > kSensorJumpRad) {
      if (jumps.count++ == 0) {
        jumps.first = int(i);
        jumps.first_m = m;
        jumps.first_rad = rad;
      }
    }
  }
  return jumps;
}

std::string describe(const SensorJumps& jumps, int first_row_line) {
  char text[320];
  std::snprintf(text, sizeof text,
                "the sensor pose jumps by more than %.0f mm or %.1f rad from one frame to the next "
                "%d time(s), first from frame %d to %d (",
                kSensorJumpM * 1e3, kSensorJumpRad, jumps.count, jumps.first - 1, jumps.first);
  std::string out = text;
  if (first_row_line > 0) {
    out += "lines " + std::to_string(jumps.first - 1 + first_row_line) + "-" +
           std::to_string(jumps.first + first_row_line) + ": ";
  }
  std::snprintf(text, sizeof text, "%.1f mm, %.3f rad)", jumps.first_m * 1e3, jumps.first_rad);
  return out + text;
}

void DatasetWriter::check_folder(const std::string& dir, DatasetMaker maker) {
  std::error_code ec;
  if (!fs::exists(dir, ec)) return;
  if (!fs::is_directory(dir, ec)) {
    throw InputError(dir + ": exists and is not a folder; give a folder for the dataset");
  }
  if (fs::is_empty(dir, ec)) return;
  bool dataset = false;
  try {
    const nlohmann::json j = parse_json_file((fs::path(dir) / "dataset.json").string());
    dataset = j.is_object() && j.value("format", "") == "patchgraph-dataset";
  } catch (const std::exception&) {
    // not a dataset's description
  }
  const auto several_sensors = [&dir] {
    if (fs::exists(fs::path(dir) / "dataset.json")) return false;  // of another format
    try {
      return !sensor_dataset_dirs(dir).empty();
    } catch (const std::exception&) {
      return false;  // a sensors.json of someone else's
    }
  };
  if (!dataset && several_sensors()) {
    throw InputError(dir + ": holds a render of several sensors (" + kSensorIndexFile +
                     "); one sensor's dataset written there would leave their folders beside it; "
                     "give a new or empty folder, or remove that render first");
  }
  if (!dataset) {
    throw InputError(dir +
                     ": is not empty and holds no dataset (no dataset.json of the "
                     "patchgraph-dataset format), so writing one there could replace your files; "
                     "give a new or empty folder, or an earlier dataset's folder to replace it");
  }
  const DatasetMaker made = fs::exists(fs::path(dir) / "circles.csv", ec) ? DatasetMaker::kLabelBall
                            : fs::exists(fs::path(dir) / "sources.csv", ec)
                                ? DatasetMaker::kRecording
                                : DatasetMaker::kRender;
  if (made != DatasetMaker::kRender && made != maker) {
    const char* writer = maker == DatasetMaker::kRender      ? "a render"
                         : maker == DatasetMaker::kRecording ? "a recording"
                                                             : "label-ball";
    throw InputError(dir +
                     (made == DatasetMaker::kRecording
                          ? ": holds a recording of a real sensor (sources.csv), whose frames "
                          : ": holds presses labelled by label-ball (circles.csv, perhaps "
                            "corrected by hand), whose labels ") +
                     writer +
                     " there would replace; give a new or empty folder, or remove that dataset "
                     "first");
  }
}

DatasetWriter::DatasetWriter(std::string dir, DatasetInfo info, DatasetMaker maker)
    : dir_(std::move(dir)),
      info_(std::move(info)),
      poses_(info_.frames),
      written_(info_.frames, 0) {
  check_folder(dir_, maker);
  std::error_code ec;
  const fs::path earlier_poses = fs::path(dir_) / "poses.csv";
  if (fs::exists(earlier_poses, ec) && !fs::remove(earlier_poses, ec)) {
    throw InputError(earlier_poses.string() +
                     ": cannot remove the earlier dataset's poses: " + ec.message());
  }
  fs::create_directories(dir_, ec);
  if (ec) throw InputError(dir_ + ": cannot create the dataset folder: " + ec.message());
  for (const auto& o : info_.outputs) {
    fs::create_directories(fs::path(dir_) / o, ec);
    if (ec) throw InputError(dir_ + "/" + o + ": cannot create: " + ec.message());
  }
  write_text_atomically((fs::path(dir_) / "dataset.json").string(),
                        info_to_json(info_).dump(2) + "\n");
}

void DatasetWriter::write_frame(const FramePose& pose, const FrameImages& images) {
  if (pose.frame < 0 || pose.frame >= info_.frames) {
    throw std::out_of_range("DatasetWriter: frame " + std::to_string(pose.frame) + " out of range");
  }
  const int w = info_.width(), h = info_.height();
  for (const auto& o : info_.outputs) {
    const std::string path = dataset_frame_path(dir_, o, pose.frame);
    if (o == "color") check_image(path, images.color, w, h, 3), write_image(path, images.color);
    if (o == "normal") check_image(path, images.normal, w, h, 3), write_image(path, images.normal);
    if (o == "normal_png") {
      check_image(path, images.normal, w, h, 3);
      ImageF encoded = images.normal;
      for (float& v : encoded.data) v = 0.5f * (v + 1.0f);
      write_image_u16(path, encoded);
    }
    if (o == "depth") check_image(path, images.depth, w, h, 1), write_image(path, images.depth);
    if (o == "mask") check_image(path, images.mask, w, h, 1), write_image(path, images.mask);
    if (o == "points") write_ply(path, images.contact_points);
  }
  std::lock_guard<std::mutex> lock(mutex_);
  poses_[pose.frame] = pose;
  written_[pose.frame] = 1;
}

void DatasetWriter::write_background(const ImageU8& color) {
  const std::string path = (fs::path(dir_) / "background.png").string();
  check_image(path, color, info_.width(), info_.height(), 3);
  write_image(path, color);
  background_written_ = true;
}

void DatasetWriter::finish() {
  const auto missing = std::find(written_.begin(), written_.end(), 0);
  if (missing != written_.end()) {
    throw std::logic_error("DatasetWriter::finish: frame " +
                           std::to_string(missing - written_.begin()) + " was never written");
  }
  write_poses_csv((fs::path(dir_) / "poses.csv").string(), poses_);
  remove_stale_frames();
}

// An earlier dataset in the same folder (a longer sequence, or other outputs) left frame files
// this one did not overwrite: they are removed, so the folder holds one dataset. Only files named
// as a dataset's frames (000042.png in an output's folder) go, an output folder that is left
// empty, and circles.csv and sources.csv (label-ball's and recording's lists of the earlier
// frames) and background.png unless this dataset wrote one; anything else in the folder stays.
void DatasetWriter::remove_stale_frames() const {
  for (const std::string& output : dataset_output_names()) {
    const fs::path folder = fs::path(dir_) / output;
    std::error_code ec;
    if (!fs::is_directory(folder, ec)) continue;
    const bool written = info_.has_output(output);
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
      const std::string stem = entry.path().stem().string();
      if (stem.empty() || stem.size() > 9 || stem.find_first_not_of("0123456789") != stem.npos) {
        continue;
      }
      const int frame = std::stoi(stem);
      const bool frame_file =
          entry.path().filename() == fs::path(dataset_frame_path(dir_, output, frame)).filename();
      if (frame_file && (!written || frame >= info_.frames)) fs::remove(entry.path(), ec);
    }
    if (!written && fs::is_empty(folder, ec)) fs::remove(folder, ec);
  }
  // The lists of the earlier frames' circles (patchgraph label-ball) and source files
  // (patchgraph recording), which those write after this.
  std::error_code ec;
  fs::remove(fs::path(dir_) / "circles.csv", ec);
  fs::remove(fs::path(dir_) / "sources.csv", ec);
  // An earlier dataset's reference image would pass for this one's.
  if (!background_written_) fs::remove(fs::path(dir_) / "background.png", ec);
}

void write_sensor_index(const std::string& dir, const std::vector<std::string>& names) {
  const std::string path = (fs::path(dir) / kSensorIndexFile).string();
  write_text_atomically(path, nlohmann::json({{"sensors", names}}).dump(2) + "\n");
}

std::vector<std::string> sensor_dataset_dirs(const std::string& dir) {
  if (fs::is_regular_file(fs::path(dir) / "dataset.json")) return {dir};
  const std::string path = (fs::path(dir) / kSensorIndexFile).string();
  if (!fs::is_regular_file(path)) return {};
  const nlohmann::json j = parse_json_file(path);
  JsonFields f(j, path);
  const auto names = f.required<std::vector<std::string>>("sensors");
  f.finish();
  if (names.empty()) throw InputError(path + ": sensors: empty");
  std::vector<std::string> dirs;
  for (auto name = names.begin(); name != names.end(); ++name) {
    if (name->empty() || *name == "." || *name == ".." ||
        name->find_first_of("/\\") != std::string::npos) {
      throw InputError(path + ": sensors: '" + *name + "' is not a folder name");
    }
    if (std::find(names.begin(), name, *name) != name) {
      throw InputError(path + ": sensors: '" + *name +
                       "' listed twice (one sensor's measurements would count double)");
    }
    dirs.push_back((fs::path(dir) / *name).string());
    if (!fs::is_directory(dirs.back())) {
      throw InputError(path + ": sensors: '" + *name + "': no such folder next to it (" +
                       dirs.back() + ")");
    }
  }
  return dirs;
}

Dataset Dataset::open(const std::string& dir) {
  if (!fs::is_directory(dir)) {
    // A file where the folder goes: a frame or the dataset.json, given instead of its folder.
    throw InputError(dir + (fs::exists(dir) ? ": is a file, not a dataset folder (give the folder "
                                              "that holds dataset.json)"
                                            : ": dataset folder not found"));
  }
  Dataset d;
  d.dir_ = dir;
  const std::string info_path = (fs::path(dir) / "dataset.json").string();
  if (!fs::exists(info_path) && fs::exists(fs::path(dir) / kSensorIndexFile)) {
    std::string sensors;
    for (const std::string& sub : sensor_dataset_dirs(dir)) {
      sensors += (sensors.empty() ? "" : ", ") + fs::path(sub).filename().string();
    }
    throw InputError(dir + ": is not a dataset, but a render of several sensors (" +
                     kSensorIndexFile + "): " + sensors +
                     "; give one of those folders (patchgraph track takes " + dir +
                     " itself, to track them together)");
  }
  if (!fs::exists(info_path)) {
    // A scene of several sensors writes one dataset per sensor, in folders under its --out (an
    // older render, without sensors.json), or DIR is a folder of datasets.
    std::string sensors;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir, ec)) {
      if (fs::exists(entry.path() / "dataset.json")) {
        sensors += (sensors.empty() ? "" : ", ") + entry.path().filename().string();
      }
    }
    if (!sensors.empty()) {
      throw InputError(
          dir + ": is not a dataset, but holds datasets: " + sensors +
          "; give one of those folders (patchgraph track takes several sensors' folders of one "
          "sequence, to track them together)");
    }
    throw InputError(info_path +
                     ": missing: not a dataset folder (tacsim render writes one; a folder of a "
                     "sensor's frames becomes one with patchgraph recording)");
  }
  d.info_ = info_from_json(parse_json_file(info_path), info_path);
  const std::string poses_path = (fs::path(dir) / "poses.csv").string();
  // DatasetWriter writes poses.csv last (and removes an earlier dataset's first).
  if (!fs::exists(poses_path)) {
    throw InputError(poses_path +
                     ": missing: the dataset was never finished (its render or import stopped "
                     "or failed); write it again");
  }
  d.poses_ = read_poses_csv(poses_path);
  if (int(d.poses_.size()) != d.info_.frames) {
    throw InputError(poses_path + ": has " + std::to_string(d.poses_.size()) +
                     " frames, dataset.json says " + std::to_string(d.info_.frames));
  }
  for (const auto& o : d.info_.outputs) {
    for (int i = 0; i < d.info_.frames; ++i) {
      const std::string path = dataset_frame_path(dir, o, i);
      if (!fs::is_regular_file(path)) {
        throw InputError(path + (fs::exists(path) ? ": not a file (a frame file is expected here)"
                                                  : ": missing frame file"));
      }
    }
  }
  return d;
}

namespace {

template <typename T, typename Reader>
Image<T> read_checked(const Dataset& d, const std::string& output, int frame, Reader read) {
  if (!d.info().has_output(output)) {
    throw InputError(d.dir() + ": dataset has no '" + output + "' output");
  }
  if (frame < 0 || frame >= d.frames()) {
    throw InputError(d.dir() + ": frame " + std::to_string(frame) + " out of range");
  }
  const std::string path = dataset_frame_path(d.dir(), output, frame);
  Image<T> image = read(path);
  check_image(path, image, d.info().width(), d.info().height(), channels_of(output));
  return image;
}

}  // namespace

ImageU8 Dataset::color(int frame) const {
  return read_checked<std::uint8_t>(*this, "color", frame, read_image_u8);
}
ImageU8 Dataset::background() const {
  const std::string path = (fs::path(dir_) / "background.png").string();
  require_regular_file(path, "a background image");  // not taken for a missing one
  if (fs::is_regular_file(path)) {
    ImageU8 image = read_image_u8(path);
    check_image(path, image, info_.width(), info_.height(), 3);
    return image;
  }
  const std::vector<int> frames = reference_frames();
  if (frames.empty()) {
    throw InputError(dir_ +
                     ": no background.png and no frame that poses.csv marks as without "
                     "contact to use as the no-contact reference image");
  }
  // Their median (image_change.h: not their mean, and quieter than one frame).
  std::vector<ImageU8> images;
  for (int f : frames) images.push_back(color(f));
  return median_image(images);
}

std::vector<int> Dataset::reference_frames() const {
  std::vector<int> frames;
  for (const FramePose& p : poses_) {
    if (int(frames.size()) == kMaxReferenceFrames) break;
    if (p.contact_known && !p.contact) frames.push_back(p.frame);
  }
  return frames;
}

ImageF Dataset::normal(int frame) const {
  if (!info_.has_output("normal") && info_.has_output("normal_png")) return normal_png(frame);
  return read_checked<float>(*this, "normal", frame, read_float_file);
}
ImageF Dataset::normal_png(int frame) const {
  ImageF n = read_checked<float>(*this, "normal_png", frame, read_u16_file);
  for (std::size_t i = 0; i < n.data.size(); i += 3) {
    Eigen::Vector3f v(2 * n.data[i] - 1, 2 * n.data[i + 1] - 1, 2 * n.data[i + 2] - 1);
    const float norm = v.norm();
    if (norm > 0) v /= norm;
    for (int c = 0; c < 3; ++c) n.data[i + std::size_t(c)] = v[c];
  }
  return n;
}
ImageF Dataset::depth(int frame) const {
  return read_checked<float>(*this, "depth", frame, read_float_file);
}
ImageU8 Dataset::mask(int frame) const {
  return read_checked<std::uint8_t>(*this, "mask", frame, read_image_u8);
}
std::vector<Eigen::Vector3f> Dataset::contact_points(int frame) const {
  if (!info_.has_output("points")) throw InputError(dir_ + ": dataset has no 'points' output");
  if (frame < 0 || frame >= frames()) {
    throw InputError(dir_ + ": frame " + std::to_string(frame) + " out of range");
  }
  return read_ply(dataset_frame_path(dir_, "points", frame));
}

}  // namespace pg
