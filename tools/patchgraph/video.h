#pragma once
// A video file's frames, decoded in order by FFmpeg's libraries (libavformat, libavcodec,
// libswscale), as 8-bit RGB: `patchgraph recording --video`. FFmpeg is included only by
// video_ffmpeg.cpp.
#include <memory>
#include <string>

#include "pg/core/file_io.h"
#include "pg/core/image.h"

namespace pg {

// What a video file says about itself before its frames are decoded.
struct VideoInfo {
  int width = 0, height = 0;
  std::string codec;         // "h264", "ffv1", ...
  std::string pixel_format;  // the decoder's: "yuv420p", "bgr0", ...
  // The stream's average frame rate, 0 if the container gives none.
  double fps = 0.0;
  // The colour is stored at a lower resolution than the brightness (4:2:0, 4:2:2: each colour
  // sample covers 2 or 4 pixels).
  bool chroma_subsampled = false;
  // The codec is lossy by design (MJPEG, MPEG-4 part 2); false where it may be either (H.264 at
  // -qp 0 is lossless) or is lossless (FFV1, PNG, raw).
  bool lossy_codec = false;
  bool lossless_codec = false;  // only lossless (FFV1, PNG, raw video, ...)
  bool grey = false;            // one channel (and alpha): no colour to read the lights from
  bool palette = false;         // 256 colours at most (GIF)
  bool coarse_times = false;    // its timestamps do not time the frames (GIF)
  int video_streams = 1;        // how many the file holds (cover pictures not counted)
  int stream_index = 0;         // the one read
  // How far a player turns the frames to show them (0, 90, 180 or 270 degrees: a phone's display
  // matrix, whose direction conventions vary between writers); the frames are decoded as
  // stored, not turned.
  int display_rotation = 0;
  // What the file's header says of its length: its frame count and its duration (0 where it
  // does not say), so that a file cut short can be told.
  long header_frames = 0;
  double duration_s = 0.0;
};

// A video's frames, decoded in order: an FFmpeg decoder (video_ffmpeg.cpp).
class VideoReader {
 public:
  virtual ~VideoReader() = default;
  virtual const VideoInfo& info() const = 0;
  // The next frame as RGB (3 channels) and its time in seconds from the stream's start; false
  // after the last. A frame that does not decode whole (a file cut short, a damaged packet) is
  // left out and counted (damaged_frames). Throws InputError naming the file and frame when a
  // frame changes size.
  virtual bool next(ImageU8& rgb, double& time_s) = 0;
  // Frames or packets left out as damaged so far, and what the first one's damage was.
  virtual int damaged_frames() const = 0;
  virtual const std::string& first_damage() const = 0;
};

// Opens the file's best video stream; throws InputError naming the file when it is missing,
// not a video FFmpeg can read, or has no video stream. FFmpeg's libraries are a module of their
// own (pg_video), loaded by the first call: they are some 130 libraries, and in a program's own
// start-up every image read later (OpenImageIO, also loaded when needed) took 0.2 s longer.
std::unique_ptr<VideoReader> open_video(const std::string& path);

}  // namespace pg
