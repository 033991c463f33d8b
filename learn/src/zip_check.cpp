#include "zip_check.h"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <fstream>
#include <vector>

#include "pg/core/error.h"

namespace pg::learn {
namespace {

constexpr std::uint32_t kLocalHeader = 0x04034b50, kDirectoryEntry = 0x02014b50,
                        kDirectoryEnd = 0x06054b50, kDirectoryEnd64 = 0x06064b50,
                        kDirectoryEnd64Locator = 0x07064b50;
constexpr std::size_t kChunk = 1 << 16;  // bytes read (and inflated) at a time

// Reads the zip's fields from the file, each read checked against the file's end. Memory stays
// a few chunks whatever sizes and offsets a damaged file claims.
class ZipFile {
 public:
  ZipFile(const std::string& path, const std::string& what)
      : in_(path, std::ios::binary), path_(path), what_(what) {
    in_.seekg(0, std::ios::end);
    size_ = in_ ? std::uint64_t(in_.tellg()) : 0;
  }
  std::uint64_t size() const { return size_; }
  // `count` bytes at `at` into `out`.
  void read(std::uint64_t at, std::uint64_t count, unsigned char* out) {
    if (at > size_ || count > size_ - at) fail("cut short");
    in_.clear();
    in_.seekg(std::streamoff(at));
    in_.read(reinterpret_cast<char*>(out), std::streamsize(count));
    if (!in_) fail("cannot be read");
  }
  // A little-endian field of `bytes` (at most 8) at `at`.
  std::uint64_t get(std::uint64_t at, int bytes) {
    std::array<unsigned char, 8> b{};
    read(at, std::uint64_t(bytes), b.data());
    std::uint64_t v = 0;
    for (int i = bytes - 1; i >= 0; --i) v = (v << 8) | b[std::size_t(i)];
    return v;
  }
  std::string text(std::uint64_t at, std::uint64_t count) {
    std::string s(std::size_t(std::min<std::uint64_t>(count, 1024)), '\0');
    read(at, s.size(), reinterpret_cast<unsigned char*>(s.data()));
    return s;
  }
  [[noreturn]] void fail(const std::string& why) const {
    throw InputError(path_ + ": corrupt " + what_ + " (" + why + ")");
  }

 private:
  std::ifstream in_;
  std::uint64_t size_ = 0;
  const std::string& path_;
  const std::string& what_;
};

// The CRC-32 of the `packed` bytes at `at`, as stored (method 0) or inflated (method 8); fails
// unless they come to `size` bytes.
std::uint32_t entry_crc(ZipFile& zip, std::uint64_t at, std::uint64_t packed, std::uint64_t size,
                        bool deflated, const std::string& name) {
  std::vector<unsigned char> in(kChunk), out(kChunk);
  uLong crc = crc32(0L, Z_NULL, 0);
  if (!deflated) {
    if (packed != size) zip.fail(name + " is stored at another size than it says");
    for (std::uint64_t done = 0; done < packed;) {
      const std::uint64_t n = std::min<std::uint64_t>(kChunk, packed - done);
      zip.read(at + done, n, in.data());
      crc = crc32_z(crc, in.data(), z_size_t(n));
      done += n;
    }
    return std::uint32_t(crc);
  }
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) zip.fail("cannot inflate " + name);
  std::uint64_t read = 0, produced = 0;
  int status = Z_OK;
  while (status != Z_STREAM_END) {
    if (z.avail_in == 0) {
      const std::uint64_t n = std::min<std::uint64_t>(kChunk, packed - read);
      if (n == 0) break;  // ran out of data before the stream's end
      zip.read(at + read, n, in.data());
      read += n;
      z.next_in = in.data();
      z.avail_in = uInt(n);
    }
    z.next_out = out.data();
    z.avail_out = uInt(out.size());
    status = inflate(&z, Z_NO_FLUSH);
    if (status != Z_OK && status != Z_STREAM_END) break;
    const std::size_t got = out.size() - z.avail_out;
    crc = crc32_z(crc, out.data(), got);
    produced += got;
    if (produced > size) break;  // more than it says: no need to inflate the rest
  }
  inflateEnd(&z);
  if (status != Z_STREAM_END || produced != size) zip.fail(name + " does not inflate");
  return std::uint32_t(crc);
}

}  // namespace

