// PNG and EXR files read and written inside pg_core (core/src/image_formats.h), checked against
// the OpenImageIO module that read and wrote them before: each reads the other's files to the
// same values, bit for bit. One difference, on purpose: a PNG's alpha channel. OpenImageIO
// multiplied the colour by it on reading (and divided on writing); the values now read as the
// file stores them, as a camera frame saved with an alpha channel should.
#include <gtest/gtest.h>
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "../common/test_support.h"
#include "image_codec.h"
#include "pg/core/error.h"
#include "pg/core/image.h"
#include "pg/core/module.h"

namespace pg {
namespace {

namespace fs = std::filesystem;
using image_codec::Stored;
using testing_support::expect_input_error;
using testing_support::TempDir;

const image_codec::Table& open_image_io() {
  using Entry = const image_codec::Table* (*)();
  return *reinterpret_cast<Entry>(
      module_entry(PG_IMAGE_CODEC_MODULE, image_codec::kEntryPoint, "the image codecs"))();
}

ImageF module_read_float(const std::string& path, Stored stored = Stored::kAny) {
  ImageF image;
  const std::string error = open_image_io().read_float(path, stored, image);
  EXPECT_EQ(error, "");
  return image;
}

ImageU8 module_read_u8(const std::string& path) {
  ImageU8 image;
  EXPECT_EQ(open_image_io().read_u8(path, image), "");
  return image;
}

// Bit-for-bit equality of float images (NaN included), with the first difference printed.
void expect_same(const ImageF& a, const ImageF& b, const std::string& what) {
  ASSERT_TRUE(a.same_shape(b.width, b.height, b.channels))
      << what << ": " << a.width << "x" << a.height << "x" << a.channels << " against " << b.width
      << "x" << b.height << "x" << b.channels;
  for (std::size_t i = 0; i < a.data.size(); ++i) {
    if (std::memcmp(&a.data[i], &b.data[i], sizeof(float)) != 0) {
      ADD_FAILURE() << what << ": value " << i << " is " << a.data[i] << " against " << b.data[i];
      return;
    }
  }
}

// With `opaque`, an alpha channel (the 2nd of 2, the 4th of 4) is 255 everywhere: the values
// OpenImageIO left as they were.
ImageU8 random_u8(int w, int h, int c, unsigned seed, bool opaque) {
  std::mt19937 rng(seed);
  ImageU8 image(w, h, c);
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const bool alpha = (c == 2 || c == 4) && int(i % c) == c - 1;
    image.data[i] = opaque && alpha ? 255 : std::uint8_t(rng() & 0xff);
  }
  return image;
}

// Values beyond [0, 1], exact halves of a step and NaN: the quantisation's edge cases (in the
// first channel; an alpha channel as above).
ImageF random_float(int w, int h, int c, unsigned seed, bool opaque) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.1f, 1.1f);
  ImageF image(w, h, c);
  for (std::size_t i = 0; i < image.data.size(); ++i) {
    const bool alpha = (c == 2 || c == 4) && int(i % c) == c - 1;
    image.data[i] = opaque && alpha ? 1.0f : u(rng);
  }
  const float edges[] = {std::numeric_limits<float>::quiet_NaN(), 0.5f / 255.0f, 254.5f / 255.0f,
                         1e30f};
  for (int k = 0; k < 4; ++k) image.data[std::size_t(k * c)] = edges[k];
  return image;
}

