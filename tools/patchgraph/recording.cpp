#include "recording.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <vector>

#include "../common/cli_main.h"
#include "../common/progress.h"
#include "../common/sensor_choice.h"
#include "pg/core/dataset.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/gel_rays.h"
#include "pg/core/image.h"
#include "pg/core/image_change.h"
#include "pg/core/sensor.h"
#include "pg/graph/track_dataset.h"
#include "pg/tracker/contact_cloud.h"
#include "video.h"

namespace pg {

namespace fs = std::filesystem;

namespace {

bool is_image_file(const fs::path& path) {
  const std::string ext = lower_extension(path.string());
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp" || ext == ".tif" ||
         ext == ".tiff";
}

// The name with each run of digits left-padded with zeros to 20: its text order is the order of
// the numbers in it ("frame2" before "frame10").
std::string numbers_padded(const std::string& name) {
  std::string out, digits;
  for (std::size_t k = 0; k <= name.size(); ++k) {
    if (k < name.size() && std::isdigit(static_cast<unsigned char>(name[k]))) {
      digits += name[k];
      continue;
    }
    if (!digits.empty())
      out += std::string(digits.size() < 20 ? 20 - digits.size() : 0, '0') + digits;
    digits.clear();
    if (k < name.size()) out += name[k];
  }
  return out;
}

// The frame files of DIR in name order; hidden files (a copy tool's "._frame.png") are not
// frames. Warns when the names' numbers are not zero-padded, so that name order is not their
// numbers' order ("frame10" before "frame2"), where the order matters (`in_order`). `option`
// names the folder's option in messages. `videos`: video files count as well as images.
std::vector<fs::path> image_files(const std::string& dir, const std::string& option,
                                  bool in_order = true, bool videos = false) {
  if (!fs::is_directory(dir)) throw InputError(dir + ": not a folder (" + option + ")");
  std::vector<fs::path> files;
  std::string video_seen;
  for (const auto& entry : fs::directory_iterator(dir)) {
    const bool hidden = entry.path().filename().string().rfind('.', 0) == 0;
    if (hidden || !entry.is_regular_file()) continue;
    const bool video = has_video_extension(entry.path().string());
    if (is_image_file(entry.path()) || (videos && video)) files.push_back(entry.path());
    if (video) video_seen = entry.path().string();
  }
  if (files.empty()) {
    throw InputError(dir + ": holds no image (png, jpg, bmp or tif" +
                     (videos ? ") or video (" : ") (") + option + ")" +
                     (video_seen.empty()
                          ? ""
                          : "; it holds a video, " + video_seen + ": give it as --video FILE"));
  }
  std::sort(files.begin(), files.end());
  for (std::size_t i = 1; in_order && i < files.size(); ++i) {
    const std::string earlier = files[i - 1].filename().string(),
                      later = files[i].filename().string();
    if (numbers_padded(later) < numbers_padded(earlier)) {
      std::fprintf(stderr,
                   "warning: %s: the frames are taken in name order, in which %s comes before "
                   "%s; if that is not the order they were taken in, pad the numbers with zeros\n",
                   dir.c_str(), earlier.c_str(), later.c_str());
      break;
    }
  }
  return files;
}

// Warns when the frames' numbers (the last run of digits in each name, when every name has one
// and they rise in name order) skip some: each image becomes the next frame, and the tracker
// steps its motion priors per frame, so a frame missing from the camera's numbering is a jump.
void warn_of_numbering_gaps(const std::vector<fs::path>& files, const std::string& dir) {
  std::vector<long long> numbers;
  for (const fs::path& file : files) {
    const std::string stem = file.stem().string();
    const std::size_t end = stem.find_last_of("0123456789");
    if (end == std::string::npos) return;
    std::size_t begin = end;
    while (begin > 0 && std::isdigit(static_cast<unsigned char>(stem[begin - 1]))) --begin;
    if (end - begin >= 18) return;  // not a frame counter
    numbers.push_back(std::stoll(stem.substr(begin, end - begin + 1)));
    if (numbers.size() > 1 && numbers.back() <= numbers[numbers.size() - 2]) return;
  }
  std::string gaps;
  long long missing = 0;
  int listed = 0;
  for (std::size_t i = 1; i < numbers.size(); ++i) {
    const long long from = numbers[i - 1] + 1, to = numbers[i] - 1;
    if (to < from) continue;
    missing += to - from + 1;
    if (++listed <= 3) {
      gaps += (gaps.empty() ? "" : ", ") + std::to_string(from) +
              (to > from ? "-" + std::to_string(to) : "") + " (after " +
              files[i - 1].filename().string() + ")";
    }
  }
  if (missing == 0) return;
  std::fprintf(stderr,
               "warning: %s: the frames' numbers skip %lld: %s%s; each image becomes the next "
               "frame, and the tracker steps its motion priors per frame, so a missing frame is a "
               "jump in the motion (ball presses for label-ball do not mind)\n",
               dir.c_str(), missing, gaps.c_str(), listed > 3 ? " and more" : "");
}

// How a camera's files become the sensor's frames: turned clockwise by `rotate` degrees (a
// driver's landscape frames of a portrait sensor), then `factor` x `factor` blocks averaged.
struct FrameReading {
  CameraModel camera;
  int factor = 1;
  int rotate = 0;
  // A file's image shape once turned.
  ImageShape turned(const ImageShape& raw) const {
    return rotate % 180 == 0 ? raw : ImageShape{raw.height, raw.width, raw.channels};
  }
};

// Throws InputError naming the file unless an image of this shape (turned as `reading` turns it)
// is a frame of the sensor: RGB (or RGBA) at the camera's size times the factor.
void check_frame_shape(const std::string& path, const ImageShape& raw,
                       const FrameReading& reading) {
  const CameraModel& camera = reading.camera;
  const int factor = reading.factor, rotate = reading.rotate;
  if (raw.channels != 3 && raw.channels != 4) {
    throw InputError(path + ": " + std::to_string(raw.channels) +
                     (raw.channels == 1 ? " channel (grey)" : " channels") +
                     "; a tactile sensor's frame is RGB");
  }
  if (raw.width != camera.width * factor || raw.height != camera.height * factor) {
    const auto size = [](int w, int h) { return std::to_string(w) + "x" + std::to_string(h); };
    std::string text = path + ": " + size(raw.width, raw.height) +
                       " px, but the sensor's frames are " + size(camera.width, camera.height) +
                       " px";
    if (factor > 1) {
      text += ", so with --downsample " + std::to_string(factor) + " the images must be " +
              size(camera.width * factor, camera.height * factor) + " px";
    }
    std::vector<std::string> hints;
    if (raw.width % camera.width == 0 && raw.height % camera.height == 0 &&
        raw.width / camera.width == raw.height / camera.height) {
      hints.push_back("--downsample " + std::to_string(raw.width / camera.width) +
                      " fits this image");
    }
    for (const std::string& name : sensor_preset_names()) {
      const SensorModel preset = sensor_preset(name);
      if (preset.camera.width == raw.width && preset.camera.height == raw.height) {
        hints.push_back("--sensor " + name + " takes " + size(raw.width, raw.height) + " frames");
      }
    }
    // Turned by 90 degrees (a camera driver's landscape frames of a portrait sensor), at this
    // factor or another.
    if (raw.width % camera.height == 0 && raw.height % camera.width == 0 &&
        raw.width / camera.height == raw.height / camera.width) {
      const int turned = raw.width / camera.height;
      hints.push_back(
          "the image is turned by 90 degrees (the sensor's are " +
          std::string(camera.width < camera.height ? "portrait" : "landscape") +
          (rotate == 0
               ? "): --rotate 90 or 270 turns the frames, whichever puts "
                 "the sensor's lights where its model has them"
               : "), as --rotate " + std::to_string(rotate) + " turned it: leave --rotate out") +
          (turned != factor ? "; turned, they take --downsample " + std::to_string(turned)
                            : std::string()));
    }
    if (!hints.empty()) {
      text += " (";
      for (std::size_t k = 0; k < hints.size(); ++k) text += (k ? "; " : "") + hints[k];
      text += ")";
    }
    throw InputError(text);
  }
}

// `image` turned clockwise by `degrees` (0, 90, 180 or 270).
ImageU8 rotate_clockwise(const ImageU8& image, int degrees) {
  if (degrees == 0) return image;
  const int w = image.width, h = image.height;
  ImageU8 out = degrees == 180 ? ImageU8(w, h, image.channels) : ImageU8(h, w, image.channels);
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      // The source pixel of (x, y): clockwise, the first column becomes the first row.
      const int sx = degrees == 90 ? y : degrees == 180 ? w - 1 - x : w - 1 - y;
      const int sy = degrees == 90 ? h - 1 - x : degrees == 180 ? h - 1 - y : x;
      for (int c = 0; c < image.channels; ++c) out.at(x, y, c) = image.at(sx, sy, c);
    }
  }
  return out;
}

