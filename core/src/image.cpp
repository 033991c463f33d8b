#include "pg/core/image.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <filesystem>
#include <string>

#include "image_codec.h"
#include "pg/core/error.h"
#include "pg/core/file_io.h"
#include "pg/core/module.h"

namespace pg {

namespace {

// Threads asked for before the codec module was loaded (-1: none), and the module's table once
// it is (image_codec.h).
std::atomic<int> requested_threads{-1};
std::atomic<const image_codec::Table*> loaded_table{nullptr};

// The codec table, the module loaded on the first call (thread-safe; a failure throws and the
// next call tries again).
const image_codec::Table& codec() {
  static const image_codec::Table* table = [] {
    using Entry = const image_codec::Table* (*)();
    const image_codec::Table* t = reinterpret_cast<Entry>(module_entry(
        PG_IMAGE_CODEC_MODULE, image_codec::kEntryPoint, "the image codecs (OpenImageIO)"))();
    loaded_table.store(t);
    const int threads = requested_threads.load();
    if (threads >= 0) t->set_threads(threads);
    return t;
  }();
  return *table;
}

void check_readable(const std::string& path) {
  require_regular_file(path, "an image file");
  if (!std::filesystem::is_regular_file(path)) throw InputError(path + ": image file not found");
}

void throw_if_error(const std::string& error) {
  if (!error.empty()) throw InputError(error);
}

ImageF read_float(const std::string& path, image_codec::Stored stored) {
  check_readable(path);
  ImageF image;
  throw_if_error(codec().read_float(path, stored, image));
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
  const std::string error = codec().write_float(path, image, as_u16, error_number);
  throw_if_write_error(path, error, error_number);
}

}  // namespace

void set_image_codec_threads(int threads) {
  requested_threads.store(std::max(0, threads));
  if (const image_codec::Table* t = loaded_table.load()) t->set_threads(threads);
}

int image_codec_threads() {
  if (const image_codec::Table* t = loaded_table.load()) return t->threads();
  return std::max(0, requested_threads.load());  // OpenImageIO's default: 0, one per core
}

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
  throw_if_error(codec().read_u8(path, image));
  return image;
}

void check_image_output(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) {
    throw InputError(path + ": is a folder; give the image file's name");
  }
  throw_if_error(codec().check_writer(path));
  const std::filesystem::path folder = std::filesystem::absolute(path, ec).parent_path();
  if (!std::filesystem::is_directory(folder, ec)) {
    throw InputError(path + ": cannot write: " + folder.string() + " is not a folder");
  }
}

void write_image(const std::string& path, const ImageF& image) { write_float(path, image, false); }

void write_image(const std::string& path, const ImageU8& image) {
  check_writable_shape(path, image.channels, image.empty());
  int error_number = 0;
  const std::string error = codec().write_u8(path, image, error_number);
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
  throw_if_error(codec().read_shape(path, shape));
  return shape;
}

}  // namespace pg