TEST(ImageFormats, PngFilesReadAndWriteAsOpenImageIODid) {
  TempDir tmp;
  for (int channels = 1; channels <= 4; ++channels) {
    SCOPED_TRACE("channels " + std::to_string(channels));
    const ImageU8 u8 = random_u8(37, 23, channels, 10 + channels, true);
    // Ours written, OpenImageIO reads it; OpenImageIO's written, ours reads it.
    write_image(tmp.str("ours.png"), u8);
    EXPECT_EQ(module_read_u8(tmp.str("ours.png")).data, u8.data);
    int error_number = 0;
    ASSERT_EQ(open_image_io().write_u8(tmp.str("theirs.png"), u8, error_number), "");
    EXPECT_EQ(read_image_u8(tmp.str("theirs.png")).data, u8.data);
    expect_same(read_image_float(tmp.str("theirs.png")), module_read_float(tmp.str("theirs.png")),
                "8-bit read as float");
    const ImageShape shape = read_image_shape(tmp.str("theirs.png"));
    EXPECT_EQ(shape.width, 37);
    EXPECT_EQ(shape.height, 23);
    EXPECT_EQ(shape.channels, channels);

    // Floats quantised to 8 and to 16 bits the same way.
    const ImageF f = random_float(37, 23, channels, 20 + channels, true);
    write_image(tmp.str("ours_f.png"), f);
    ASSERT_EQ(open_image_io().write_float(tmp.str("theirs_f.png"), f, false, error_number), "");
    EXPECT_EQ(read_image_u8(tmp.str("ours_f.png")).data,
              module_read_u8(tmp.str("theirs_f.png")).data);
    write_image_u16(tmp.str("ours_16.png"), f);
    ASSERT_EQ(open_image_io().write_float(tmp.str("theirs_16.png"), f, true, error_number), "");
    const ImageF ours16 = read_u16_file(tmp.str("ours_16.png"));
    expect_same(ours16, module_read_float(tmp.str("theirs_16.png"), Stored::kUInt16),
                "16-bit written by each");
    expect_same(ours16, module_read_float(tmp.str("ours_16.png"), Stored::kUInt16),
                "16-bit read by each");
    EXPECT_EQ(read_image_u8(tmp.str("theirs_16.png")).data,
              module_read_u8(tmp.str("theirs_16.png")).data)
        << "16 bits to 8";

    // Any alpha: our files read back as written.
    const ImageU8 any = random_u8(37, 23, channels, 40 + channels, false);
    write_image(tmp.str("any.png"), any);
    EXPECT_EQ(read_image_u8(tmp.str("any.png")).data, any.data);
    const ImageF any_f = random_float(37, 23, channels, 50 + channels, false);
    write_image_u16(tmp.str("any_16.png"), any_f);
    const ImageF back = read_u16_file(tmp.str("any_16.png"));
    for (std::size_t i = 4 * std::size_t(channels); i < any_f.data.size(); ++i) {
      ASSERT_NEAR(back.data[i], std::clamp(any_f.data[i], 0.0f, 1.0f), 0.5 / 65535 + 1e-7) << i;
    }
  }
}

TEST(ImageFormats, ExrFilesReadAndWriteAsOpenImageIODid) {
  TempDir tmp;
  for (int channels = 1; channels <= 4; ++channels) {
    SCOPED_TRACE("channels " + std::to_string(channels));
    ImageF f = random_float(41, 19, channels, 30 + channels, false);
    f.data[5] = -std::numeric_limits<float>::infinity();
    f.data[6] = 1e-40f;  // subnormal
    write_image(tmp.str("ours.exr"), f);
    expect_same(module_read_float(tmp.str("ours.exr"), Stored::kFloat), f, "ours, read by them");
    expect_same(read_float_file(tmp.str("ours.exr")), f, "ours, read by us");
    int error_number = 0;
    ASSERT_EQ(open_image_io().write_float(tmp.str("theirs.exr"), f, false, error_number), "");
    expect_same(read_float_file(tmp.str("theirs.exr")), f, "theirs, read by us");
    EXPECT_EQ(read_image_u8(tmp.str("theirs.exr")).data, module_read_u8(tmp.str("theirs.exr")).data)
        << "float to 8 bits";
    const ImageShape shape = read_image_shape(tmp.str("theirs.exr"));
    EXPECT_EQ(shape.width, 41);
    EXPECT_EQ(shape.height, 19);
    EXPECT_EQ(shape.channels, channels);
  }
}

