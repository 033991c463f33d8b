#pragma once
// Writing files so that a full disk (or a folder gone from under a run) is an InputError naming
// the file and the cause, never a truncated file taken for a whole one.
#include <cctype>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace pg {

// The file's extension in lower case (".png"). Inline: the image and video modules use it too,
// which do not link pg_core.
inline std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  for (auto& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  return ext;
}

// Whether the file's extension is a video container's (mp4, avi, mkv, mov, ...): for options
// that take images or videos, and to refuse a video where an image is expected by name, whatever
// the image reader makes of it.
inline bool has_video_extension(const std::string& path) {
  const std::string ext = lower_extension(path);
  for (const char* video : {".mp4", ".m4v", ".mov", ".avi", ".mkv", ".webm", ".mpg", ".mpeg", ".ts",
                            ".wmv", ".flv", ".ogv", ".h264", ".264"}) {
    if (ext == video) return true;
  }
  return false;
}

// The bytes of the files in `folder` and below it (0 for none, or no such folder).
std::uintmax_t folder_bytes(const std::string& folder);

// The FNV-1a of the file's bytes as 16 hex digits (pg/core/hash.h): tells a file rewritten in
// place (a model trained again into the same path) from the one before. InputError naming `path`
// when it cannot be read.
std::string file_digest(const std::string& path);

// Free space below which a failed write is put down to a full disk [bytes].
inline constexpr unsigned long long kLowDiskSpace = 1ull << 20;

// " (CAUSE)" for a write of `path` that failed with `error_number` (errno; 0 when not known),
// naming a disk with less than kLowDiskSpace free as full; "" when nothing is known.
std::string write_failure_cause(const std::string& path, int error_number);
// `path` opened for writing (replacing it); InputError "PATH: cannot write (CAUSE)" when it
// cannot be.
std::ofstream open_for_writing(const std::string& path);
// Closes `out`, opened on `path`, and throws InputError "PATH: cannot write (CAUSE)" unless every
// write to it reached the file.
void close_checked(std::ofstream& out, const std::string& path);
// Writes `text` to `path`, replacing it; InputError as close_checked.
void write_text_file(const std::string& path, std::string_view text);
// The same through a temporary file beside it (temporary_path_for) and a rename, so no reader
// sees half a file: a write that fails leaves the previous file as it was and no temporary file.
// A device or pipe at `path` (/dev/stdout, a FIFO) is written to directly, a symbolic link's
// file replaced (replaceable_file). `what`, if given, names the file in the message: "PATH:
// cannot write the WHAT (CAUSE)".
void write_text_atomically(const std::string& path, std::string_view text,
                           const std::string& what = "");
// The file that a whole-file replacement (a temporary file renamed over it) of `path` renames
// onto: `path`, or the file a symbolic link there points to (the link stays a link). Throws
// InputError naming `path` when it is a device, pipe or socket, which a rename would replace
// with a plain file (as root, /dev/null itself), or a folder (or a link to one), which it cannot
// replace.
std::string replaceable_file(const std::string& path);
// Whether `path` (links followed) is a device, pipe or socket.
bool is_special_file(const std::string& path);
// Throws InputError "PATH: cannot write (CAUSE)" when no file can be made where a whole-file
// write of `path` puts its temporary file (a folder not writable, /proc): checked before long
// work rather than after it. A device or pipe passes (write_text_atomically writes to it).
void check_can_write(const std::string& path);
// Throws InputError naming `path`, read as `what` ("a mesh file"), when it is a directory ("PATH:
// is a directory, not WHAT") or not a regular file ("PATH: is not a regular file (a device,
// pipe or socket), not WHAT"): reading a pipe with no writer blocks for ever, a device may never
// end. A path that does not exist passes (the caller's open says so in its own words).
void require_regular_file(const std::string& path, const std::string& what);
// A name beside `path` for the temporary file a write goes to before it is renamed to `path`:
// PATH.tmp.PID.N, so that two processes (or threads) writing one file at once do not take each
// other's temporary file away (the last rename wins, each file whole).
std::string temporary_path_for(const std::string& path);

}  // namespace pg