void check_zip_checksums(const std::string& path, const std::string& what) {
  ZipFile zip(path, what);
  if (zip.size() < 22 || zip.get(0, 4) != kLocalHeader) return;  // not a zip: Torch says so
  // The end-of-directory record: the last one in the final 64 kB (a comment may follow it).
  const std::uint64_t tail = std::min<std::uint64_t>(zip.size(), 22 + 65535);
  std::vector<unsigned char> end_bytes(tail);
  zip.read(zip.size() - tail, tail, end_bytes.data());
  std::uint64_t end = 0;
  bool found = false;
  for (std::uint64_t k = tail - 22 + 1; k-- > 0 && !found;) {
    found = end_bytes[k] == 0x50 && end_bytes[k + 1] == 0x4b && end_bytes[k + 2] == 0x05 &&
            end_bytes[k + 3] == 0x06;
    if (found) end = zip.size() - tail + k;
  }
  if (!found) zip.fail("no zip directory at its end: cut short?");
  std::uint64_t entries = zip.get(end + 10, 2), at = zip.get(end + 16, 4);
  // Torch reads the zip64 record wherever there is one (every model and checkpoint has it), so
  // the check reads the same; the 16-bit record must agree with it where it is not all ones.
  if (end >= 20 && zip.get(end - 20, 4) == kDirectoryEnd64Locator) {
    const std::uint64_t end64 = zip.get(end - 20 + 8, 8);
    if (zip.get(end64, 4) != kDirectoryEnd64) zip.fail("damaged zip64 directory record");
    const std::uint64_t entries64 = zip.get(end64 + 32, 8), at64 = zip.get(end64 + 48, 8);
    if ((entries != 0xFFFF && entries != entries64) || (at != 0xFFFFFFFF && at != at64)) {
      zip.fail("its two directory records disagree");
    }
    entries = entries64;
    at = at64;
  }
  for (std::uint64_t k = 0; k < entries; ++k) {
    if (zip.get(at, 4) != kDirectoryEntry) zip.fail("damaged zip directory");
    const std::uint64_t method = zip.get(at + 10, 2);
    const auto crc = std::uint32_t(zip.get(at + 16, 4));
    std::uint64_t packed = zip.get(at + 20, 4), size = zip.get(at + 24, 4);
    const std::uint64_t name_length = zip.get(at + 28, 2), extra_length = zip.get(at + 30, 2),
                        comment_length = zip.get(at + 32, 2);
    std::uint64_t local = zip.get(at + 42, 4);
    const std::string name = zip.text(at + 46, name_length);
    // zip64: the 32-bit fields that are all ones come from the extra field, in this order.
    const std::uint64_t extra = at + 46 + name_length;
    for (std::uint64_t e = extra; e + 4 <= extra + extra_length;) {
      const std::uint64_t id = zip.get(e, 2), length = zip.get(e + 2, 2);
      if (id == 0x0001) {
        std::uint64_t field = e + 4;
        for (std::uint64_t* value : {&size, &packed, &local}) {
          if (*value == 0xFFFFFFFF && field + 8 <= e + 4 + length) {
            *value = zip.get(field, 8);
            field += 8;
          }
        }
      }
      e += 4 + length;
    }
    if (zip.get(local, 4) != kLocalHeader) zip.fail("damaged entry " + name);
    const std::uint64_t data = local + 30 + zip.get(local + 26, 2) + zip.get(local + 28, 2);
    if (data > zip.size() || packed > zip.size() - data) zip.fail("cut short in " + name);
    if (method != 0 && method != 8) {
      zip.fail(name + " is packed by an unknown method " + std::to_string(method));
    }
    if (entry_crc(zip, data, packed, size, method == 8, name) != crc) {
      zip.fail(name + " does not match its checksum: bytes damaged");
    }
    at = extra + extra_length + comment_length;
  }
}

}  // namespace pg::learn
