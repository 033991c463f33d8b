#include "video.h"

#include <algorithm>
#include <array>

#include "pg/core/module.h"

namespace pg {

std::unique_ptr<VideoReader> open_video(const std::string& path) {
  using Open = VideoReader* (*)(const std::string&);
  static const Open open = reinterpret_cast<Open>(
      module_entry(PG_VIDEO_MODULE, "pg_open_video", "the video decoders (FFmpeg)"));
  return std::unique_ptr<VideoReader>(open(path));
}

bool has_video_extension(const std::string& path) {
  const std::string ext = lower_extension(path);
  static const std::array<const char*, 14> kVideo = {".mp4",  ".m4v", ".mov",  ".avi", ".mkv",
                                                     ".webm", ".mpg", ".mpeg", ".ts",  ".wmv",
                                                     ".flv",  ".ogv", ".h264", ".264"};
  return std::any_of(kVideo.begin(), kVideo.end(), [&](const char* e) { return ext == e; });
}

}  // namespace pg
