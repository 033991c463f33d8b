#include "video.h"

#include "pg/core/module.h"

namespace pg {

std::unique_ptr<VideoReader> open_video(const std::string& path) {
  using Open = VideoReader* (*)(const std::string&);
  static const Open open = reinterpret_cast<Open>(
      module_entry(PG_VIDEO_MODULE, "pg_open_video", "the video decoders (FFmpeg)"));
  return std::unique_ptr<VideoReader>(open(path));
}

}  // namespace pg
