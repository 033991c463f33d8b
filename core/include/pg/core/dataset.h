#pragma once
// The dataset format: what the renderer writes and the tracker reads.
//
//   DIR/dataset.json      sensor model, image size, frame count, outputs, scene, seed, object
//   DIR/poses.csv         one row per frame (world frame, metres, unit quaternions x y z w);
//                         a recording may leave the object pose and the contact cells empty
//   DIR/color/000000.png  8-bit RGB           DIR/normal/000000.exr  float xyz in S
//   DIR/depth/000000.exr  indentation [m]     DIR/mask/000000.png    contact 0/255
//   DIR/points/000000.ply the tracked object's contact points, in its own frame (optional)
//   DIR/normal_png/000000.png  the normals as 16-bit RGB (n + 1) / 2, for tools without EXR
//                         (optional)
//   DIR/background.png    the sensor's no-contact colour image, noise free (with "color")
#include <mutex>
#include <string>
#include <vector>

#include "pg/core/image.h"
#include "pg/core/sensor.h"

namespace pg {

// Names of the per-frame outputs, in file order, and an error if `names` is empty or one of them
// is not one of these or is given twice (`where` names the field, e.g. "--outputs").
const std::vector<std::string>& dataset_output_names();
void check_output_names(const std::vector<std::string>& names, const std::string& where);

struct FramePose {
  int frame = 0;
  double time_s = 0.0;
  SE3 T_world_object;
  SE3 T_world_sensor;
  bool contact = false;
  // A recording has no ground truth: poses.csv may leave a row's seven object-pose cells empty
  // (the object's pose is not known at that frame; T_world_object is then the identity) and its
  // contact cell (not known; such a frame is never taken as the no-contact reference image).
  bool object_known = true;
  bool contact_known = true;
};

struct DatasetInfo {
  SensorModel sensor;
  int frames = 0;
  double fps = 60.0;
  std::vector<std::string> outputs;  // subset of dataset_output_names()
  std::string scene;                 // scene file it was rendered from ("" if none)
  std::uint64_t seed = 0;
  std::string object_name;  // the tracked object
  std::string object_mesh;  // its mesh file (absolute path), for model-based baselines
  double object_scale = 1.0;
  // How a rendered dataset was shaded beyond its sensor (the scene's "render" block after tacsim
  // render's overrides), when known: not for a recording, nor a render from before these were
  // recorded.
  bool render_known = false;
  bool shadows = false;
  std::string background;  // the real background image blended in (absolute path), "" if none

  bool has_output(const std::string& name) const;
  // Normals in either form: "normal" (float EXR) or "normal_png" (16-bit), which Dataset::normal
  // reads.
  bool has_normals() const;
  // Whether the frames are a real background plus the shading's change (a render blended onto a
  // real image, or a real sensor's recording, whose no-contact image is its own), not the sensor
  // model's shading itself: how the shading's inverse and the fit of a sensor's lights read them.
  bool on_real_background() const {
    return !background.empty() || (!render_known && scene.empty());
  }
  int width() const { return sensor.camera.width; }
  int height() const { return sensor.camera.height; }
};

struct FrameImages {
  ImageU8 color;   // width x height x 3
  ImageF normal;   // width x height x 3, unit normals in S
  ImageF depth;    // width x height x 1, gel indentation [m]
  ImageU8 mask;    // width x height x 1, 0 or 255
  std::vector<Eigen::Vector3f> contact_points;  // object frame [m], for the "points" output
};

// Path of one frame's image for an output, e.g. DIR/color/000042.png.
std::string dataset_frame_path(const std::string& dir, const std::string& output, int frame);

// Which command made a dataset, as its folder tells: `patchgraph recording` (a real sensor's
// frames, listed in its sources.csv), `patchgraph label-ball` (presses labelled in circles.csv,
// perhaps corrected by hand), or a render (anything else: it can be made again).
enum class DatasetMaker { kRender, kRecording, kLabelBall };

// Writes a dataset. Frames may be written from several threads, in any order.
class DatasetWriter {
 public:
  // Creates DIR and the output folders and writes dataset.json. An earlier dataset in DIR is
  // replaced: its poses.csv goes first, so that a run that stops before finish() leaves a folder
  // that does not open as a dataset (rather than the new dataset.json over the old frames).
  // Throws InputError naming the path, or check_folder's (for a dataset `maker` writes).
  DatasetWriter(std::string dir, DatasetInfo info, DatasetMaker maker = DatasetMaker::kRender);
  // Throws InputError unless DIR can take a new dataset from `maker`: it does not exist, or is an
  // empty folder, or holds a dataset (its dataset.json says so; finished or not) that is a render
  // or `maker`'s own. Writing into any other folder would replace and remove the user's own files
  // of the dataset's names (poses.csv, 000007.png); over a recording or a labelled dataset, its
  // frames or circles, which no render makes again.
  static void check_folder(const std::string& dir, DatasetMaker maker = DatasetMaker::kRender);
  // Writes the requested outputs (each must be present and of the sensor's image size).
  void write_frame(const FramePose& pose, const FrameImages& images);
  // Writes DIR/background.png: what the sensor shows without contact (the reference frame a
  // real sensor's pipeline captures before touching anything).
  void write_background(const ImageU8& color);
  // Writes poses.csv; every frame 0..frames-1 must have been written. Then removes the frame
  // files an earlier dataset in the folder left that this one did not overwrite (frames past its
  // last, outputs it does not have, a background.png it did not write), so that the folder holds
  // one dataset.
  void finish();