// A PNG made by hand: libpng's writer and OpenImageIO's never make palettes, bit depths below 8
// or transparency chunks, which a user's background image may have.
void chunk(std::string& png, const char* type, const std::string& data) {
  const auto be32 = [&](std::uint32_t v) {
    for (int s = 24; s >= 0; s -= 8) png.push_back(char((v >> s) & 0xff));
  };
  be32(std::uint32_t(data.size()));
  const std::string body = std::string(type, 4) + data;
  png += body;
  be32(std::uint32_t(crc32(0, reinterpret_cast<const Bytef*>(body.data()), uInt(body.size()))));
}

std::string handmade_png(int width, int height, int bit_depth, int color_type,
                         const std::string& palette, const std::string& transparency,
                         const std::vector<std::string>& rows) {
  std::string png = "\x89PNG\r\n\x1a\n";
  std::string header;
  for (int v : {width, height}) {
    for (int s = 24; s >= 0; s -= 8) header.push_back(char((v >> s) & 0xff));
  }
  header += {char(bit_depth), char(color_type), 0, 0, 0};
  chunk(png, "IHDR", header);
  if (!palette.empty()) chunk(png, "PLTE", palette);
  if (!transparency.empty()) chunk(png, "tRNS", transparency);
  std::string raw;
  for (const std::string& row : rows) raw += '\0' + row;  // filter type 0 on each row
  std::vector<Bytef> packed(compressBound(uLong(raw.size())));
  uLongf size = uLongf(packed.size());
  compress(packed.data(), &size, reinterpret_cast<const Bytef*>(raw.data()), uLong(raw.size()));
  chunk(png, "IDAT", std::string(reinterpret_cast<char*>(packed.data()), size));
  chunk(png, "IEND", "");
  return png;
}

