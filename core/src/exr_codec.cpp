// EXR files through OpenEXR (image_formats.h says why not through OpenImageIO), written as
// OpenImageIO wrote them: 32-bit float channels named Y (one channel) or R, G, B, A,
// run-length compressed (image_codec.cpp says why), no time of writing in the header.
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfThreading.h>

#include <algorithm>
#include <atomic>
#include <cstring>
#include <mutex>
#include <thread>
#include <vector>

#include "image_formats.h"

namespace pg::image_codec {

namespace {

// Codec threads as image.h defines them (0: one per core, 1: the calling thread, n: a pool of n),
// applied to OpenEXR's process-wide pool when an image is next read or written, so that a
// program that sets them and reads no EXR file starts no pool.
std::atomic<int> requested_threads{0};

// The threads to hand a file: 0 is OpenEXR's calling thread. A pool of one worker is never made:
// the caller would hand it the work and wait (image.h).
int exr_threads() {
  static std::mutex mutex;
  static int applied = -1;
  const int requested = requested_threads.load();
  int pool = requested == 0 ? int(std::thread::hardware_concurrency()) : requested;
  if (pool <= 1) pool = 0;
  const std::lock_guard<std::mutex> lock(mutex);
  if (pool != applied) {
    Imf::setGlobalThreadCount(pool);
    applied = pool;
  }
  return pool;
}

// A file written into memory, then to disk in one write (write_file).
class MemoryStream : public Imf::OStream {
 public:
  MemoryStream(const std::string& path, std::vector<std::uint8_t>& bytes)
      : Imf::OStream(path.c_str()), bytes_(bytes) {}
  void write(const char c[], int n) override {
    if (at_ + std::size_t(n) > bytes_.size()) bytes_.resize(at_ + std::size_t(n));
    std::memcpy(bytes_.data() + at_, c, std::size_t(n));
    at_ += std::size_t(n);
  }
  std::uint64_t tellp() override { return at_; }
  void seekp(std::uint64_t at) override { at_ = std::size_t(at); }

