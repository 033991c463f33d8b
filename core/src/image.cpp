#include "pg/core/image.h"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>

#include "pg/core/error.h"
#include "pg/core/file_io.h"

namespace pg {

namespace {

// An OpenImageIO error's first line: a reader may stack the same failure in several lines
// (libpng's adds "PNG read error: " with the same words, then "PNG library error"), and an error
// message is one line.
std::string first_line(const std::string& error) { return error.substr(0, error.find('\n')); }

std::unique_ptr<OIIO::ImageInput> open_input(const std::string& path) {
  require_regular_file(path, "an image file");
  if (!std::filesystem::is_regular_file(path)) throw InputError(path + ": image file not found");
  auto in = OIIO::ImageInput::open(path);
  if (!in) throw InputError(path + ": cannot read image: " + first_line(OIIO::geterror()));
  // OpenImageIO 2.4 reads movies through FFmpeg (its reader's format: "FFmpeg movie"), and that
  // reader writes past its frame buffer on 4:2:0 video (the process aborts, or worse). Only
  // `patchgraph recording --video` decodes video, with FFmpeg's own libraries.
  if (std::string(in->format_name()).find("FFmpeg") != std::string::npos) {
    throw InputError(path + ": is a video, not an image file (PNG, JPEG, TIFF, EXR); " +
                     "`patchgraph recording --video` makes frames of a sensor's video");
  }
  return in;
}

template <typename T>
Image<T> read_image(const std::string& path, OIIO::TypeDesc type,
                    OIIO::TypeDesc stored = OIIO::TypeDesc::UNKNOWN) {
  auto in = open_input(path);
  const OIIO::ImageSpec& spec = in->spec();
  if (stored == OIIO::TypeDesc::FLOAT && !spec.format.is_floating_point()) {
    throw InputError(path + ": is a " + in->format_name() + " file of " + spec.format.c_str() +
                     " pixels, not floating-point data");
  }
  if (stored == OIIO::TypeDesc::UINT16 && spec.format != OIIO::TypeDesc::UINT16) {
    throw InputError(path + ": is a " + in->format_name() + " file of " + spec.format.c_str() +
                     " pixels, not 16-bit ones");
  }
  if (spec.nchannels < 1 || spec.width < 1 || spec.height < 1) {
    throw InputError(path + ": image has no pixels");
  }
  Image<T> image(spec.width, spec.height, spec.nchannels);
  // A file cut short may decode "successfully" with the rest of the image made up (JPEG: grey);
  // the reader then holds an error (premature end of data).
  if (!in->read_image(0, 0, 0, spec.nchannels, type, image.data.data()) || in->has_error()) {
    const std::string cause = first_line(in->geterror());
    throw InputError(path + ": cannot decode image: " +
                     (cause.empty() ? std::string("the file is damaged or cut short") : cause));
  }
  in->close();
  return image;
}

bool holds_float(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return ext == ".exr" || ext == ".tif" || ext == ".tiff" || ext == ".hdr" || ext == ".pfm";
}

template <typename T>
void write(const std::string& path, const Image<T>& image, OIIO::TypeDesc mem_type,
           OIIO::TypeDesc file_type = OIIO::TypeDesc::UNKNOWN) {
  if (image.empty() || image.channels < 1 || image.channels > 4) {
    throw InputError(path + ": refusing to write an empty image or one with " +
                     std::to_string(image.channels) + " channels");
  }
  auto out = OIIO::ImageOutput::create(path);
  if (!out) {
    throw InputError(path +
                     ": no image writer for this extension: " + first_line(OIIO::geterror()));
  }
  // Float data goes to float files where the format supports it, 8 bits otherwise.
  if (file_type == OIIO::TypeDesc::UNKNOWN) {
    file_type = mem_type;
    if (mem_type == OIIO::TypeDesc::FLOAT && !holds_float(path)) file_type = OIIO::TypeDesc::UINT8;
  }
  OIIO::ImageSpec spec(image.width, image.height, image.channels, file_type);
  // OpenImageIO stamps EXR files with the time of writing unless told a date; an empty one keeps
  // two writes of the same pixels byte-identical, so datasets can be compared by checksum.
  spec.attribute("DateTime", "");
  errno = 0;
  if (!out->open(path, spec) || !out->write_image(mem_type, image.data.data()) || !out->close()) {
    const int error_number = errno;
    throw InputError(path + ": cannot write image: " + first_line(out->geterror()) +
                     write_failure_cause(path, error_number));
  }
}

}  // namespace

void set_image_codec_threads(int threads) { OIIO::attribute("exr_threads", std::max(0, threads)); }

int image_codec_threads() {
  int threads = 0;
  OIIO::getattribute("exr_threads", threads);
  return threads;
}

ImageF read_image_float(const std::string& path) {
  return read_image<float>(path, OIIO::TypeDesc::FLOAT);
}

ImageF read_float_file(const std::string& path) {
  return read_image<float>(path, OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::FLOAT);
}

ImageF read_u16_file(const std::string& path) {
  return read_image<float>(path, OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::UINT16);
}

ImageU8 read_image_u8(const std::string& path) {
  return read_image<std::uint8_t>(path, OIIO::TypeDesc::UINT8);
}

void check_image_output(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError(path + ": is a folder; give the image file's name");
  }
  if (!OIIO::ImageOutput::create(path)) {
    throw InputError(path +
                     ": no image writer for this extension: " + first_line(OIIO::geterror()));
  }
  const std::filesystem::path folder = std::filesystem::absolute(path, ec).parent_path();
  if (!std::filesystem::is_directory(folder, ec)) {
    throw InputError(path + ": cannot write: " + folder.string() + " is not a folder");
  }
}

void write_image(const std::string& path, const ImageF& image) {
  write(path, image, OIIO::TypeDesc::FLOAT);
}

void write_image(const std::string& path, const ImageU8& image) {
  write(path, image, OIIO::TypeDesc::UINT8);
}

void write_image_u16(const std::string& path, const ImageF& image) {
  write(path, image, OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::UINT16);
}

std::optional<std::array<int, 3>> first_non_finite(const ImageF& image) {
  const auto bad =
      std::find_if(image.data.begin(), image.data.end(), [](float v) { return !std::isfinite(v); });
  if (bad == image.data.end()) return std::nullopt;
  const std::size_t k = std::size_t(bad - image.data.begin());
  const std::size_t pixel = k / std::size_t(image.channels);
  return std::array<int, 3>{int(pixel % std::size_t(image.width)),
                            int(pixel / std::size_t(image.width)),
                            int(k % std::size_t(image.channels))};
}

ImageShape read_image_shape(const std::string& path) {
  auto in = open_input(path);
  const auto& spec = in->spec();
  return {spec.width, spec.height, spec.nchannels};
}

}  // namespace pg
