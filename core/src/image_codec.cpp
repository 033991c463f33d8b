// The pg_image_codec module: every OpenImageIO call of the project (image_codec.h says why
// they live apart). Loaded by image.cpp, which checks the paths and throws the errors.
#include "image_codec.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cerrno>
#include <memory>

#include "pg/core/file_io.h"

namespace pg::image_codec {

namespace {

// Opens a file for reading; on failure `error` holds why.
std::unique_ptr<OIIO::ImageInput> open_input(const std::string& path, std::string& error) {
  // OpenImageIO 2.4 reads movies through FFmpeg (its reader's format: "FFmpeg movie"), and that
  // reader writes past its frame buffer on 4:2:0 video (the process aborts, or worse); a
  // container it has no reader for (Matroska) it calls an unknown format. Only `patchgraph
  // recording --video` decodes video, with FFmpeg's own libraries.
  const std::string video = path + ": is a video, not an image file (PNG, JPEG, TIFF, EXR); " +
                            "`patchgraph recording --video` makes frames of a sensor's video";
  if (has_video_extension(path)) {
    error = video;
    return nullptr;
  }
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    error = path + ": cannot read image: " + first_line(OIIO::geterror());
    return nullptr;
  }
  if (std::string(in->format_name()).find("FFmpeg") != std::string::npos) {
    error = video;  // a container whose extension the list lacks
    return nullptr;
  }
  return in;
}

template <typename T>
std::string read(const std::string& path, OIIO::TypeDesc type, Stored stored, Image<T>& image) {
  std::string error;
  auto in = open_input(path, error);
  if (!in) return error;
  const OIIO::ImageSpec& spec = in->spec();
  if (stored == Stored::kFloat && !spec.format.is_floating_point()) {
    return path + ": is a " + in->format_name() + " file of " + spec.format.c_str() +
           " pixels, not floating-point data";
  }
  if (stored == Stored::kUInt16 && spec.format != OIIO::TypeDesc::UINT16) {
    return path + ": is a " + in->format_name() + " file of " + spec.format.c_str() +
           " pixels, not 16-bit ones";
  }
  if (spec.nchannels < 1 || spec.width < 1 || spec.height < 1) {
    return path + ": image has no pixels";
  }
  image = Image<T>(spec.width, spec.height, spec.nchannels);
  // A file cut short may decode "successfully" with the rest of the image made up (JPEG: grey);
  // the reader then holds an error (premature end of data).
  if (!in->read_image(0, 0, 0, spec.nchannels, type, image.data.data()) || in->has_error()) {
    const std::string cause = first_line(in->geterror());
    image = Image<T>();
    return path + ": cannot decode image: " +
           (cause.empty() ? std::string("the file is damaged or cut short") : cause);
  }
  in->close();
  return {};
}

bool holds_float(const std::string& path) {
  const std::string ext = lower_extension(path);
  return ext == ".exr" || ext == ".tif" || ext == ".tiff" || ext == ".hdr" || ext == ".pfm";
}

template <typename T>
std::string write(const std::string& path, const Image<T>& image, OIIO::TypeDesc mem_type,
                  OIIO::TypeDesc file_type, int& error_number) {
  error_number = 0;
  auto out = OIIO::ImageOutput::create(path);
  if (!out) return path + ": no image writer for this extension: " + first_line(OIIO::geterror());
  // Float data goes to float files where the format supports it, 8 bits otherwise.
  if (file_type == OIIO::TypeDesc::UNKNOWN) {
    file_type = mem_type;
    if (mem_type == OIIO::TypeDesc::FLOAT && !holds_float(path)) file_type = OIIO::TypeDesc::UINT8;
  }
  OIIO::ImageSpec spec(image.width, image.height, image.channels, file_type);
  // EXR files run-length compressed, not zip compressed (OpenImageIO's default): a frame of gel
  // normals is noise in its low bits, which zip shrank by 4 % for 8 ms of a 120x160 frame's
  // writing and 1.4 ms of its reading; RLE writes it in 2 ms and reads it as fast as raw, and
  // still shrinks a depth image's untouched gel (zeros) 15-fold (docs/benchmarks.md, "Image
  // files").
  if (std::string(out->format_name()) == "openexr") {
    spec.attribute("compression", "rle");
  }
  // OpenImageIO stamps EXR files with the time of writing unless told a date; an empty one keeps
  // two writes of the same pixels byte-identical, so datasets can be compared by checksum.
  spec.attribute("DateTime", "");
  errno = 0;
  if (!out->open(path, spec) || !out->write_image(mem_type, image.data.data()) || !out->close()) {
    error_number = errno;
    return path + ": cannot write image: " + first_line(out->geterror());
  }
  return {};
}

const Table kTable = {
    [](const std::string& path, Stored stored, ImageF& image) {
      return read(path, OIIO::TypeDesc::FLOAT, stored, image);
    },
    [](const std::string& path, ImageU8& image) {
      return read(path, OIIO::TypeDesc::UINT8, Stored::kAny, image);
    },
    [](const std::string& path, ImageShape& shape) {
      std::string error;
      auto in = open_input(path, error);
      if (!in) return error;
      const auto& spec = in->spec();
      shape = {spec.width, spec.height, spec.nchannels};
      return std::string();
    },
    [](const std::string& path, const ImageF& image, bool as_u16, int& error_number) {
      return write(path, image, OIIO::TypeDesc::FLOAT,
                   as_u16 ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UNKNOWN, error_number);
    },
    [](const std::string& path, const ImageU8& image, int& error_number) {
      return write(path, image, OIIO::TypeDesc::UINT8, OIIO::TypeDesc::UNKNOWN, error_number);
    },
    [](const std::string& path) {
      return OIIO::ImageOutput::create(path)
                 ? std::string()
                 : path + ": no image writer for this extension: " + first_line(OIIO::geterror());
    },
    // One thread is the calling one: OpenImageIO's -1 (no pool). Its 1 is a pool of one worker,
    // which the caller hands each block of scanlines and waits for: twice as slow.
    [](int threads) { OIIO::attribute("exr_threads", threads == 1 ? -1 : std::max(0, threads)); },
    []() {
      int threads = 0;
      OIIO::getattribute("exr_threads", threads);
      return threads < 0 ? 1 : threads;
    },
};

}  // namespace

}  // namespace pg::image_codec

extern "C" __attribute__((visibility("default"))) const pg::image_codec::Table*
pg_image_codec_table() {
  return &pg::image_codec::kTable;
}