TEST(ImageFormats, PalettesLowBitDepthsAndTransparencyReadAsOpenImageIOReadThem) {
  TempDir tmp;
  struct Case {
    const char* name;
    std::string png;
    int channels;
    std::vector<std::uint8_t> expected;  // for the alpha cases, where OpenImageIO premultiplied
  };
  const std::string palette("\xff\x00\x00\x00\x80\x00\x10\x20\x30\xfe\xfd\xfc", 12);
  const std::vector<Case> cases = {
      {"palette.png", handmade_png(4, 2, 8, 3, palette, "", {{0, 1, 2, 3}, {3, 2, 1, 0}}), 3, {}},
      {"palette_alpha.png",
       handmade_png(4, 1, 8, 3, palette, std::string("\x00\x80", 2), {{0, 1, 2, 3}}),
       4,
       {0xff, 0, 0, 0, 0, 0x80, 0, 0x80, 0x10, 0x20, 0x30, 0xff, 0xfe, 0xfd, 0xfc, 0xff}},
      {"palette_4bit.png",
       handmade_png(4, 2, 4, 3, palette, "", {{char(0x01), char(0x23)}, {char(0x32), 0x10}}),
       3,
       {}},
      {"gray_1bit.png",
       handmade_png(9, 2, 1, 0, "", "", {std::string("\xa5\x80", 2), std::string("\x5a\x00", 2)}),
       1,
       {}},
      {"gray_4bit.png", handmade_png(3, 1, 4, 0, "", "", {std::string("\x0f\x70", 2)}), 1, {}},
      {"gray_key.png",
       handmade_png(3, 1, 8, 0, "", std::string("\x00\x40", 2), {std::string("\x40\x41\x00", 3)}),
       2,
       {0x40, 0, 0x41, 0xff, 0, 0xff}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    std::ofstream(tmp.str(c.name), std::ios::binary) << c.png;
    const ImageU8 theirs = module_read_u8(tmp.str(c.name));
    const ImageU8 ours = read_image_u8(tmp.str(c.name));
    EXPECT_EQ(ours.channels, c.channels);
    EXPECT_TRUE(ours.same_shape(theirs.width, theirs.height, theirs.channels))
        << ours.channels << " channels against " << theirs.channels;
    if (c.expected.empty()) {
      EXPECT_EQ(ours.data, theirs.data);
      expect_same(read_image_float(tmp.str(c.name)), module_read_float(tmp.str(c.name)),
                  "as float");
    } else {
      EXPECT_EQ(ours.data, c.expected);
    }
  }
}

// A program whose images are all PNG and EXR never loads OpenImageIO (about 0.45 s). ctest runs
// each test in a process of its own; run with the others in one process, an earlier test may
// have loaded it.
TEST(ImageFormats, PngAndExrFilesNeedNoOpenImageIO) {
  const auto mapped = [] {
    std::ifstream maps("/proc/self/maps");
    const std::string text((std::istreambuf_iterator<char>(maps)),
                           std::istreambuf_iterator<char>());
    return text.find("libOpenImageIO") != std::string::npos;
  };
  if (mapped()) GTEST_SKIP() << "OpenImageIO was loaded by an earlier test in this process";
  TempDir tmp;
  write_image(tmp.str("a.png"), ImageU8(8, 4, 3, 7));
  write_image_u16(tmp.str("b.png"), ImageF(8, 4, 3, 0.25f));
  write_image(tmp.str("c.exr"), ImageF(8, 4, 1, 0.5f));
  EXPECT_EQ(read_image_u8(tmp.str("a.png")).data[5], 7);
  EXPECT_EQ(read_u16_file(tmp.str("b.png")).data[5], float(16384) / 65535.0f);
  EXPECT_EQ(read_float_file(tmp.str("c.exr")).data[5], 0.5f);
  EXPECT_EQ(read_image_shape(tmp.str("c.exr")).channels, 1);
  check_image_output(tmp.str("d.png"));
  EXPECT_FALSE(mapped());
  // Another format still goes through the module.
  write_image(tmp.str("e.jpg"), ImageU8(8, 4, 3, 7));
  EXPECT_TRUE(mapped());
}

TEST(ImageFormats, DamagedFilesAreRefusedNamingThem) {
  TempDir tmp;
  ImageF f(64, 48, 3);
  for (std::size_t i = 0; i < f.data.size(); ++i) f.data[i] = float(i % 97) / 97.0f;
  write_image(tmp.str("whole.exr"), f);
  const auto cut = [&](const std::string& name, std::uintmax_t size) {
    fs::copy_file(tmp.str("whole.exr"), tmp.str(name));
    fs::resize_file(tmp.str(name), size);
  };
  const std::uintmax_t size = fs::file_size(tmp.str("whole.exr"));
  cut("half.exr", size / 2);
  cut("header.exr", 40);
  for (const char* name : {"half.exr", "header.exr"}) {
    SCOPED_TRACE(name);
    try {
      read_float_file(tmp.str(name));
      ADD_FAILURE() << "read";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(std::string(name) + ": cannot"), std::string::npos)
          << e.what();
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
    }
  }
  // A PNG by another name, and files of the wrong kind for the dataset's readers.
  write_image(tmp.str("png.png"), ImageU8(4, 4, 3, 1));
  fs::copy_file(tmp.str("png.png"), tmp.str("png.exr"));
  expect_input_error([&] { read_float_file(tmp.str("png.exr")); },
                     {"png.exr: is a png file of uint8 pixels, not floating-point data"});
  EXPECT_EQ(read_image_u8(tmp.str("png.exr")).data[0], 1);
  expect_input_error([&] { read_u16_file(tmp.str("whole.exr")); },
                     {"whole.exr: is an OpenEXR file of float pixels, not 16-bit ones"});
  // A header that claims more pixels than may be read (and has none).
  std::ofstream(tmp.str("huge.png"), std::ios::binary)
      << handmade_png(60000, 60000, 8, 2, "", "", {});
  expect_input_error([&] { read_image_u8(tmp.str("huge.png")); },
                     {"huge.png: cannot read image: 60000x60000 pixels"});
  // Damaged pixel data after a good header.
  std::string png = handmade_png(4, 2, 8, 0, "", "", {"abcd", "efgh"});
  png[png.size() - 20] ^= 0x55;  // in the IDAT chunk
  std::ofstream(tmp.str("bad_crc.png"), std::ios::binary) << png;
  expect_input_error([&] { read_image_u8(tmp.str("bad_crc.png")); },
                     {"bad_crc.png: cannot decode image"});
}