// An 8-bit RGB image of the sensor's size from a camera's image (`name` in messages): an alpha
// channel is dropped, the image turned and `factor` x `factor` pixel blocks averaged (rounded to
// the nearest level).
ImageU8 sensor_image(const ImageU8& image, const std::string& name, const FrameReading& reading) {
  const CameraModel& camera = reading.camera;
  const int factor = reading.factor;
  const ImageU8 raw = rotate_clockwise(image, reading.rotate);
  check_frame_shape(name, {raw.width, raw.height, raw.channels}, reading);
  ImageU8 out(camera.width, camera.height, 3);
  const int n = factor * factor;
  for (int y = 0; y < out.height; ++y) {
    for (int x = 0; x < out.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        int sum = 0;
        for (int dy = 0; dy < factor; ++dy) {
          for (int dx = 0; dx < factor; ++dx) sum += raw.at(x * factor + dx, y * factor + dy, c);
        }
        out.at(x, y, c) = static_cast<std::uint8_t>((sum + n / 2) / n);
      }
    }
  }
  return out;
}

// The same from an image file.
ImageU8 sensor_image(const std::string& path, const FrameReading& reading) {
  return sensor_image(read_image_u8(path), path, reading);
}

// The no-contact images --background names: each file, and the image and video files of each
// folder; each once (a folder given twice, or a file also in a folder given, would weigh double).
std::vector<fs::path> background_files(const std::vector<std::string>& given) {
  std::vector<fs::path> files;
  const auto add = [&](const fs::path& file) {
    const bool seen = std::any_of(files.begin(), files.end(), [&](const fs::path& f) {
      std::error_code ec;
      return f == file || fs::equivalent(f, file, ec);
    });
    if (!seen) files.push_back(file);
  };
  for (const std::string& path : given) {
    if (fs::is_directory(path)) {
      for (const fs::path& file : image_files(path, "--background", false, true)) add(file);
    } else {
      add(path);
    }
  }
  return files;
}

