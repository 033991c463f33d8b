// PNG files through libpng (image_formats.h says why not through OpenImageIO). libpng reports an
// error by a longjmp back to the last setjmp: each call that can fail runs in a stage function
// whose frame holds no C++ object with a destructor, and the caller owns the buffers and handles.
#include <png.h>
#include <zlib.h>

#include <csetjmp>
#include <cstdio>
#include <memory>
#include <vector>

#include "image_formats.h"

namespace pg::image_codec {

namespace {

// libpng's error callback writes the message here, then jumps back.
struct PngError {
  char message[200] = "";
};

void on_error(png_structp png, png_const_charp message) {
  auto* error = static_cast<PngError*>(png_get_error_ptr(png));
  std::snprintf(error->message, sizeof error->message, "%s", message);
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}  // an ancillary chunk's complaint: read on

// Reads through stdio's buffer: a header read (read_image_shape, for every frame of a recording)
// reads no more of the file than the chunks before the pixels.
void read_bytes(png_structp png, png_bytep out, std::size_t n) {
  if (std::fread(out, 1, n, static_cast<std::FILE*>(png_get_io_ptr(png))) != n) {
    png_error(png, "the file is cut short");
  }
}

struct ByteSink {
  std::vector<std::uint8_t>* bytes;
};

void write_bytes(png_structp png, png_bytep data, std::size_t n) {
  auto* sink = static_cast<ByteSink*>(png_get_io_ptr(png));
  bool ok = true;
  try {
    sink->bytes->insert(sink->bytes->end(), data, data + n);
  } catch (...) {
    ok = false;
  }
  if (!ok) png_error(png, "out of memory");
}

void flush_bytes(png_structp) {}

// What a read makes of the file: 8-bit or 16-bit values, 1-4 channels (palettes and bit depths
// below 8 expanded, a transparency chunk an alpha channel, as OpenImageIO read them).
struct PngLayout {
  png_uint_32 width = 0, height = 0;
  int channels = 0, bit_depth = 0;
};

// Stage 1: the header, and the transformations to the layout above.
bool read_header(png_structp png, png_infop info, std::FILE* file, PngLayout* layout) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_read_fn(png, file, read_bytes);
  png_set_sig_bytes(png, 8);  // checked by the caller
  png_read_info(png, info);
  const int color_type = png_get_color_type(png, info);
  const int depth = png_get_bit_depth(png, info);
  if (color_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
  if (color_type == PNG_COLOR_TYPE_GRAY && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
  if (png_get_valid(png, info, PNG_INFO_tRNS)) png_set_tRNS_to_alpha(png);
  if (depth == 16) png_set_swap(png);  // to the machine's byte order (little-endian)
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  layout->width = png_get_image_width(png, info);
  layout->height = png_get_image_height(png, info);
  layout->channels = png_get_channels(png, info);
  layout->bit_depth = png_get_bit_depth(png, info);
  return true;
}

// Stage 2: the pixels.
bool read_rows(png_structp png, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  return true;
}

// A file being read: the file, libpng's handles (destroyed together) and its error message.
class PngReader {
 public:
  ~PngReader() { png_destroy_read_struct(&png_, info_ ? &info_ : nullptr, nullptr); }

  // Opens the file and reads its header; the layout is then known.
  std::string open(const std::string& path) {
    file_.reset(std::fopen(path.c_str(), "rb"));
    if (!file_) return path + ": cannot read image: cannot open the file";
    png_byte signature[8] = {};
    if (std::fread(signature, 1, sizeof signature, file_.get()) != sizeof signature ||
        png_sig_cmp(signature, 0, sizeof signature) != 0) {
      return path + ": cannot read image: not a PNG file";
    }
    png_ = png_create_read_struct(PNG_LIBPNG_VER_STRING, &error_, on_error, on_warning);
    if (png_) info_ = png_create_info_struct(png_);
    if (!info_) return path + ": cannot read image: out of memory";
    if (!read_header(png_, info_, file_.get(), &layout_)) {
      return path + ": cannot read image: " + error_.message;
    }
    return {};
  }

  const PngLayout& layout() const { return layout_; }

  // The pixels as stored (8 or 16 bits a value, machine order).
  std::string pixels(const std::string& path, std::vector<std::uint8_t>& pixels) {
    const long long values = (long long)layout_.width * layout_.height * layout_.channels;
    if (values < 1 || values > kMaxImageValues) {
      return path + ": cannot read image: " + std::to_string(layout_.width) + "x" +
             std::to_string(layout_.height) + " pixels is beyond what an image may hold here";
    }
    const std::size_t row_bytes =
        std::size_t(layout_.width) * layout_.channels * std::size_t(layout_.bit_depth / 8);
    pixels.resize(row_bytes * layout_.height);
    std::vector<png_bytep> rows(layout_.height);
    for (png_uint_32 y = 0; y < layout_.height; ++y) rows[y] = pixels.data() + y * row_bytes;
    if (!read_rows(png_, rows.data())) return path + ": cannot decode image: " + error_.message;
    return {};
  }

 private:
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file_{nullptr, std::fclose};
  PngError error_;
  png_structp png_ = nullptr;
  png_infop info_ = nullptr;
  PngLayout layout_;
};

template <typename T, typename Convert8, typename Convert16>
std::string read(const std::string& path, Stored stored, Image<T>& image, Convert8 convert8,
                 Convert16 convert16) {
  PngReader reader;
  if (std::string error = reader.open(path); !error.empty()) return error;
  const PngLayout& layout = reader.layout();
  const char* stored_type = layout.bit_depth == 16 ? "uint16" : "uint8";
  if (stored == Stored::kFloat) {
    return path + ": is a png file of " + stored_type + " pixels, not floating-point data";
  }
  if (stored == Stored::kUInt16 && layout.bit_depth != 16) {
    return path + ": is a png file of " + stored_type + " pixels, not 16-bit ones";
  }
  std::vector<std::uint8_t> pixels;
  if (std::string error = reader.pixels(path, pixels); !error.empty()) return error;
  image = Image<T>(int(layout.width), int(layout.height), layout.channels);
  if (layout.bit_depth == 16) {
    const auto* v = reinterpret_cast<const std::uint16_t*>(pixels.data());
    for (std::size_t i = 0; i < image.data.size(); ++i) image.data[i] = convert16(v[i]);
  } else {
    for (std::size_t i = 0; i < image.data.size(); ++i) image.data[i] = convert8(pixels[i]);
  }
  return {};
}

// Stage 3: a whole file, written into `sink`.
bool encode(png_structp png, png_infop info, ByteSink* sink, png_uint_32 width, png_uint_32 height,
            int bit_depth, int color_type, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_write_fn(png, sink, write_bytes, flush_bytes);
  png_set_IHDR(png, info, width, height, bit_depth, color_type, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  // Chosen for speed (docs/benchmarks.md, "Image files"): zlib's level 6 and libpng's adaptive
  // filters (OpenImageIO's setting) spent 3.6 ms on a 120x160 colour frame with the camera's
  // noise and 11 ms on 16-bit normals. With the Paeth filter, 8-bit images run-length encoded
  // (1.5 ms, 3 % larger) and 16-bit ones at level 1 (2.2 ms, 15 % larger; run lengths miss the
  // repeated high bytes, 49 % larger).
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_PAETH);
  if (bit_depth == 8) {
    png_set_compression_strategy(png, Z_RLE);
  } else {
    png_set_compression_level(png, 1);
  }
  png_write_info(png, info);
  if (bit_depth == 16) png_set_swap(png);
  png_write_image(png, rows);
  png_write_end(png, info);
  return true;
}

struct WriteHandles {
  png_structp png = nullptr;
  png_infop info = nullptr;
  ~WriteHandles() { png_destroy_write_struct(&png, info ? &info : nullptr); }
};

// `pixels`: 8-bit or 16-bit values (machine order), interleaved.
std::string write(const std::string& path, int width, int height, int channels, int bit_depth,
                  const void* pixels, int& error_number) {
  error_number = 0;
  static constexpr int kColorTypes[] = {PNG_COLOR_TYPE_GRAY, PNG_COLOR_TYPE_GRAY_ALPHA,
                                        PNG_COLOR_TYPE_RGB, PNG_COLOR_TYPE_RGB_ALPHA};
  PngError error;
  WriteHandles h;
  h.png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &error, on_error, on_warning);
  if (h.png) h.info = png_create_info_struct(h.png);
  if (!h.info) return path + ": cannot write image: out of memory";
  const std::size_t row_bytes = std::size_t(width) * channels * bit_depth / 8;
  std::vector<png_bytep> rows(height);
  for (int y = 0; y < height; ++y) {
    rows[y] = const_cast<png_bytep>(static_cast<const std::uint8_t*>(pixels) + y * row_bytes);
  }
  std::vector<std::uint8_t> bytes;
  ByteSink sink{&bytes};
  if (!encode(h.png, h.info, &sink, png_uint_32(width), png_uint_32(height), bit_depth,
              kColorTypes[channels - 1], rows.data())) {
    return path + ": cannot write image: " + error.message;
  }
  return write_file(path, bytes, error_number);
}

std::string write_float(const std::string& path, const ImageF& image, bool as_u16,
                        int& error_number) {
  if (as_u16) {
    std::vector<std::uint16_t> v(image.data.size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = float_to_unorm<std::uint16_t>(image.data[i]);
    return write(path, image.width, image.height, image.channels, 16, v.data(), error_number);
  }
  std::vector<std::uint8_t> v(image.data.size());
  for (std::size_t i = 0; i < v.size(); ++i) v[i] = float_to_unorm<std::uint8_t>(image.data[i]);
  return write(path, image.width, image.height, image.channels, 8, v.data(), error_number);
}

const Table kPngTable = {
    [](const std::string& path, Stored stored, ImageF& image) {
      return read(path, stored, image, unorm_to_float<std::uint8_t>, unorm_to_float<std::uint16_t>);
    },
    [](const std::string& path, ImageU8& image) {
      return read(
          path, Stored::kAny, image, [](std::uint8_t v) { return v; }, u16_to_u8);
    },
    [](const std::string& path, ImageShape& shape) {
      PngReader reader;
      if (std::string error = reader.open(path); !error.empty()) return error;
      const PngLayout& layout = reader.layout();
      shape = {int(layout.width), int(layout.height), layout.channels};
      return std::string();
    },
    write_float,
    [](const std::string& path, const ImageU8& image, int& error_number) {
      return write(path, image.width, image.height, image.channels, 8, image.data.data(),
                   error_number);
    },
    [](const std::string&) { return std::string(); },
    [](int) {},
    []() { return 1; },
};

}  // namespace

const Table& png_table() { return kPngTable; }

}  // namespace pg::image_codec
