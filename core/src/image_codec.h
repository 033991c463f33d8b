#pragma once
// The image files' codecs (OpenImageIO), built as a module of their own (pg_image_codec, from
// image_codec.cpp) that image.cpp loads when a program first reads or writes an image that is
// neither PNG nor EXR (those pg_core handles itself, image_formats.h).
// OpenImageIO brings in some 260 libraries (OpenVDB, GDAL, OpenCV, ...) whose loading and
// relocation took about 0.5 s at the start of every program that linked it, whether it touched an
// image or not: `tacsim --help`, a command-line error, each unit test's process.
//
// The module and the programs are built together by one compiler, so the table passes C++ types.
// Its functions throw nothing: each returns an empty string on success, else the error's message,
// which names the file; image.cpp throws it as an InputError.
#include <string>

#include "pg/core/image.h"

namespace pg::image_codec {

// The first line of a library's error message (a message is one line; libpng's reader under
// OpenImageIO stacks the same failure in several).
inline std::string first_line(const std::string& error) {
  return error.substr(0, error.find('\n'));
}

// What a float read requires the file to store.
enum class Stored { kAny, kFloat, kUInt16 };

struct Table {
  // Pixels converted to float (8-bit and 16-bit files scaled to [0, 1]) or to 8 bits.
  std::string (*read_float)(const std::string& path, Stored stored, ImageF& image);
  std::string (*read_u8)(const std::string& path, ImageU8& image);
  std::string (*read_shape)(const std::string& path, ImageShape& shape);
  // as_u16: values in [0, 1] as 16-bit integers. On failure error_number is errno's value then.
  std::string (*write_float)(const std::string& path, const ImageF& image, bool as_u16,
                             int& error_number);
  std::string (*write_u8)(const std::string& path, const ImageU8& image, int& error_number);
  // Empty when there is a writer for the path's extension.
  std::string (*check_writer)(const std::string& path);
  void (*set_threads)(int threads);
  int (*threads)();
};

// The name of the module's one exported function, `const Table* pg_image_codec_table()`.
inline constexpr const char* kEntryPoint = "pg_image_codec_table";

}  // namespace pg::image_codec