// The frame files of --images in name order, less the --background images kept among them;
// notes what is skipped, dropped frames and lossy files.
std::vector<fs::path> frame_files(const std::string& dir, const std::vector<fs::path>& references) {
  // A no-contact image kept beside the frames is the reference, not a frame.
  std::vector<fs::path> files, skipped;
  for (const fs::path& file : image_files(dir, "--images")) {
    const bool reference = std::any_of(references.begin(), references.end(), [&](const auto& r) {
      std::error_code ec;
      return fs::equivalent(file, r, ec);
    });
    (reference ? skipped : files).push_back(file);
  }
  if (files.empty()) {
    throw InputError(dir + ": every image in it is a --background image; no frame is left");
  }
  warn_of_numbering_gaps(files, dir);
  // Lossy frames: JPEG's 8x8 blocks change pixels of their own, which the press search and the
  // contact mask read as the gel's.
  const auto jpeg = [](const fs::path& file) {
    const std::string ext = lower_extension(file.string());
    return ext == ".jpg" || ext == ".jpeg";
  };
  const long jpegs = std::count_if(files.begin(), files.end(), jpeg);
  if (jpegs > 0) {
    std::fprintf(stderr,
                 "note: %ld of the %zu frames are JPEG: its compression changes pixels of its own, "
                 "which the contact mask and label-ball's press search read as the gel's (an "
                 "audit's ball presses: quality 75-90 labelled as PNG, 50 not); a lossless format "
                 "(PNG) keeps the camera's frames as they were\n",
                 jpegs, files.size());
  }
  if (skipped.size() == 1) {
    std::fprintf(stderr, "note: %s is a --background image: not taken as a frame\n",
                 skipped[0].string().c_str());
  } else if (!skipped.empty()) {
    std::fprintf(stderr,
                 "note: %zu images of %s are --background images (the first %s, the last %s): not "
                 "taken as frames\n",
                 skipped.size(), dir.c_str(), skipped.front().filename().string().c_str(),
                 skipped.back().filename().string().c_str());
  }
  return files;
}

// A video's frames as `reading` makes them the sensor's, read through once: what it is, and
// each frame's time in it.
struct VideoScan {
  VideoInfo info;
  std::vector<double> times_s;
  double fps = 0.0;           // the camera's rate: the container's, or one over the median step
  std::vector<ImageU8> kept;  // the frames of the range asked for, as the sensor's images
};

// Frames FIRST to LAST of the frames, both included.
struct FrameRange {
  int first = 0, last = -1;
  bool empty() const { return last < first; }
  bool contains(int i) const { return i >= first && i <= last; }
};