 private:
  void remove_stale_frames() const;
  std::string dir_;
  DatasetInfo info_;
  std::vector<FramePose> poses_;
  std::vector<char> written_;
  bool background_written_ = false;
  std::mutex mutex_;
};

class Dataset {
 public:
  // Reads and checks dataset.json and poses.csv, and that every frame's files exist. Throws
  // InputError naming the file (and row/field) for anything missing, malformed or non-finite.
  static Dataset open(const std::string& dir);

  const std::string& dir() const { return dir_; }
  const DatasetInfo& info() const { return info_; }
  const std::vector<FramePose>& poses() const { return poses_; }
  int frames() const { return info_.frames; }

  // Each checks the image size and channel count against dataset.json.
  ImageU8 color(int frame) const;
  // The "normal" output, or without it the "normal_png" one (normal_png()).
  ImageF normal(int frame) const;
  // The "normal_png" output decoded: 16-bit (n + 1) / 2, back to unit normals (about 3e-5 off).
  ImageF normal_png(int frame) const;
  ImageF depth(int frame) const;
  ImageU8 mask(int frame) const;
  std::vector<Eigen::Vector3f> contact_points(int frame) const;
  // The no-contact reference colour image: DIR/background.png, or else the per-pixel median of
  // reference_frames() (of an even count, the two middle values' mean). Throws InputError when
  // there is neither.
  ImageU8 background() const;
  // Without background.png, the frames whose median is the no-contact reference: the first
  // kMaxReferenceFrames that poses.csv marks as without contact. One frame would carry its camera
  // noise into every difference image the learned normals read (docs/learned_normals.md).
  std::vector<int> reference_frames() const;
  static constexpr int kMaxReferenceFrames = 32;

 private:
  std::string dir_;
  DatasetInfo info_;
  std::vector<FramePose> poses_;
};

// A scene of several sensors renders one dataset per sensor, DIR/<name>/, and lists their names
// in the scene's order in DIR/sensors.json: {"sensors": ["digit_bottom", "digit_top"]}.
inline constexpr const char* kSensorIndexFile = "sensors.json";
void write_sensor_index(const std::string& dir, const std::vector<std::string>& names);
// The dataset folders DIR stands for: DIR itself when it holds a dataset (dataset.json), the
// sensors' folders of DIR/sensors.json in its order, else none. Throws InputError naming
// sensors.json and the field when it is malformed.
std::vector<std::string> sensor_dataset_dirs(const std::string& dir);

void write_poses_csv(const std::string& path, const std::vector<FramePose>& poses);
std::vector<FramePose> read_poses_csv(const std::string& path);

// Where the sensor pose moves further from one row to the next than a hand does (more than
// kSensorJumpM, 3 m/s at 60 fps, or kSensorJumpRad): likelier a glitch in the poses than a
// motion. The tracker takes them as given, so `track` and `recording` warn.
inline constexpr double kSensorJumpM = 0.05, kSensorJumpRad = 0.5;
struct SensorJumps {
  int count = 0;
  int first = -1;  // the row the first jump lands on (-1: none)
  double first_m = 0.0, first_rad = 0.0;
};
SensorJumps sensor_jumps(const std::vector<FramePose>& poses);
// "the sensor pose jumps by more than 50 mm or 0.5 rad from one frame to the next 2 time(s),
// first from frame 10 to 11 (1000.0 mm, 0.000 rad)"; `first_row_line` > 0 names the first
// jump's rows by their lines in the poses file too, "(lines 12-13: 1000.0 mm, ...)", row i
// being at line i + first_row_line.
std::string describe(const SensorJumps& jumps, int first_row_line = 0);

}  // namespace pg
