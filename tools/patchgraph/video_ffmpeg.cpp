#include "video.h"

extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/display.h>
#include <libavutil/imgutils.h>
#include <libavutil/pixdesc.h>
#include <libswscale/swscale.h>
}

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <vector>

#include "pg/core/error.h"

namespace pg {

namespace {

std::string av_error_text(int code) {
  std::array<char, AV_ERROR_MAX_STRING_SIZE> text{};
  av_strerror(code, text.data(), text.size());
  return text.data();
}

}  // namespace

// OpenImageIO reads movies through FFmpeg too, but its 2.4 reader has swscale write past the end
// of an unpadded frame buffer (valgrind: invalid writes on a 4:2:0 H.264 file), so the frames are
// decoded here, into buffers FFmpeg allocates with its own padding.
struct FfmpegState {
  std::string path;
  VideoInfo info;
  AVFormatContext* format = nullptr;
  AVCodecContext* decoder = nullptr;
  SwsContext* scaler = nullptr;
  AVPacket* packet = nullptr;
  AVFrame* frame = nullptr;
  AVFrame* rgb = nullptr;
  int stream = -1;
  double time_base = 0.0;
  bool flushed = false;  // the decoder was told the stream ended
  bool ended = false;
  int frames = 0;
  double first_time = 0.0;
  // Damaged frames, left out: the stream times of packets the demuxer found cut short, and
  // how many frames or packets did not decode whole.
  std::vector<std::int64_t> corrupt_packets;
  int damaged = 0;
  std::string damage;  // what the first damage was

  [[noreturn]] void fail(const std::string& what) const { throw InputError(path + ": " + what); }

  ~FfmpegState() {
    sws_freeContext(scaler);
    av_frame_free(&rgb);
    av_frame_free(&frame);
    av_packet_free(&packet);
    avcodec_free_context(&decoder);
    avformat_close_input(&format);
  }

  // The decoded frame as RGB into `out`.
  void convert(ImageU8& out) {
    const int w = frame->width, h = frame->height;
    if (w != info.width || h != info.height) {
      fail("frame " + std::to_string(frames) + " is " + std::to_string(w) + "x" +
           std::to_string(h) + " px, the video's first " + std::to_string(info.width) + "x" +
           std::to_string(info.height) + " px: a video's frames must be of one size");
    }
    const auto format_in = static_cast<AVPixelFormat>(frame->format);
    scaler = sws_getCachedContext(scaler, w, h, format_in, w, h, AV_PIX_FMT_RGB24,
                                  SWS_BICUBIC | SWS_ACCURATE_RND | SWS_FULL_CHR_H_INT, nullptr,
                                  nullptr, nullptr);
    if (!scaler) {
      fail("cannot convert its pixel format " +
           std::string(av_get_pix_fmt_name(format_in) ? av_get_pix_fmt_name(format_in) : "?") +
           " to RGB");
    }
    // The frame's own colour matrix and range (BT.709 in HD video, full range in MJPEG), where
    // it says; FFmpeg's default (BT.601, limited range) where it does not.
    const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(format_in);
    const bool yuv = desc && !(desc->flags & AV_PIX_FMT_FLAG_RGB) && desc->nb_components >= 3;
    if (yuv) {
      const int space =
          frame->colorspace == AVCOL_SPC_UNSPECIFIED ? SWS_CS_DEFAULT : int(frame->colorspace);
      const int full_range = frame->color_range == AVCOL_RANGE_JPEG ? 1 : 0;
      int* inv = nullptr;
      int* table = nullptr;
      int src_range = 0, dst_range = 0, brightness = 0, contrast = 0, saturation = 0;
      if (sws_getColorspaceDetails(scaler, &inv, &src_range, &table, &dst_range, &brightness,
                                   &contrast, &saturation) >= 0) {
        sws_setColorspaceDetails(scaler, sws_getCoefficients(space), full_range || src_range, table,
                                 1, brightness, contrast, saturation);
      }
    }
    if (!rgb->data[0]) {
      rgb->format = AV_PIX_FMT_RGB24;
      rgb->width = w;
      rgb->height = h;
      // Padded rows and end: swscale's vector code writes whole blocks.
      if (av_frame_get_buffer(rgb, 64) < 0)
        fail("out of memory for a " + std::to_string(w) + "px frame");
    }
    sws_scale(scaler, frame->data, frame->linesize, 0, h, rgb->data, rgb->linesize);
    out = ImageU8(w, h, 3);
    for (int y = 0; y < h; ++y) {
      std::memcpy(&out.data[std::size_t(y) * w * 3],
                  rgb->data[0] + std::size_t(y) * rgb->linesize[0], std::size_t(w) * 3);
    }
  }
};

// The FFmpeg decoder behind open_video; the module pg_video's one export makes it.
class FfmpegVideoReader final : public VideoReader {
 public:
  explicit FfmpegVideoReader(const std::string& path);
  const VideoInfo& info() const override { return s_->info; }
  bool next(ImageU8& rgb, double& time_s) override;
  int damaged_frames() const override { return s_->damaged; }
  const std::string& first_damage() const override { return s_->damage; }

