#pragma once
// Images as the sensor streams them: width x height, 1-3 interleaved channels, row-major.
// File I/O: PNG (libpng) and EXR (OpenEXR) in pg_core itself, any other format (JPEG, TIFF, ...)
// through OpenImageIO, loaded with the first such file; a file is read by its content and
// written by its extension.
#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace pg {

template <typename T>
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  std::vector<T> data;  // index (y * width + x) * channels + c

  Image() = default;
  Image(int w, int h, int c, T fill = T())
      : width(w), height(h), channels(c), data(std::size_t(w) * h * c, fill) {}

  bool empty() const { return data.empty(); }
  std::size_t index(int x, int y, int c = 0) const {
    return (std::size_t(y) * width + x) * channels + c;
  }
  T& at(int x, int y, int c = 0) { return data[index(x, y, c)]; }
  const T& at(int x, int y, int c = 0) const { return data[index(x, y, c)]; }
  bool same_shape(int w, int h, int c) const { return width == w && height == h && channels == c; }
  // The values width x height x channels call for (0 for a negative side): what `data` holds,
  // unless a buffer was wrapped by hand at another size.
  std::size_t shape_values() const {
    return std::size_t(std::max(width, 0)) * std::size_t(std::max(height, 0)) *
           std::size_t(std::max(channels, 0));
  }
};

using ImageF = Image<float>;
using ImageU8 = Image<std::uint8_t>;

// The first value of `image` (in storage order) that is not a finite number, as {x, y, channel};
// none when every value is finite. For errors that name the pixel.
std::optional<std::array<int, 3>> first_non_finite(const ImageF& image);

// Reads any format OpenImageIO knows. 8-bit and 16-bit files read as float are scaled to [0, 1].
// A PNG's alpha channel reads as stored (OpenImageIO, which read PNG files until 2026-11-30,
// multiplied the colour channels by it).
// Throws InputError naming the path when the file is missing or unreadable.
ImageF read_image_float(const std::string& path);
ImageU8 read_image_u8(const std::string& path);
// Like read_image_float, but refuses a file that does not store floating-point pixels (a
// dataset's normal and depth images are float EXR; a PNG renamed .exr is not one).
ImageF read_float_file(const std::string& path);
// Like read_image_float, scaled to [0, 1], but refuses a file that does not store 16-bit pixels
// (a dataset's normal_png: an 8-bit file would read as normals a hundredth of a radian coarse).
ImageF read_u16_file(const std::string& path);

// Threads that may decode or encode one EXR image (OpenEXR's pool, process-wide; 0: one per core,
// the default; 1: the calling thread alone, no pool). track_dataset
// sets 1 while it runs: it reads the next frame on a thread of its own beside the tracker's update,
// which a pool the size of the machine would crowd (measured on 2 cores: the update 1.0 -> 1.3 ms
// a frame with the pool, 1.0 without). So does a render, whose frames keep every core busy. On
// one thread, a 120x160 frame of normals (RLE) read in 1.4 ms through OpenImageIO, against 2.1
// with the pool of 2 cores and 3.0 with a pool of one worker, which hands the caller's work over.
void set_image_codec_threads(int threads);
int image_codec_threads();

// set_image_codec_threads(threads) while it lives, the setting before it afterwards.
class ScopedImageCodecThreads {
 public:
  explicit ScopedImageCodecThreads(int threads) : before_(image_codec_threads()) {
    set_image_codec_threads(threads);
  }
  ~ScopedImageCodecThreads() { set_image_codec_threads(before_); }
  ScopedImageCodecThreads(const ScopedImageCodecThreads&) = delete;
  ScopedImageCodecThreads& operator=(const ScopedImageCodecThreads&) = delete;

 private:
  int before_;
};

// Writes by extension. Float images go to EXR as 32-bit float; to PNG/JPEG they are clamped to
// [0, 1] and quantised to 8 bits. Throws InputError naming the path on failure.
void write_image(const std::string& path, const ImageF& image);
void write_image(const std::string& path, const ImageU8& image);
// Writes values in [0, 1] (clamped) as 16-bit integers 0-65535 (PNG, TIFF): images that tools
// without float formats read. read_image_float reads them back scaled to [0, 1].
void write_image_u16(const std::string& path, const ImageF& image);
// Throws InputError naming the path unless write_image could write there: PNG, EXR or another
// format that OpenImageIO writes, in a folder that exists. For long jobs, to fail before the work.
void check_image_output(const std::string& path);

// Reads only the header: width, height and channel count. Throws like read_image_*.
struct ImageShape {
  int width = 0, height = 0, channels = 0;
};
ImageShape read_image_shape(const std::string& path);

}  // namespace pg
