#include "zip_check.h"

#include <zlib.h>

#include <cstdint>
#include <fstream>
#include <iterator>
#include <vector>

#include "pg/core/error.h"

namespace pg::learn {
namespace {

constexpr std::uint32_t kLocalHeader = 0x04034b50, kDirectoryEntry = 0x02014b50,
                        kDirectoryEnd = 0x06054b50, kDirectoryEnd64 = 0x06064b50,
                        kDirectoryEnd64Locator = 0x07064b50;

// Little-endian fields of the zip format, each read checked against the end of the file.
class Reader {
 public:
  Reader(const std::vector<unsigned char>& bytes, const std::string& path, const std::string& what)
      : bytes_(bytes), path_(path), what_(what) {}
  std::uint64_t get(std::uint64_t at, int size) const {
    if (at > bytes_.size() || std::uint64_t(size) > bytes_.size() - at) fail("cut short");
    std::uint64_t v = 0;
    for (int i = size - 1; i >= 0; --i) v = (v << 8) | bytes_[std::size_t(at) + std::size_t(i)];
    return v;
  }
  [[noreturn]] void fail(const std::string& why) const {
    throw InputError(path_ + ": corrupt " + what_ + " (" + why + ")");
  }

 private:
  const std::vector<unsigned char>& bytes_;
  const std::string& path_;
  const std::string& what_;
};

// The CRC-32 of a deflated entry's data once inflated; fails if it does not inflate to `size`.
std::uint32_t inflated_crc(const unsigned char* data, std::uint64_t packed, std::uint64_t size,
                           const Reader& r, const std::string& name) {
  if (packed > UINT32_MAX || size >= UINT32_MAX) r.fail(name + " is too large to check");
  std::vector<unsigned char> out(std::size_t(size) + 1);
  z_stream z{};
  if (inflateInit2(&z, -MAX_WBITS) != Z_OK) r.fail("cannot inflate " + name);
  z.next_in = const_cast<unsigned char*>(data);
  z.avail_in = uInt(packed);
  z.next_out = out.data();
  z.avail_out = uInt(out.size());
  const int status = inflate(&z, Z_FINISH);
  const std::uint64_t produced = z.total_out;
  inflateEnd(&z);
  if (status != Z_STREAM_END || produced != size) r.fail(name + " does not inflate");
  return std::uint32_t(crc32(0L, out.data(), uInt(size)));
}

}  // namespace

void check_zip_checksums(const std::string& path, const std::string& what) {
  std::ifstream in(path, std::ios::binary);
  const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(in)),
                                         std::istreambuf_iterator<char>());
  const Reader r(bytes, path, what);
  if (bytes.size() < 22 || r.get(0, 4) != kLocalHeader) return;  // not a zip: Torch says so
  // The end-of-directory record: the last one in the final 64 kB (a comment may follow it).
  std::uint64_t end = 0;
  bool found = false;
  for (std::uint64_t at = bytes.size() - 22; !found; --at) {
    found = r.get(at, 4) == kDirectoryEnd;
    if (found) end = at;
    if (at == 0 || bytes.size() - at > 22 + 65535) break;
  }
  if (!found) r.fail("no zip directory at its end: cut short?");
  std::uint64_t entries = r.get(end + 10, 2), directory = r.get(end + 16, 4);
  if ((entries == 0xFFFF || directory == 0xFFFFFFFF) && end >= 20 &&
      r.get(end - 20, 4) == kDirectoryEnd64Locator) {
    const std::uint64_t end64 = r.get(end - 20 + 8, 8);
    if (r.get(end64, 4) != kDirectoryEnd64) r.fail("damaged zip64 directory record");
    entries = r.get(end64 + 32, 8);
    directory = r.get(end64 + 48, 8);
  }
  std::uint64_t at = directory;
  for (std::uint64_t k = 0; k < entries; ++k) {
    if (r.get(at, 4) != kDirectoryEntry) r.fail("damaged zip directory");
    const auto method = r.get(at + 10, 2);
    const auto crc = std::uint32_t(r.get(at + 16, 4));
    std::uint64_t packed = r.get(at + 20, 4), size = r.get(at + 24, 4);
    const std::uint64_t name_length = r.get(at + 28, 2), extra_length = r.get(at + 30, 2),
                        comment_length = r.get(at + 32, 2);
    std::uint64_t local = r.get(at + 42, 4);
    const std::uint64_t name_at = at + 46;
    if (name_at + name_length > bytes.size()) r.fail("cut short");
    const std::string name(bytes.begin() + std::ptrdiff_t(name_at),
                           bytes.begin() + std::ptrdiff_t(name_at + name_length));
    // zip64: the 32-bit fields that are all ones come from the extra field, in this order.
    for (std::uint64_t e = name_at + name_length; e + 4 <= name_at + name_length + extra_length;) {
      const std::uint64_t id = r.get(e, 2), length = r.get(e + 2, 2);
      if (id == 0x0001) {
        std::uint64_t field = e + 4;
        for (std::uint64_t* value : {&size, &packed, &local}) {
          if (*value == 0xFFFFFFFF && field + 8 <= e + 4 + length) {
            *value = r.get(field, 8);
            field += 8;
          }
        }
      }
      e += 4 + length;
    }
    if (r.get(local, 4) != kLocalHeader) r.fail("damaged entry " + name);
    const std::uint64_t data = local + 30 + r.get(local + 26, 2) + r.get(local + 28, 2);
    if (data > bytes.size() || packed > bytes.size() - data) r.fail("cut short in " + name);
    std::uint32_t actual = 0;
    if (method == 0) {
      actual = std::uint32_t(crc32_z(0L, bytes.data() + data, z_size_t(packed)));
    } else if (method == 8) {
      actual = inflated_crc(bytes.data() + data, packed, size, r, name);
    } else {
      r.fail(name + " is packed by an unknown method " + std::to_string(method));
    }
    if (actual != crc) r.fail(name + " does not match its checksum: bytes damaged");
    at = name_at + name_length + extra_length + comment_length;
  }
}

}  // namespace pg::learn