 private:
  std::unique_ptr<FfmpegState> s_ = std::make_unique<FfmpegState>();
};

FfmpegVideoReader::FfmpegVideoReader(const std::string& path) {
  s_->path = path;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) s_->fail("no such file");
  if (std::filesystem::is_directory(path, ec)) {
    s_->fail("a folder, not a video file (a folder of frames is --images)");
  }
  // Read twice (counted, then written), so a pipe's stream would be gone the second time.
  if (!std::filesystem::is_regular_file(path, ec)) {
    s_->fail("not a regular file (a pipe or a device): give a video file");
  }
  av_log_set_level(AV_LOG_QUIET);  // errors are reported here, with the file's name
  int code = avformat_open_input(&s_->format, path.c_str(), nullptr, nullptr);
  if (code < 0) {
    const std::string ext = lower_extension(path);
    const bool mp4 = ext == ".mp4" || ext == ".mov" || ext == ".m4v";
    s_->fail("not a video FFmpeg can read (" + av_error_text(code) + ")" +
             (mp4 ? "; an MP4 or MOV whose recording never finished lacks the index written "
                    "at its end, and cannot be read (a recorder writing fragmented MP4, or "
                    "Matroska, leaves a readable file when cut short)"
                  : ""));
  }
  code = avformat_find_stream_info(s_->format, nullptr);
  if (code < 0) s_->fail("cannot read its streams (" + av_error_text(code) + ")");
  // FFmpeg reads a single image as a one-frame video; a folder of them is --images.
  const std::string demuxer = s_->format->iformat->name;
  if (demuxer == "image2" ||
      (demuxer.size() > 5 && demuxer.substr(demuxer.size() - 5) == "_pipe")) {
    s_->fail("an image, not a video (give the folder of the frames as --images)");
  }
  const AVCodec* codec = nullptr;
  s_->stream = av_find_best_stream(s_->format, AVMEDIA_TYPE_VIDEO, -1, -1, &codec, 0);
  if (s_->stream < 0) {
    s_->fail(s_->stream == AVERROR_DECODER_NOT_FOUND
                 ? "its video's codec has no decoder in this FFmpeg"
                 : "holds no video stream");
  }
  const AVStream* stream = s_->format->streams[s_->stream];
  s_->decoder = avcodec_alloc_context3(codec);
  if (!s_->decoder || avcodec_parameters_to_context(s_->decoder, stream->codecpar) < 0) {
    s_->fail("cannot set up its decoder");
  }
  s_->decoder->thread_count = 1;  // small frames; the tracker's tools keep the other core
  code = avcodec_open2(s_->decoder, codec, nullptr);
  if (code < 0)
    s_->fail("cannot open its " + std::string(codec->name) + " decoder (" + av_error_text(code) +
             ")");
  s_->packet = av_packet_alloc();
  s_->frame = av_frame_alloc();
  s_->rgb = av_frame_alloc();
  if (!s_->packet || !s_->frame || !s_->rgb) s_->fail("out of memory");
  s_->time_base = av_q2d(stream->time_base);