// --background-frames' "FIRST-LAST" (or one frame's number); a usage error unless it is one.
FrameRange parse_frame_range(const std::string& text) {
  FrameRange range;
  if (text.empty()) return range;
  const std::size_t dash = text.find('-');
  const auto number = [&](const std::string& part) {
    if (part.empty() || part.size() > 9 ||
        !std::all_of(part.begin(), part.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      throw UsageError("--background-frames " + text +
                       ": give FIRST-LAST, the frames' numbers from 0 (0-29: the first 30)");
    }
    return std::stoi(part);
  };
  range.first = number(text.substr(0, dash));
  range.last = dash == std::string::npos ? range.first : number(text.substr(dash + 1));
  if (range.last < range.first) {
    throw UsageError("--background-frames " + text + ": the last frame comes before the first");
  }
  return range;
}

// Warns when the video's timestamps skip frames (a webcam's dropped frames, a variable-rate
// file): each decoded frame becomes the next frame, and the tracker steps per frame.
void warn_of_time_gaps(const std::vector<double>& times, double step, const std::string& path) {
  // Jitter (a step of 25 ms after one of 8 at 60 frames per second) is no dropped frame: frames
  // are missing only when the span holds more steps than frames.
  const long span_steps = std::lround((times.back() - times.front()) / step);
  if (span_steps + 1 <= long(times.size())) return;
  int gaps = 0;
  long missing = 0;
  std::string listed;
  for (std::size_t i = 1; i < times.size(); ++i) {
    const double dt = times[i] - times[i - 1];
    if (!(dt > 1.5 * step)) continue;
    missing += std::lround(dt / step) - 1;
    if (++gaps <= 3) {
      listed += (listed.empty() ? "" : ", ") + std::string("after frame ") + std::to_string(i - 1) +
                " (" + format_number(dt * 1e3) + " ms)";
    }
  }
  if (gaps == 0) return;
  std::fprintf(stderr,
               "warning: %s: its timestamps skip about %ld frame%s at %d place%s, %s%s (the "
               "frames are %s ms apart): each decoded frame becomes the next frame, and the "
               "tracker steps its motion priors per frame, so a dropped frame is a jump in the "
               "motion\n",
               path.c_str(), missing, missing == 1 ? "" : "s", gaps, gaps > 1 ? "s" : "",
               listed.c_str(), gaps > 3 ? " and more" : "", format_number(step * 1e3).c_str());
}

// What a video's codec and pixel format do to a sensor's frames, as a note's text; "" when it
// keeps them as they were.
std::string codec_note(const VideoInfo& info) {
  const std::string subsampled =
      "holds the colour at a lower resolution than the brightness: each colour sample spans 2 "
      "or 4 pixels, which blurs the press's colour edges that the normals are read from";
  const std::string lossless_advice =
      "PNG frames or a lossless video (ffmpeg -c:v ffv1) keep the camera's frames as they were";
  if (info.chroma_subsampled && info.lossless_codec) {  // as the camera sent it
    return subsampled +
           ", as the camera sent it (a webcam's YUYV); a camera mode in RGB, if "
           "the camera has one, keeps them";
  }
  if (info.palette) {
    return "holds at most 256 colours (a palette): the gel's shading is quantised to them; " +
           lossless_advice;
  }
  if (info.chroma_subsampled) {
    return subsampled +
           " (measured on renders, H.264 at CRF 23: the default model's contact angle 10% worse "
           "than on PNG frames); a lossless RGB video (ffmpeg -c:v ffv1 -pix_fmt bgr0, or -c:v "
           "libx264rgb -qp 0), PNG frames, or at least -pix_fmt yuv444p keep the colour at full "
           "resolution";
  }
  if (!info.lossless_codec) {
    return std::string(info.lossy_codec ? "is compressed with loss"
                                        : "is compressed with loss unless it was made lossless "
                                          "(H.264 at -qp 0)") +
           ", which changes pixels of its own that the contact mask and the normals read as the "
           "gel's; " +
           lossless_advice;
  }
  return "";
}

// Throws InputError naming the video unless its frames have colour (the decoder would make RGB
// of grey frames, which the size check then passes).
void refuse_grey(const VideoInfo& info, const std::string& path) {
  if (info.grey) {
    throw InputError(path + ": grey frames (pixel format " + info.pixel_format +
                     "); a tactile sensor's frame is RGB");
  }
}

VideoScan scan_video(const std::string& path, const FrameReading& reading, const FrameRange& keep) {
  const std::unique_ptr<VideoReader> reader = open_video(path);
  VideoScan scan;
  scan.info = reader->info();
  const VideoInfo& info = scan.info;
  // A phone's video is stored turned and shown upright by its display matrix, which decoding
  // does not apply: said before the size check, whose hint may otherwise be the only word.
  if (info.display_rotation != reading.rotate && info.display_rotation != 0) {
    std::fprintf(stderr,
                 "note: %s: its metadata (a display matrix) has players show it turned by %d "
                 "degrees, which decoding does not do; --rotate %d turns the frames so (if that "
                 "puts the sensor's lights where its model has them)\n",
                 path.c_str(), info.display_rotation, info.display_rotation);
  }
  if (info.video_streams > 1) {
    std::fprintf(stderr,
                 "note: %s holds %d video streams; the frames are those of stream %d (%dx%d px, "
                 "%s), the one FFmpeg takes as the main one\n",
                 path.c_str(), info.video_streams, info.stream_index, info.width, info.height,
                 info.codec.c_str());
  }
  refuse_grey(info, path);
  check_frame_shape(path, reading.turned({info.width, info.height, 3}), reading);
  ImageU8 raw;
  double time_s = 0.0;
  while (reader->next(raw, time_s)) {
    if (keep.contains(int(scan.times_s.size())))
      scan.kept.push_back(sensor_image(raw, path, reading));
    scan.times_s.push_back(time_s);
  }
  if (scan.times_s.empty()) {
    throw InputError(path + ": holds no frame" +
                     (reader->damaged_frames() > 0
                          ? " that decodes (" + reader->first_damage() + ")"
                          : std::string()) +
                     " (--video)");
  }
  if (reader->damaged_frames() > 0) {
    std::fprintf(stderr,
                 "warning: %s: %d frame%s left out as damaged (the first: %s); the %zu that "
                 "decoded whole are the dataset's frames\n",
                 path.c_str(), reader->damaged_frames(), reader->damaged_frames() == 1 ? "" : "s",
                 reader->first_damage().c_str(), scan.times_s.size());
  }
  std::vector<double> steps;
  for (std::size_t i = 1; i < scan.times_s.size(); ++i) {
    steps.push_back(scan.times_s[i] - scan.times_s[i - 1]);
  }
  double step = 0.0;
  if (!steps.empty()) {
    std::nth_element(steps.begin(), steps.begin() + steps.size() / 2, steps.end());
    step = steps[steps.size() / 2];
  }
  // The container's rate where the steps agree with it (a Matroska file's millisecond stamps
  // step 16 and 17 ms at 60 frames per second), else the steps'.
  scan.fps = info.fps > 0 && (!(step > 0) || std::abs(info.fps * step - 1.0) < 0.05) ? info.fps
             : step > 0                                                              ? 1.0 / step
                                                                                     : 60.0;
  if (step > 0 && !info.coarse_times) warn_of_time_gaps(scan.times_s, 1.0 / scan.fps, path);
  // Cut short: fewer frames than the header counts, or frames that end before its duration.
  const long decoded = long(scan.times_s.size());
  const double end_s = scan.times_s.back() + (step > 0 ? step : 1.0 / scan.fps);
  std::string header;
  if (info.header_frames > decoded + 1) {
    header = "its header says " + std::to_string(info.header_frames) + " frames, " +
             std::to_string(decoded) + " decoded";
  } else if (info.header_frames == 0 && info.duration_s > end_s + 1.5 / scan.fps) {
    header = "its header says it lasts " + format_number(info.duration_s) + " s, its " +
             std::to_string(decoded) + " frames end at " + format_number(end_s) + " s";
  }
  if (!header.empty()) {
    std::fprintf(stderr,
                 "warning: %s: %s: is it cut short (a recording stopped before its file was "
                 "closed)? The dataset holds the %ld frames that decoded\n",
                 path.c_str(), header.c_str(), decoded);
  }
  // What the codec does to the frames: the network reads the gel's shading from colour edges
  // a pixel wide.
  const std::string note = codec_note(info);
  if (!note.empty()) {
    std::fprintf(stderr, "note: %s (%s, %s) %s\n", path.c_str(), info.codec.c_str(),
                 info.pixel_format.c_str(), note.c_str());
  }
  return scan;
}

// Frame numbers as ranges: "frame 5", "frames 5-6, 9"; "" for none.
std::string frame_list(const std::vector<int>& numbers) {
  std::string list;
  for (std::size_t k = 0; k < numbers.size();) {
    std::size_t end = k;
    while (end + 1 < numbers.size() && numbers[end + 1] == numbers[end] + 1) ++end;
    list += (list.empty() ? "" : ", ") + std::to_string(numbers[k]) +
            (end > k ? "-" + std::to_string(numbers[end]) : "");
    k = end + 1;
  }
  return list.empty() ? "" : (numbers.size() == 1 ? "frame " : "frames ") + list;
}

// The numbers (from `first`) of the images in [begin, end) that differ from `reference` as a
// contact would, as the tracker's no-change test tells one (changed regions of the smallest
// contact's size, `min_contact` pixels).
std::vector<int> frames_that_show_contact(std::vector<ImageU8>::const_iterator begin,
                                          std::vector<ImageU8>::const_iterator end, int first,
                                          const ImageU8& reference, int min_contact) {
  std::vector<int> touched;
  for (auto image = begin; image != end; ++image) {
    if (pixels_beyond_specks(changed_regions(*image, reference), min_contact) >= min_contact) {
      touched.push_back(first + int(image - begin));
    }
  }
  return touched;
}

// The frame rate of a poses file's time column (first to last row), so that dataset.json says
// what the rows do; `given` (--fps, 0 if not) must agree with it to 1 %. A single row or a
// constant time column has none: `given`, or 60.
double frame_rate(const std::vector<FramePose>& poses, const std::string& path, double given) {
  const double span = poses.back().time_s - poses.front().time_s;
  if (poses.size() < 2 || !(span > 0)) return given > 0 ? given : 60.0;
  const double rate = double(poses.size() - 1) / span;
  if (given > 0 && std::abs(given - rate) > 0.01 * rate) {
    throw InputError("--fps " + format_number(given) + " disagrees with " + path +
                     "'s time column (" + format_number(rate) + " frames per second)");
  }
  if (!(rate >= 1e-6 && rate <= 1e6)) {
    throw InputError(path + ": the time column gives " + format_number(rate) +
                     " frames per second, outside [1e-06, 1e+06]");
  }
  // A camera's stream runs at 10-150 frames per second, which a time column in milliseconds
  // reads as 0.01-0.15 (the tracker's motion priors do not read the rate, dataset.json states it).
  if (rate < 0.15 && given <= 0) {
    std::fprintf(stderr,
                 "warning: %s: the time column gives %s frames per second; if it is in "
                 "milliseconds, convert it to seconds\n",
                 path.c_str(), format_number(rate).c_str());
  }
  return given > 0 ? given : rate;
}

// The dataset's poses and frame rate.
struct RecordingPoses {
  std::vector<FramePose> poses;
  double fps = 60.0;
};

// --poses' rows, one per frame, at its time column's rate; or a still sensor's, the time column
// at --fps, the video's rate (`video_fps`, 0 for image files) or 60.
RecordingPoses recording_poses(const RecordingArgs& a, int frames, const std::string& source,
                               double video_fps) {
  const bool from_video = video_fps > 0;
  std::vector<FramePose> poses(frames);
  double fps = a.fps > 0 ? a.fps : from_video ? video_fps : 60.0;
  if (from_video && a.fps > 0 && a.poses.empty() &&
      std::abs(a.fps - video_fps) > 0.01 * video_fps) {
    std::fprintf(stderr,
                 "warning: --fps %s replaces %s's own rate, %s frames per second, in the time "
                 "column (sources.csv keeps the video's times)\n",
                 format_number(a.fps).c_str(), a.video.c_str(), format_number(video_fps).c_str());
  }
  if (!a.poses.empty()) {
    poses = read_poses_csv(a.poses);
    if (int(poses.size()) != frames) {
      throw InputError(a.poses + ": " + std::to_string(poses.size()) + " rows, but " + source +
                       " holds " + std::to_string(frames) + " frames");
    }
    fps = frame_rate(poses, a.poses, a.fps);
    if (frames > 1 && !(poses.back().time_s > poses.front().time_s) && a.fps <= 0) {
      std::fprintf(stderr,
                   "warning: %s: the time column does not advance (%s s in the first row, %s s "
                   "in the last): the dataset says 60 frames per second; --fps sets the rate\n",
                   a.poses.c_str(), format_number(poses.front().time_s).c_str(),
                   format_number(poses.back().time_s).c_str());
    } else if (from_video && a.fps <= 0 && std::abs(fps - video_fps) > 0.01 * video_fps) {
      std::fprintf(stderr,
                   "warning: %s: the time column gives %s frames per second, the video %s %s: "
                   "are the rows the video's frames?\n",
                   a.poses.c_str(), format_number(fps).c_str(), a.video.c_str(),
                   format_number(video_fps).c_str());
    }
    object_frame_is_sensor(poses, a.poses);  // refused now, not when the dataset is tracked
    // Row i is frame i (read_poses_csv holds them to it), below the header: line i + 2.
    const SensorJumps jumps = sensor_jumps(poses);
    if (jumps.count > 0) {
      std::fprintf(stderr,
                   "warning: %s: %s: a glitch? The tracker takes the sensor poses as given\n",
                   a.poses.c_str(), describe(jumps, 2).c_str());
    }
  } else {
    for (int i = 0; i < frames; ++i) {
      poses[i].frame = i;
      poses[i].time_s = i / fps;
      poses[i].object_known = false;
      poses[i].contact_known = false;
    }
  }
  return {poses, fps};
}

// The no-contact images --background names (image files, folders of them, videos), each input
// checked against the frames' size, with which of the images each one gave.
struct NoContactImages {
  struct Slice {
    std::string name;
    bool video;
    std::size_t begin, count;
  };
  std::vector<ImageU8> images;
  std::vector<Slice> slices;
};

NoContactImages background_images(const std::vector<fs::path>& references,
                                  const ImageShape& frame_shape, const FrameReading& reading) {
  NoContactImages given;
  for (const fs::path& file : references) {
    const std::string path = file.string();
    // Of another size than the frames (which fit): said so, rather than hints for the frames
    // that they do not need.
    const auto check_size = [&](const ImageShape& shape) {
      if (shape.width != frame_shape.width || shape.height != frame_shape.height) {
        throw InputError("--background " + path + ": " + std::to_string(shape.width) + "x" +
                         std::to_string(shape.height) + " px, the frames " +
                         std::to_string(frame_shape.width) + "x" +
                         std::to_string(frame_shape.height) +
                         " px: the no-contact image must come from the same camera at the same "
                         "settings as the frames");
      }
    };
    const bool is_video = has_video_extension(path);
    given.slices.push_back({path, is_video, given.images.size(), 0});
    if (is_video) {  // every frame
      const std::unique_ptr<VideoReader> reader = open_video(path);
      check_size({reader->info().width, reader->info().height, 3});
      refuse_grey(reader->info(), path);
      ImageU8 raw;
      double time_s = 0.0;
      while (reader->next(raw, time_s)) given.images.push_back(sensor_image(raw, path, reading));
      if (given.images.size() == given.slices.back().begin) {
        throw InputError(path + ": holds no frame (--background)");
      }
    } else {
      check_size(read_image_shape(path));
      given.images.push_back(sensor_image(path, reading));
    }
    given.slices.back().count = given.images.size() - given.slices.back().begin;
  }
  return given;
}

// Warnings about no-contact images that show a press: each input's images (and the recording's
// own, `own`, frames `keep` of it) against their median `background` (one image alone is the
// reference), and `keep` against the contact column of --poses.
std::vector<std::string> press_warnings(const NoContactImages& given,
                                        const std::vector<ImageU8>& own, const FrameRange& keep,
                                        const ImageU8& background, const SensorModel& sensor,
                                        const std::vector<FramePose>& poses,
                                        const RecordingArgs& a) {
  std::vector<std::string> warnings;
  const auto pressed = [&](const std::string& what, const std::string& how) {
    warnings.push_back(what + ": " + how +
                       ": if something touched the gel there, the reference holds it, and the "
                       "network reads every frame against it; give images from before the first "
                       "touch");
  };
  const auto differ = [](const std::vector<int>& touched) {
    return frame_list(touched) + (touched.size() == 1 ? " differs" : " differ") +
           " from the reference as a press would (a changed region of a contact's size)";
  };
  const std::string range_option = "--background-frames " + a.background_frames;
  // The smallest contact, ContactCloudOptions' mask.min_area_m2, on this sensor.
  const int min_contact =
      min_contact_pixels(make_gel_rays(sensor.camera, sensor.gel), ContactCloudOptions().mask);
  if (given.images.size() + own.size() > 1) {
    for (const NoContactImages::Slice& slice : given.slices) {
      const auto first = given.images.begin() + std::ptrdiff_t(slice.begin);
      const std::vector<int> touched = frames_that_show_contact(
          first, first + std::ptrdiff_t(slice.count), 0, background, min_contact);
      if (touched.empty()) continue;
      pressed("--background " + slice.name,
              slice.video ? differ(touched)
                          : "it differs from the reference as a press would (a changed region "
                            "of a contact's size)");
    }
    const std::vector<int> touched =
        frames_that_show_contact(own.begin(), own.end(), keep.first, background, min_contact);
    if (!touched.empty()) pressed(range_option, differ(touched));
  }
  std::vector<int> in_contact;
  for (int i = keep.first; i <= keep.last; ++i) {
    const FramePose& p = poses[std::size_t(i)];
    if (p.contact_known && p.contact) in_contact.push_back(i);
  }
  if (!in_contact.empty()) {
    pressed(range_option, a.poses + " marks " + frame_list(in_contact) + " as in contact");
  }
  return warnings;
}

}  // namespace