// Bytes damaged at random (a PNG's chunk checksums made right again, so that the damage reaches
// the decoder): each file reads or is refused with an InputError naming it, never a crash (the
// sanitizer build checks the memory), a hang or another exception.
std::string with_checksums(std::string png) {
  for (std::size_t at = 8; at + 12 <= png.size();) {
    const std::uint32_t size = std::uint32_t(std::uint8_t(png[at])) << 24 |
                               std::uint32_t(std::uint8_t(png[at + 1])) << 16 |
                               std::uint32_t(std::uint8_t(png[at + 2])) << 8 |
                               std::uint32_t(std::uint8_t(png[at + 3]));
    if (size > png.size() - at - 12) break;
    const auto crc = std::uint32_t(
        crc32(0, reinterpret_cast<const Bytef*>(png.data() + at + 4), uInt(size + 4)));
    for (int k = 0; k < 4; ++k) png[at + 8 + size + k] = char(crc >> (24 - 8 * k));
    at += 12 + size;
  }
  return png;
}

TEST(ImageFormats, DamagedBytesAreReadOrRefused) {
  TempDir tmp;
  ImageF f(24, 16, 3);
  for (std::size_t i = 0; i < f.data.size(); ++i) f.data[i] = float(i % 29) / 29.0f;
  write_image(tmp.str("a.png"), f);
  write_image_u16(tmp.str("b.png"), f);
  write_image(tmp.str("c.exr"), f);
  std::mt19937 rng(5);
  int read = 0, refused = 0;
  for (const char* name : {"a.png", "b.png", "c.exr"}) {
    std::ifstream in(tmp.str(name), std::ios::binary);
    const std::string whole((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const bool png = std::string(name).find(".png") != std::string::npos;
    for (int trial = 0; trial < 300; ++trial) {
      std::string bytes = whole;
      const int changes = 1 + int(rng() % 4);
      for (int k = 0; k < changes; ++k) {
        const std::size_t at = 8 + rng() % (bytes.size() - 8);  // the magic bytes kept
        bytes[at] = rng() % 3 == 0 ? char(0xff) : char(rng() & 0xff);
      }
      if (rng() % 5 == 0) bytes.resize(8 + rng() % (bytes.size() - 8));
      if (png) bytes = with_checksums(bytes);
      const std::string path = tmp.str(std::string("damaged_") + name);
      std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
      try {
        const ImageF image = read_image_float(path);
        EXPECT_GT(image.width * image.height * image.channels, 0) << name << " trial " << trial;
        ++read;
      } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        ++refused;
      }
    }
  }
  std::printf("damaged files: %d read, %d refused\n", read, refused);
  EXPECT_GT(refused, 100);
}

// A write that cannot reach its file names it and the cause.
TEST(ImageFormats, AWriteThatFailsNamesTheFileAndCause) {
  for (const char* name : {"/proc/version.png", "/proc/version.exr"}) {
    SCOPED_TRACE(name);
    expect_input_error([&] { write_image(name, ImageU8(4, 4, 1)); },
                       {std::string(name) + ": cannot write image"});
  }
  if (fs::exists("/dev/full")) {
    // libpng's and OpenEXR's buffers reach the file only at the end: the full disk must show.
    TempDir tmp;
    fs::create_symlink("/dev/full", tmp.str("full.png"));
    expect_input_error([&] { write_image(tmp.str("full.png"), ImageU8(64, 64, 3, 9)); },
                       {"full.png: cannot write image"});
  }
}

}  // namespace
}  // namespace pg