  VideoInfo& info = s_->info;
  info.width = stream->codecpar->width;
  info.height = stream->codecpar->height;
  if (info.width <= 0 || info.height <= 0) s_->fail("its video stream gives no frame size");
  info.codec = codec->name;
  const auto pixel_format = static_cast<AVPixelFormat>(stream->codecpar->format);
  const char* format_name = av_get_pix_fmt_name(pixel_format);
  info.pixel_format = format_name ? format_name : "unknown";
  if (const AVPixFmtDescriptor* desc = av_pix_fmt_desc_get(pixel_format)) {
    info.chroma_subsampled = !(desc->flags & AV_PIX_FMT_FLAG_RGB) && desc->nb_components >= 3 &&
                             (desc->log2_chroma_w > 0 || desc->log2_chroma_h > 0);
    info.grey = !(desc->flags & AV_PIX_FMT_FLAG_PAL) && desc->nb_components < 3;
    info.palette = (desc->flags & AV_PIX_FMT_FLAG_PAL) != 0;
  }
  // GIF decodes to RGBA from its palette of 256 colours, with delays in hundredths of a second
  // (a 60 Hz file's 1.67 cs as 1 and 2 cs, which readers take as 10): its times say little.
  if (info.codec == "gif") {
    info.palette = true;
    info.coarse_times = true;
  }
  info.video_streams = 0;
  for (unsigned k = 0; k < s_->format->nb_streams; ++k) {
    const AVStream* other = s_->format->streams[k];
    info.video_streams += other->codecpar->codec_type == AVMEDIA_TYPE_VIDEO &&
                          !(other->disposition & AV_DISPOSITION_ATTACHED_PIC);
  }
  info.stream_index = s_->stream;
  if (const AVCodecDescriptor* desc = avcodec_descriptor_get(stream->codecpar->codec_id)) {
    info.lossy_codec =
        (desc->props & AV_CODEC_PROP_LOSSY) && !(desc->props & AV_CODEC_PROP_LOSSLESS);
    info.lossless_codec =
        (desc->props & AV_CODEC_PROP_LOSSLESS) && !(desc->props & AV_CODEC_PROP_LOSSY);
  }
  const AVRational rate =
      stream->avg_frame_rate.num > 0 ? stream->avg_frame_rate : stream->r_frame_rate;
  info.fps = rate.num > 0 && rate.den > 0 ? av_q2d(rate) : 0.0;
  if (const auto* matrix = reinterpret_cast<const std::int32_t*>(
          av_stream_get_side_data(stream, AV_PKT_DATA_DISPLAYMATRIX, nullptr))) {
    // The matrix turns the frame counter-clockwise by this angle; a player turns it back.
    const double turn = -av_display_rotation_get(matrix);
    if (std::isfinite(turn))
      info.display_rotation = ((int(std::lround(turn / 90.0)) % 4 + 4) % 4) * 90;
  }
  info.header_frames = stream->nb_frames > 0 ? long(stream->nb_frames) : 0;
  // The stream's duration; the file's only when the stream is all it holds (another stream may
  // run longer).
  info.duration_s = stream->duration != AV_NOPTS_VALUE ? stream->duration * s_->time_base
                    : s_->format->duration != AV_NOPTS_VALUE && s_->format->nb_streams == 1
                        ? double(s_->format->duration) / AV_TIME_BASE
                        : 0.0;
}

bool FfmpegVideoReader::next(ImageU8& rgb, double& time_s) {
  FfmpegState& s = *s_;
  const auto damaged = [&](const std::string& what) {
    if (s.damaged++ == 0) s.damage = what;
  };
  while (!s.ended) {
    const int got = avcodec_receive_frame(s.decoder, s.frame);
    if (got == 0) {
      const std::int64_t pts = s.frame->pts;
      const bool cut = pts != AV_NOPTS_VALUE &&
                       std::find(s.corrupt_packets.begin(), s.corrupt_packets.end(), pts) !=
                           s.corrupt_packets.end();
      if (cut || (s.frame->flags & AV_FRAME_FLAG_CORRUPT) || s.frame->decode_error_flags) {
        damaged(cut ? "its data is cut short" : "the decoder found it damaged");
        av_frame_unref(s.frame);
        continue;
      }
      s.convert(rgb);
      const std::int64_t stamp = s.frame->best_effort_timestamp;
      const double t = stamp == AV_NOPTS_VALUE ? s.frames / (s.info.fps > 0 ? s.info.fps : 60.0)
                                               : stamp * s.time_base;
      if (s.frames == 0) s.first_time = t;
      time_s = t - s.first_time;
      ++s.frames;
      av_frame_unref(s.frame);
      return true;
    }
    if (got == AVERROR_EOF || (got != AVERROR(EAGAIN) && s.flushed)) {
      if (got != AVERROR_EOF) damaged("it does not decode (" + av_error_text(got) + ")");
      s.ended = true;
      break;
    }
    // A frame that does not decode is left out and counted; then, as after EAGAIN, the decoder
    // is fed: the next packet of the video stream, or the end.
    if (got != AVERROR(EAGAIN)) damaged("it does not decode (" + av_error_text(got) + ")");
    if (s.flushed) {  // nothing more will come
      s.ended = true;
      break;
    }
    const int read = av_read_frame(s.format, s.packet);
    if (read == AVERROR_EOF || read < 0) {
      // A read error past the start is a file cut short: what decoded so far is kept.
      if (read != AVERROR_EOF) damaged("it cannot be read on (" + av_error_text(read) + ")");
      avcodec_send_packet(s.decoder, nullptr);
      s.flushed = true;
      continue;
    }
    if (s.packet->stream_index == s.stream) {
      if (s.packet->flags & AV_PKT_FLAG_CORRUPT) s.corrupt_packets.push_back(s.packet->pts);
      const int sent = avcodec_send_packet(s.decoder, s.packet);
      if (sent < 0 && sent != AVERROR(EAGAIN)) {  // a packet that does not decode: left out
        damaged("it does not decode (" + av_error_text(sent) + ")");
      }
    }
    av_packet_unref(s.packet);
  }
  return false;
}

}  // namespace pg

// The module pg_video's one exported function (video.cpp loads it). Throws InputError, which the
// program catches as its own (the same class, compared by name).
extern "C" __attribute__((visibility("default"))) pg::VideoReader* pg_open_video(
    const std::string& path) {
  return new pg::FfmpegVideoReader(path);
}
