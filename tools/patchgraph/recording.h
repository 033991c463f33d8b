#pragma once
// patchgraph recording: a real sensor's frames -> a dataset the tracker reads.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace pg {

struct RecordingArgs {
  std::string images;          // folder of the frames, taken in file-name order
  std::string video;           // or a video file of them (one of the two)
  // The sensor's images with nothing touching (files, folders of them, or videos): their per-pixel
  // median is the no-contact reference.
  std::vector<std::string> backgrounds;
  // "FIRST-LAST": frames of --images or --video that show nothing touching, whose median is
  // the reference too (with --background, or instead of it); they stay frames of the dataset.
  std::string background_frames;
  std::string poses;           // poses.csv in the dataset's format, one row per frame
  bool static_sensor = false;  // no poses file: the sensor did not move (the world is its frame)
  std::string sensor = "digit";
  std::string sensor_file;
  double fps = 0.0;    // 0: not given (60 with --static-sensor; --poses' time column's rate)
  int downsample = 1;  // average N x N pixel blocks
  int rotate = 0;      // turn each image clockwise by this many degrees first (0, 90, 180, 270)
  std::string object;  // name of the object, for the outputs
  std::string out;
  bool quiet = false;
};

CLI::App* add_recording_command(CLI::App& app, RecordingArgs& args);
int run_recording(const RecordingArgs& args);

}  // namespace pg
