#include "pg/core/image.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>

#include "image_formats.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/module.h"

namespace pg {

namespace {

// The module's table once it is loaded (image_codec.h).
std::atomic<const image_codec::Table*> loaded_table{nullptr};

// The codec table, the module loaded on the first call (thread-safe; a failure throws and the
// next call tries again).
const image_codec::Table& codec() {
  static const image_codec::Table* table = [] {
    using Entry = const image_codec::Table* (*)();
    const image_codec::Table* t = reinterpret_cast<Entry>(module_entry(
        PG_IMAGE_CODEC_MODULE, image_codec::kEntryPoint, "the image codecs (OpenImageIO)"))();
    t->set_threads(image_codec::exr_table().threads());
    loaded_table.store(t);
    return t;
  }();
  return *table;
}

// The codecs of a format: PNG and EXR in pg_core, the rest through the module. A file to read
// goes by its first bytes, one to write by its extension.
const image_codec::Table& codec_of(image_codec::Format format) {
  switch (format) {
    case image_codec::Format::kPng:
      return image_codec::png_table();
    case image_codec::Format::kExr:
      return image_codec::exr_table();
    default:
      return codec();
  }
}

const image_codec::Table& reader_of(const std::string& path) {
  return codec_of(image_codec::format_of_file(path));
}

const image_codec::Table& writer_of(const std::string& path) {
  return codec_of(image_codec::format_of_name(path));
}

void check_readable(const std::string& path) {
  require_regular_file(path, "an image file");
  if (!std::filesystem::is_regular_file(path)) throw InputError(path + ": image file not found");
  // One that cannot be opened (no permission) said so, not as a file of another format.
  errno = 0;
  if (!std::ifstream(path, std::ios::binary)) {
    throw InputError(path + ": cannot read" +
                     (errno ? std::string(": ") + std::strerror(errno) : std::string()));
  }
}

void throw_if_error(const std::string& error) {
  if (!error.empty()) throw InputError(error);
}

ImageF read_float(const std::string& path, image_codec::Stored stored) {
  check_readable(path);
  ImageF image;
  throw_if_error(reader_of(path).read_float(path, stored, image));
  return image;
}

void check_writable_shape(const std::string& path, int channels, bool empty) {
  if (empty || channels < 1 || channels > 4) {
    throw InputError(path + ": refusing to write an empty image or one with " +
                     std::to_string(channels) + " channels");
  }
}

void throw_if_write_error(const std::string& path, const std::string& error, int error_number) {
  if (!error.empty()) throw InputError(error + write_failure_cause(path, error_number));
}

void write_float(const std::string& path, const ImageF& image, bool as_u16) {
  check_writable_shape(path, image.channels, image.empty());
  int error_number = 0;
  const std::string error = writer_of(path).write_float(path, image, as_u16, error_number);
  throw_if_write_error(path, error, error_number);
}

}  // namespace

namespace image_codec {

Format format_of_file(const std::string& path) {
  char magic[8] = {};
  std::ifstream in(path, std::ios::binary);
  if (!in.read(magic, sizeof magic)) return Format::kOther;
  if (std::memcmp(magic, "\x89PNG\r\n\x1a\n", 8) == 0) return Format::kPng;
  if (std::memcmp(magic, "\x76\x2f\x31\x01", 4) == 0) return Format::kExr;
  return Format::kOther;
}

std::string write_file(const std::string& path, const std::vector<std::uint8_t>& bytes,
                       int& error_number) {
  errno = 0;
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file) {
    error_number = errno;
    return path + ": cannot write image: cannot open the file";
  }
  const bool written = std::fwrite(bytes.data(), 1, bytes.size(), file) == bytes.size();
  error_number = errno;
  if (std::fclose(file) != 0 || !written) {
    if (error_number == 0) error_number = errno;
    return path + ": cannot write image: the file is incomplete";
  }
  error_number = 0;
  return {};
}

Format format_of_name(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext == ".png") return Format::kPng;
  if (ext == ".exr") return Format::kExr;
  return Format::kOther;
}

}  // namespace image_codec

void set_image_codec_threads(int threads) {
  image_codec::exr_table().set_threads(threads);
  if (const image_codec::Table* t = loaded_table.load()) t->set_threads(threads);
}

int image_codec_threads() { return image_codec::exr_table().threads(); }

ImageF read_image_float(const std::string& path) {
  return read_float(path, image_codec::Stored::kAny);
}

ImageF read_float_file(const std::string& path) {
  return read_float(path, image_codec::Stored::kFloat);
}

ImageF read_u16_file(const std::string& path) {
  return read_float(path, image_codec::Stored::kUInt16);
}

ImageU8 read_image_u8(const std::string& path) {
  check_readable(path);
  ImageU8 image;
  throw_if_error(reader_of(path).read_u8(path, image));
  return image;
}

void check_image_output(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError(path + ": is a folder; give the image file's name");
  }
  if (std::filesystem::path(path).extension().string().size() < 2) {
    throw InputError(path +
                     ": no file extension to choose the image format by; give the "
                     "file's name with one (.png, .exr, .jpg)");
  }
  throw_if_error(writer_of(path).check_writer(path));
  const std::filesystem::path folder = std::filesystem::absolute(path, ec).parent_path();
  if (!std::filesystem::is_directory(folder, ec)) {
    throw InputError(path + ": cannot write: " + folder.string() + " is not a folder");
  }
}

void write_image(const std::string& path, const ImageF& image) { write_float(path, image, false); }

void write_image(const std::string& path, const ImageU8& image) {
  check_writable_shape(path, image.channels, image.empty());
  int error_number = 0;
  const std::string error = writer_of(path).write_u8(path, image, error_number);
  throw_if_write_error(path, error, error_number);
}

void write_image_u16(const std::string& path, const ImageF& image) {
  write_float(path, image, true);
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
  check_readable(path);
  ImageShape shape;
  throw_if_error(reader_of(path).read_shape(path, shape));
  return shape;
}

}  // namespace pg
