#include "pg/core/file_io.h"

#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <vector>

#include "pg/core/error.h"
#include "pg/core/hash.h"

namespace pg {

namespace fs = std::filesystem;

std::uintmax_t folder_bytes(const std::string& folder) {
  std::uintmax_t bytes = 0;
  std::error_code ec;
  for (const auto& entry : fs::recursive_directory_iterator(folder, ec)) {
    if (entry.is_regular_file(ec)) bytes += entry.file_size(ec);
  }
  return bytes;
}

std::string file_digest(const std::string& path) {
  require_regular_file(path, "a file to digest");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(path + ": cannot read (" + std::strerror(errno) + ")");
  std::uint64_t h = kFnvOffset;
  std::vector<char> chunk(1 << 16);
  while (in) {
    in.read(chunk.data(), std::streamsize(chunk.size()));
    h = fnv1a(chunk.data(), std::size_t(in.gcount()), h);
  }
  if (in.bad()) throw InputError(path + ": cannot read (a read failed)");
  return hex64(h);
}

std::string write_failure_cause(const std::string& path, int error_number) {
  std::string cause = error_number != 0 ? std::strerror(error_number) : "";
  fs::path folder = fs::path(path).parent_path();
  if (folder.empty()) folder = ".";
  std::error_code ec;
  const fs::space_info space = fs::space(folder, ec);
  // A file system of no capacity (/proc, /sys) is no full disk.
  if (!ec && space.capacity > 0 && space.available < kLowDiskSpace) {
    cause += (cause.empty() ? "" : "; ") + std::string("the disk holding ") + folder.string() +
             " is full: " + std::to_string(space.available / 1024) + " KB free";
  }
  return cause.empty() ? "" : " (" + cause + ")";
}

namespace {

// Writes `text` to `path`; nullopt when every byte reached the file, else the cause
// (write_failure_cause).
std::optional<std::string> try_write(const std::string& path, std::string_view text) {
  errno = 0;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) {
    out.write(text.data(), std::streamsize(text.size()));
    out.close();  // the last buffered bytes reach the file here, or fail to
  }
  if (out) return std::nullopt;
  return write_failure_cause(path, errno);
}

}  // namespace

std::ofstream open_for_writing(const std::string& path) {
  errno = 0;
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw InputError(path + ": cannot write" + write_failure_cause(path, errno));
  return out;
}

void close_checked(std::ofstream& out, const std::string& path) {
  errno = 0;
  out.close();  // the last buffered bytes reach the file here, or fail to
  if (!out) throw InputError(path + ": cannot write" + write_failure_cause(path, errno));
}

void write_text_file(const std::string& path, std::string_view text) {
  if (const auto cause = try_write(path, text)) throw InputError(path + ": cannot write" + *cause);
}

std::string temporary_path_for(const std::string& path) {
  static std::atomic<unsigned> count{0};
  return path + ".tmp." + std::to_string(::getpid()) + "." + std::to_string(count++);
}

bool is_special_file(const std::string& path) {
  std::error_code ec;
  const fs::file_status s = fs::status(path, ec);
  return !ec && fs::exists(s) && !fs::is_regular_file(s) && !fs::is_directory(s);
}

std::string replaceable_file(const std::string& path) {
  if (is_special_file(path)) {
    throw InputError(path +
                     ": is a device or pipe; a file written here would replace it: give a "
                     "file name");
  }
  std::error_code ec;
  // A folder cannot be replaced by the file (the rename fails only after the work is done).
  if (fs::is_directory(path, ec)) throw InputError(path + ": is a folder; give a file name");
  if (!fs::is_symlink(path, ec)) return path;
  const fs::path target = fs::weakly_canonical(path, ec);
  return ec ? path : target.string();
}

void require_regular_file(const std::string& path, const std::string& what) {
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) return;
  if (fs::is_directory(status)) throw InputError(path + ": is a directory, not " + what);
  if (!fs::is_regular_file(status)) {
    throw InputError(path + ": is not a regular file (a device, pipe or socket), not " + what);
  }
}

void check_can_write(const std::string& path) {
  if (is_special_file(path)) return;
  const std::string probe = temporary_path_for(replaceable_file(path));
  errno = 0;
  if (!std::ofstream(probe))
    throw InputError(path + ": cannot write" + write_failure_cause(path, errno));
  std::error_code ec;
  fs::remove(probe, ec);
}

void write_text_atomically(const std::string& path, std::string_view text,
                           const std::string& what) {
  const std::string cannot = ": cannot write" + (what.empty() ? "" : " the " + what);
  if (is_special_file(path)) {  // /dev/stdout, /dev/null, a FIFO: written to, not replaced
    if (const auto cause = try_write(path, text)) throw InputError(path + cannot + *cause);
    return;
  }
  const std::string target = replaceable_file(path);
  const std::string tmp = temporary_path_for(target);
  std::error_code ec;
  if (const auto cause = try_write(tmp, text)) {
    fs::remove(tmp, ec);
    throw InputError(path + cannot + *cause);
  }
  fs::rename(tmp, target, ec);
  if (ec) {
    const std::string message = what.empty()
                                    ? path + ": cannot replace it with " + tmp + ": " + ec.message()
                                    : path + cannot + ": " + ec.message();
    fs::remove(tmp, ec);
    throw InputError(message);
  }
}

}  // namespace pg