CLI::App* add_recording_command(CLI::App& app, RecordingArgs& a) {
  CLI::App* cmd = app.add_subcommand(
      "recording", "Make a dataset of a real sensor's frames, for track --normals MODEL");
  auto* images =
      cmd->add_option("--images", a.images, "Folder of the frames (png, jpg, ...), in name order");
  cmd->add_option("--video", a.video,
                  "A video file of the frames (mp4, avi, mkv, ...; decoded with FFmpeg), instead "
                  "of --images")
      ->excludes(images);
  cmd->add_option("--background", a.backgrounds,
                  "The sensor's image with nothing touching; or several such frames (image "
                  "files, videos, or folders of them): their per-pixel median is the reference, "
                  "with less camera noise");
  cmd->add_option("--background-frames", a.background_frames,
                  "FIRST-LAST: frames of --images or --video with nothing touching (a recording "
                  "that starts before the touch), numbered from 0; their median is the "
                  "reference (with --background's images, if given), and they stay frames");
  auto* poses = cmd->add_option("--poses", a.poses,
                                "poses.csv in the dataset format, one row per frame (the object "
                                "pose and contact cells may be empty)");
  auto* fixed = cmd->add_flag("--static-sensor", a.static_sensor,
                              "The sensor did not move: its frame is the world for every frame");
  poses->excludes(fixed);
  fixed->excludes(poses);
  auto* preset = cmd->add_option("--sensor", a.sensor, "Sensor preset (default digit)");
  cmd->add_option("--sensor-file", a.sensor_file, "Sensor config file (instead of --sensor)")
      ->excludes(preset);
  cmd->add_option("--fps", a.fps,
                  "Frame rate: the time column with --static-sensor (default 60, or the video's); "
                  "with --poses "
                  "it is the time column's and --fps, if given, must agree")
      ->check(range_check(1e-6, 1e6));  // the range dataset.json's fps is read in
  cmd->add_option("--downsample", a.downsample, "Average N x N pixel blocks (default 1)")
      ->check(range_check(1, 16));
  cmd->add_option("--rotate", a.rotate,
                  "Turn each image clockwise by 90, 180 or 270 degrees first (a camera driver's "
                  "landscape frames of a portrait sensor; default 0)")
      ->check(CLI::IsMember({0, 90, 180, 270}));
  cmd->add_option("--object", a.object, "Name of the object, for the outputs");
  cmd->add_option("--out,-o", a.out, "Output dataset folder")->required();
  cmd->add_flag("--quiet,-q", a.quiet, "No progress line");
  return cmd;
}