 private:
  std::vector<std::uint8_t>& bytes_;
  std::size_t at_ = 0;
};

const char* type_name(Imf::PixelType type) {
  switch (type) {
    case Imf::HALF:
      return "half";
    case Imf::FLOAT:
      return "float";
    default:
      return "uint";
  }
}

// OpenImageIO's order: R (or Y), G, B, A first, then the others as the file lists them
// (alphabetically).
int channel_rank(const std::string& name) {
  if (name == "R" || name == "Y") return 0;
  if (name == "G") return 1;
  if (name == "B") return 2;
  if (name == "A") return 3;
  return 4;
}

std::string read_float(const std::string& path, Stored stored, ImageF& image) {
  try {
    Imf::InputFile in(path.c_str(), exr_threads());
    const Imf::Header& header = in.header();
    const Imath::Box2i window = header.dataWindow();
    const long long width = (long long)window.max.x - window.min.x + 1;
    const long long height = (long long)window.max.y - window.min.y + 1;
    std::vector<std::pair<std::string, Imf::PixelType>> channels;
    for (auto c = header.channels().begin(); c != header.channels().end(); ++c) {
      if (c.channel().xSampling != 1 || c.channel().ySampling != 1) {
        return path + ": cannot read image: channel " + c.name() + " is subsampled";
      }
      channels.emplace_back(c.name(), c.channel().type);
    }
    std::stable_sort(channels.begin(), channels.end(), [](const auto& a, const auto& b) {
      return channel_rank(a.first) < channel_rank(b.first);
    });
    const auto integer = std::find_if(channels.begin(), channels.end(),
                                      [](const auto& c) { return c.second == Imf::UINT; });
    if (stored == Stored::kFloat && integer != channels.end()) {
      return path + ": is an OpenEXR file of uint pixels, not floating-point data";
    }
    if (stored == Stored::kUInt16) {
      return path + ": is an OpenEXR file of " +
             type_name(channels.empty() ? Imf::FLOAT : channels.front().second) +
             " pixels, not 16-bit ones";
    }
    const long long values = width * height * (long long)channels.size();
    if (channels.empty() || width < 1 || height < 1) return path + ": image has no pixels";
    if (values > kMaxImageValues) {
      return path + ": cannot read image: " + std::to_string(width) + "x" + std::to_string(height) +
             " pixels is beyond what an image may hold here";
    }
    image = ImageF(int(width), int(height), int(channels.size()));
    const std::size_t x_stride = sizeof(float) * channels.size();
    Imf::FrameBuffer frame;
    for (std::size_t c = 0; c < channels.size(); ++c) {
      frame.insert(channels[c].first, Imf::Slice::Make(Imf::FLOAT, image.data.data() + c, window,
                                                       x_stride, x_stride * std::size_t(width)));
    }
    in.setFrameBuffer(frame);
    in.readPixels(window.min.y, window.max.y);
    return {};
  } catch (const std::exception& e) {
    image = ImageF();
    return path + ": cannot decode image: " + first_line(e.what());
  }
}

std::string write_float(const std::string& path, const ImageF& image, bool as_u16,
                        int& error_number) {
  error_number = 0;
  static const char* const kNames[4][4] = {
      {"Y"}, {"R", "G"}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
  std::vector<float> quantised;
  const float* pixels = image.data.data();
  if (as_u16) {  // what a 16-bit file would hold: the values in [0, 1], in steps of 1/65535
    quantised.resize(image.data.size());
    for (std::size_t i = 0; i < quantised.size(); ++i) {
      quantised[i] = unorm_to_float(float_to_unorm<std::uint16_t>(image.data[i]));
    }
    pixels = quantised.data();
  }
  try {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::RLE_COMPRESSION;
    const std::size_t x_stride = sizeof(float) * std::size_t(image.channels);
    Imf::FrameBuffer frame;
    for (int c = 0; c < image.channels; ++c) {
      const char* name = kNames[image.channels - 1][c];
      header.channels().insert(name, Imf::Channel(Imf::FLOAT));
      frame.insert(name,
                   Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(const_cast<float*>(pixels + c)),
                              x_stride, x_stride * std::size_t(image.width)));
    }
    std::vector<std::uint8_t> bytes;
    {
      MemoryStream stream(path, bytes);
      Imf::OutputFile out(stream, header, exr_threads());
      out.setFrameBuffer(frame);
      out.writePixels(image.height);
    }  // the line offsets are written as the file closes
    return write_file(path, bytes, error_number);
  } catch (const std::exception& e) {
    return path + ": cannot write image: " + first_line(e.what());
  }
}

const Table kExrTable = {
    read_float,
    [](const std::string& path, ImageU8& image) {
      ImageF values;
      if (std::string error = read_float(path, Stored::kAny, values); !error.empty()) {
        return error;
      }
      image = ImageU8(values.width, values.height, values.channels);
      for (std::size_t i = 0; i < image.data.size(); ++i) {
        image.data[i] = float_to_unorm<std::uint8_t>(values.data[i]);
      }
      return std::string();
    },
    [](const std::string& path, ImageShape& shape) {
      try {
        const Imf::InputFile in(path.c_str(), 0);
        const Imath::Box2i window = in.header().dataWindow();
        int channels = 0;
        for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) {
          ++channels;
        }
        shape = {window.max.x - window.min.x + 1, window.max.y - window.min.y + 1, channels};
        return std::string();
      } catch (const std::exception& e) {
        return path + ": cannot read image: " + first_line(e.what());
      }
    },
    write_float,
    [](const std::string& path, const ImageU8& image, int& error_number) {
      ImageF values(image.width, image.height, image.channels);
      for (std::size_t i = 0; i < values.data.size(); ++i) {
        values.data[i] = unorm_to_float(image.data[i]);
      }
      return write_float(path, values, false, error_number);
    },
    [](const std::string&) { return std::string(); },
    [](int threads) { requested_threads.store(std::max(0, threads)); },
    []() { return requested_threads.load(); },
};

}  // namespace

const Table& exr_table() { return kExrTable; }

}  // namespace pg::image_codec