int run_recording(const RecordingArgs& a) {
  if (a.poses.empty() && !a.static_sensor) {
    throw UsageError(
        "--poses or --static-sensor: the tracker needs the sensor's pose in every frame");
  }
  if (a.images.empty() == a.video.empty()) {
    throw UsageError("--images or --video: the frames are a folder of images or a video file");
  }
  if (a.backgrounds.empty() && a.background_frames.empty()) {
    throw UsageError(
        "--background or --background-frames: the network reads each frame against the sensor's "
        "image with nothing touching");
  }
  const FrameRange keep = parse_frame_range(a.background_frames);
  const bool from_video = !a.video.empty();
  const std::string source = from_video ? a.video : a.images;
  if (!from_video) check_output_is_not_input(a.out, a.images, "--images");
  // Writing the dataset fills OUT/color and removes an earlier dataset's frames from the other
  // output folders (DatasetWriter::finish): --images must be none of them.
  for (const std::string& output : dataset_output_names()) {
    std::error_code ec;
    if (!from_video && fs::equivalent(a.images, fs::path(a.out) / output, ec)) {
      throw InputError(a.out + ": its " + output +
                       " folder is --images; the frames would be overwritten or removed");
    }
  }
  DatasetWriter::check_folder(a.out, DatasetMaker::kRecording);  // before a video's decoding
  const std::vector<fs::path> references = background_files(a.backgrounds);
  const SensorModel sensor =
      a.sensor_file.empty() ? preset_option(a.sensor) : load_sensor_file(a.sensor_file);
  const FrameReading reading{sensor.camera, a.downsample, a.rotate};
  // The frames: image files, or a video's frames (each decoded once here, so that a file cut
  // short or of another size fails before anything is written).
  std::vector<fs::path> files;
  VideoScan video;
  if (from_video) {
    video = scan_video(a.video, reading, keep);
  } else {
    files = frame_files(a.images, references);
  }
  const int frames = from_video ? int(video.times_s.size()) : int(files.size());
  if (!keep.empty() && keep.last >= frames) {
    throw InputError("--background-frames " + a.background_frames + ": " + source + " holds " +
                     std::to_string(frames) + " frames (0-" + std::to_string(frames - 1) + ")");
  }
  const RecordingPoses timing = recording_poses(a, frames, source, from_video ? video.fps : 0.0);
  const std::vector<FramePose>& poses = timing.poses;
  // Read everything that can fail before writing anything: every frame's header (a frame of
  // another size half-way through would otherwise leave an earlier dataset in --out replaced by
  // half a new one), the background and the first frame whole. When --out holds an earlier
  // dataset, every frame is decoded whole too: one cut short half-way would otherwise fail only
  // after the earlier dataset is gone (a new --out is removed again on failure).
  const bool out_existed = fs::exists(a.out);
  for (const fs::path& file : files) {
    if (out_existed) {
      sensor_image(file.string(), reading);
    } else {
      check_frame_shape(file.string(), reading.turned(read_image_shape(file.string())), reading);
    }
  }
  // The no-contact reference: the median of the --background images and --background-frames.
  const ImageShape frame_shape = from_video ? ImageShape{video.info.width, video.info.height, 3}
                                            : read_image_shape(files.front().string());
  const NoContactImages given = background_images(references, frame_shape, reading);
  // The recording's own frames without contact.
  std::vector<ImageU8> own = std::move(video.kept);
  for (int i = keep.first; !from_video && i <= keep.last; ++i) {
    own.push_back(sensor_image(files[std::size_t(i)].string(), reading));
  }
  std::vector<ImageU8> no_contact = given.images;
  no_contact.insert(no_contact.end(), own.begin(), own.end());
  const ImageU8 background = median_image(no_contact);
  const std::string reference_name =
      references.size() == 1 && no_contact.size() == 1 ? "--background " + references[0].string()
      : own.size() == 1 && no_contact.size() == 1
          ? "frame " + std::to_string(keep.first) + " (--background-frames)"
          : "the median of the " + std::to_string(no_contact.size()) + " no-contact images";
  std::vector<std::string> warnings = reference_warnings(background, reference_name);
  for (std::string& w : press_warnings(given, own, keep, background, sensor, poses, a)) {
    warnings.push_back(std::move(w));
  }
  if (!from_video && !out_existed) sensor_image(files.front().string(), reading);  // whole

  DatasetInfo info;
  info.sensor = sensor;
  info.frames = frames;
  info.fps = timing.fps;
  info.outputs = {"color"};
  info.object_name = a.object;
  // A frame that turns out unreadable half-way leaves no half-written dataset behind (unless the
  // folder was there before: then it is not ours to delete).
  try {
    const StopOnSignals stop;
    DatasetWriter writer(a.out, info, DatasetMaker::kRecording);
    writer.write_background(background);
    Progress progress("importing", frames, !a.quiet);
    std::unique_ptr<VideoReader> reader;
    if (from_video) reader = open_video(a.video);
    FrameImages images;
    for (int i = 0; i < frames; ++i) {
      if (reader) {
        ImageU8 raw;
        double time_s = 0.0;
        if (!reader->next(raw, time_s)) {
          throw InputError(a.video + ": ended after " + std::to_string(i) +
                           " frames, where it "
                           "had " +
                           std::to_string(frames) + " a moment before");
        }
        images.color = sensor_image(raw, a.video, reading);
      } else {
        images.color = sensor_image(files[std::size_t(i)].string(), reading);
      }
      writer.write_frame(poses[i], images);
      progress.update(i + 1);
    }
    writer.finish();
    // Which file each frame came from, for the messages that name frames by number (label-ball's
    // "frame 17 skipped", errors.csv's rows), absolute: the dataset is read from elsewhere. A
    // video's frames are named by the video and their time in it.
    const auto absolute = [](const fs::path& file) {
      std::error_code ec;
      const fs::path path = fs::absolute(file, ec).lexically_normal();
      return csv_field((ec ? file : path).string());
    };
    std::string sources = from_video ? "frame,file,time_s\n" : "frame,file\n";
    for (int i = 0; i < frames; ++i) {
      sources +=
          std::to_string(i) + "," +
          (from_video ? absolute(a.video) + "," + format_number(video.times_s[std::size_t(i)])
                      : absolute(files[std::size_t(i)])) +
          "\n";
    }
    write_text_atomically((fs::path(a.out) / "sources.csv").string(), sources);
  } catch (...) {
    rethrow_after_dataset_write(a.out, out_existed);
  }
  int object_poses = 0;
  for (const auto& p : poses) object_poses += p.object_known;
  const int w = sensor.camera.width, h = sensor.camera.height, n = a.downsample;
  const bool turned = a.rotate % 180 != 0;
  std::printf(
      "%d frames of %s (%dx%d px%s) -> %s (%dx%d px); the object's pose is given in %d of "
      "them\n",
      frames, source.c_str(), (turned ? h : w) * n, (turned ? w : h) * n,
      a.rotate ? (", turned " + std::to_string(a.rotate) + " degrees clockwise").c_str() : "",
      a.out.c_str(), w, h, object_poses);
  if (no_contact.size() > 1) {
    std::printf("the no-contact reference (background.png) is the median of %zu images%s\n",
                no_contact.size(),
                own.empty() ? ""
                : own.size() == no_contact.size()
                    ? (" (frames " + a.background_frames + ")").c_str()
                    : (" (frames " + a.background_frames + " among them)").c_str());
  }
  std::fflush(stdout);
  for (const std::string& w : warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
  return kExitOk;
}

}  // namespace pg
