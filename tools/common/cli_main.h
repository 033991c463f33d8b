#pragma once
// Shared exit-code policy of the command-line tools: 0 ok, 1 failure, 2 usage, 3 an accuracy
// gate missed (patchgraph track/eval --max-translation/--max-rotation).
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <map>
#include <new>
#include <string>
#include <utility>
#include <vector>

#include "pg/core/error.h"
#include "stop.h"

namespace pg {

constexpr int kExitOk = 0;
constexpr int kExitFailure = 1;
constexpr int kExitUsage = 2;
constexpr int kExitAccuracy = 3;

// CLI11's NonNegativeNumber and PositiveNumber (which also refuse inf and nan), with a short
// message ("--window: must be finite and >= 0, got -1") instead of the range up to the largest
// double written out in full.
inline CLI::Validator number_check(bool allow_zero) {
  return CLI::Validator(
      [allow_zero](std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value)) return "not a number: " + text;
        if (std::isfinite(value) && (allow_zero ? value >= 0 : value > 0)) return {};
        return std::string("must be finite and ") + (allow_zero ? ">= 0" : "> 0") + ", got " + text;
      },
      allow_zero ? "NONNEGATIVE" : "POSITIVE");
}
inline const CLI::Validator kNonNegative = number_check(true);
inline const CLI::Validator kPositive = number_check(false);

// A number from `low` to `high` (or exactly 0 when `allow_zero`): "--vision-sigma: must be from
// 1e-12 to 1000, got 1e-300"; the help shows "FLOAT:1e-12 to 1000".
inline CLI::Validator range_check(double low, double high, bool allow_zero = false) {
  // Whole bounds written out ("1 to 10000000", not "1 to 1e+07"), others as %g ("1e-12 to 1000").
  const auto whole = [](double v) { return v == std::floor(v) && std::fabs(v) < 1e15; };
  const char* format = whole(low) && whole(high) ? "%.0f" : "%g";
  const auto bound = [format](double v) {
    char text[32];
    std::snprintf(text, sizeof text, format, v);
    return std::string(text);
  };
  const std::string range = bound(low) + " to " + bound(high) + (allow_zero ? " (or 0)" : "");
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value)) return "not a number: " + text;
        if ((value >= low && value <= high) || (allow_zero && value == 0)) return {};
        return std::string("must be from ") + range + ", got " + text;
      },
      range);
}

// A whole number of at least `low`: "--frames: must be at least 10, got 5".
inline CLI::Validator at_least(int low) {
  return CLI::Validator(
      [=](std::string& text) -> std::string {
        double value = 0;
        if (!CLI::detail::lexical_cast(text, value)) return "not a number: " + text;
        if (value >= low) return {};
        return "must be at least " + std::to_string(low) + ", got " + text;
      },
      "at least " + std::to_string(low));
}

// Worker threads: 0 for all cores, else at most this many (tens of thousands of threads on a
// 2-core machine are a hang, not a setting).
constexpr int kMaxThreads = 256;
inline const CLI::Validator kThreads = range_check(1, kMaxThreads, true);

// A CSV cell (RFC 4180): quoted, with its quotes doubled, when it holds a comma, a quote or a line
// break (a dataset folder named "a,b" otherwise shifted every later column).
inline std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
  return quoted + "\"";
}

// One word of a shell command line a message suggests: as it is when it holds only characters no
// shell treats specially, else in single quotes (a path with a space split into two words).
inline std::string shell_word(const std::string& text) {
  const bool plain = !text.empty() && std::all_of(text.begin(), text.end(), [](char c) {
    return std::isalnum(static_cast<unsigned char>(c)) || std::strchr("_./+-:=,@%", c) != nullptr;
  });
  if (plain) return text;
  std::string quoted = "'";
  for (char c : text) quoted += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return quoted + "'";
}

// A markdown table cell: a '|' escaped, line breaks as spaces.
inline std::string markdown_cell(std::string text) {
  std::string out;
  for (char c : text)
    out += c == '|' ? std::string("\\|") : c == '\n' || c == '\r' ? " " : std::string(1, c);
  return out;
}

// The comma-separated items of an option's value, every one kept: "a,,b" and "a," hold an empty
// item (an unset shell variable, say), for the caller to refuse by name.
inline std::vector<std::string> comma_items(const std::string& text) {
  std::vector<std::string> items;
  std::size_t start = 0;
  for (std::size_t comma; (comma = text.find(',', start)) != std::string::npos;
       start = comma + 1) {
    items.push_back(text.substr(start, comma - start));
  }
  if (!text.empty()) items.push_back(text.substr(start));
  return items;
}

// `value` as printf's `format` gives it (a number in a message or a help text).
inline std::string format_number(double value, const char* format = "%g") {
  char text[48];
  std::snprintf(text, sizeof text, format, value);
  return text;
}

// A seed: a whole number from 0 to 2^64 - 1 (the help's "UINT:SEED"). The check itself is
// whole_number_problem's, which run_cli puts in front of every whole-number option.
inline const CLI::Validator kSeed("SEED");

// Throws InputError when the output `out` (the option `out_what`: a folder or a file) is the
// input `input` (`input_what`) or lies inside it: writing there would overwrite or mix into what
// is read (a model written over a dataset's poses.csv, a JSON over the model it evaluates). A path
// that does not exist yet is compared by where it would be.
inline void check_output_is_not_input(const std::string& out, const std::string& input,
                                      const std::string& input_what,
                                      const std::string& out_what = "--out") {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path o = fs::weakly_canonical(out, ec), i = fs::weakly_canonical(input, ec);
  if (o.empty() || i.empty()) return;
  const auto [i_end, o_at] = std::mismatch(i.begin(), i.end(), o.begin(), o.end());
  if (i_end == i.end()) {  // o is i, or below it
    throw InputError(out_what + " " + out + (o == i ? " is " : " is inside ") + input_what + " " +
                     input +
                     (o == i && fs::is_regular_file(i, ec)
                          ? "; give " + out_what + " another file name"
                          : std::string("; write the outputs to another folder")));
  }
}

// Throws InputError when the output folder `out` holds a dataset (its dataset.json): a track's
// poses.csv would replace the dataset's ground truth; or a render of several sensors (its
// sensors.json), whose folder would mix a track's files with the sensors'. With `is_file`, `out` is
// a file and neither its folder nor any folder above it may hold one (a model or results saved as
// a dataset's poses.csv, an image over one of its frames in color/).
inline void check_output_is_no_dataset(const std::string& out, bool is_file = false,
                                       const std::string& out_what = "--out") {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path own =
      is_file ? fs::absolute(out, ec).lexically_normal().parent_path() : fs::path(out);
  for (fs::path folder = own;; folder = folder.parent_path()) {
    const std::string where = folder != own ? " is inside " + folder.string() + ", which holds"
                              : is_file     ? " is in a folder that holds"
                                            : " holds";
    if (fs::exists(folder / "dataset.json", ec)) {
      throw InputError(out_what + " " + out + where +
                       " a dataset (dataset.json), whose files it could replace: write the "
                       "outputs to another folder");
    }
    if (fs::exists(folder / "sensors.json", ec)) {
      throw InputError(out_what + " " + out + where +
                       " a render of several sensors (sensors.json): write the outputs to "
                       "another folder");
    }
    if (!is_file || folder.empty() || folder.parent_path() == folder) return;
  }
}

// What a file holds by its first bytes, for an output that would replace it.
enum class FileKind { kNone, kZip, kPng, kExr, kJpeg, kPly, kJson, kText, kBinary };

inline const char* describe(FileKind kind) {
  switch (kind) {
    case FileKind::kNone:
      return "nothing";
    case FileKind::kZip:
      return "a zip archive (a trained model or checkpoint)";
    case FileKind::kPng:
      return "a PNG image";
    case FileKind::kExr:
      return "an OpenEXR image";
    case FileKind::kJpeg:
      return "a JPEG image";
    case FileKind::kPly:
      return "a PLY point cloud or mesh";
    case FileKind::kJson:
      return "JSON";
    case FileKind::kText:
      return "text";
    case FileKind::kBinary:
      return "binary data";
  }
  return "?";
}

// The first `bytes` bytes of a regular file (fewer if it is shorter); empty for a path that is no
// regular file or cannot be read.
inline std::string file_head(const std::filesystem::path& path, std::size_t bytes) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return {};
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return {};
  std::string head(bytes, '\0');
  head.resize(std::fread(head.data(), 1, bytes, f));
  std::fclose(f);
  return head;
}

// kNone for a path that is no regular file or an empty one.
inline FileKind file_kind(const std::string& path) {
  const std::string text = file_head(path, 512);
  const auto* head = reinterpret_cast<const unsigned char*>(text.data());
  const std::size_t n = text.size();
  const auto starts = [&](const char* magic, std::size_t size) {
    return n >= size && std::memcmp(head, magic, size) == 0;
  };
  if (n == 0) return FileKind::kNone;
  if (starts("PK\x03\x04", 4)) return FileKind::kZip;
  if (starts("\x89PNG", 4)) return FileKind::kPng;
  if (starts("\x76\x2f\x31\x01", 4)) return FileKind::kExr;
  if (starts("\xff\xd8\xff", 3)) return FileKind::kJpeg;
  if (starts("ply", 3)) return FileKind::kPly;
  std::size_t i = 0;
  while (i < n && std::isspace(head[i])) ++i;
  if (i < n && (head[i] == '{' || head[i] == '[')) return FileKind::kJson;
  for (std::size_t k = 0; k < n; ++k) {
    if (head[k] == 0 || (head[k] < 32 && !std::isspace(head[k]))) return FileKind::kBinary;
  }
  return FileKind::kText;
}

// For a command's single output file `out`: throws InputError when it lies in a dataset's folder
// (check_output_is_no_dataset) or already holds a file of none of the `kinds` this command writes
// there (a JSON written over a trained model, a model over a CSV of the user's); a file of one
// of them is replaced, as an earlier run's would be.
inline void check_output_file(const std::string& out, std::initializer_list<FileKind> kinds,
                              const std::string& out_what = "--out") {
  check_output_is_no_dataset(out, true, out_what);
  const FileKind held = file_kind(out);
  if (held == FileKind::kNone || std::find(kinds.begin(), kinds.end(), held) != kinds.end()) {
    return;
  }
  const std::string written = describe(*kinds.begin());
  throw InputError(out_what + " " + out + ": holds " + describe(held) +
                   "; this command would replace it with " + written +
                   ". It is left as it is: give another file name, or remove it first");
}

// The canonical paths of `dirs`; throws InputError when two are one folder however written
// ("a/../b: given twice (also as b)"): a dataset counted twice would weigh twice in every mean
// and median.
inline std::vector<std::filesystem::path> check_given_once(const std::vector<std::string>& dirs) {
  std::vector<std::filesystem::path> canonical;
  std::map<std::string, std::string> seen;  // canonical path -> as given
  for (const std::string& dir : dirs) {
    canonical.push_back(std::filesystem::weakly_canonical(dir));
    const auto [it, fresh] = seen.emplace(canonical.back().string(), dir);
    if (!fresh) throw InputError(dir + ": given twice (also as " + it->second + ")");
  }
  return canonical;
}

// Warns of each dataset of `val` (held out) that is also one of `train` (trained or fitted on):
// its metrics are then on data the model has seen. `trained_on` names `train`'s option.
inline void warn_of_validation_in_training(const std::vector<std::string>& val,
                                           const std::vector<std::string>& train,
                                           const std::string& trained_on) {
  for (const std::string& v : val) {
    for (const std::string& t : train) {
      std::error_code ec;
      if (std::filesystem::equivalent(v, t, ec)) {
        std::fprintf(stderr,
                     "warning: --val %s is also one of %s (%s): its metrics are on data the "
                     "model has seen\n",
                     v.c_str(), trained_on.c_str(), t.c_str());
      }
    }
  }
}

// Throws InputError when a name of the option `option` is given twice ("--methods: patchgraph
// given twice"): its runs would count twice in every median.
inline void check_names_given_once(const std::vector<std::string>& names,
                                   const std::string& option) {
  for (auto name = names.begin(); name != names.end(); ++name) {
    if (std::find(names.begin(), name, *name) != name) {
      throw InputError(option + ": " + *name + " given twice");
    }
  }
}

// Whether a folder holds an earlier run of a command, which OutputFolder may then replace: `found`
// reads the file only that command writes (a track's summary.json, an eval's results.csv);
// `what` names it for the refusal.
struct EarlierRun {
  std::string what;
  std::function<bool(const std::filesystem::path& folder)> found;
};

// Whether `path` is a regular file whose first bytes are `prefix` (a CSV's header).
inline bool file_starts_with(const std::filesystem::path& path, const std::string& prefix) {
  return file_head(path, prefix.size()) == prefix;
}

// The output folder, created before the work so that a path that cannot be one fails at once
// rather than after a long run; removed again at the end of the scope if this created it and
// nothing was written into it (the work failed first). An earlier run's `outputs` in it (file
// names; "a_*.png" matches by prefix and suffix; "runs/" a folder) are removed first, so that a
// run that fails or is stopped half-way leaves none that look like its own. Only an earlier
// run's: when files of those names are there but `earlier_run` does not find that run (a
// user's poses.csv in a folder of their own), or a folder has a file output's name, nothing is
// removed and the run is refused before the work (InputError), as it is when one cannot be
// removed.
class OutputFolder {
 public:
  explicit OutputFolder(std::string dir, const std::vector<std::string>& outputs = {},
                        const EarlierRun& earlier_run = {})
      : dir_(std::move(dir)) {
    namespace fs = std::filesystem;
    check_output_is_no_dataset(dir_);
    std::error_code ec;
    // The outermost folder of the path that does not exist yet: what this run creates.
    fs::path folder = fs::absolute(dir_, ec).lexically_normal();
    if (folder.filename().empty()) folder = folder.parent_path();  // "out/"
    outermost_created_ = folder;
    while (folder.has_parent_path() && folder.parent_path() != folder &&
           !fs::exists(folder.parent_path(), ec)) {
      folder = folder.parent_path();
      outermost_created_ = folder;
    }
    created_ = fs::create_directories(dir_, ec);
    if (ec || !fs::is_directory(dir_)) {
      throw InputError(dir_ + ": cannot create the output folder" +
                       (ec ? ": " + ec.message() : std::string(": not a folder")));
    }
    std::vector<fs::path> earlier;
    fs::directory_iterator entries(dir_, ec);
    if (ec) throw InputError(dir_ + ": cannot list the output folder: " + ec.message());
    for (const auto& entry : entries) {
      const std::string name = entry.path().filename().string();
      for (std::string o : outputs) {
        const bool is_folder = !o.empty() && o.back() == '/';
        if (is_folder) o.pop_back();
        const std::size_t star = o.find('*');
        const std::size_t tail = star == std::string::npos ? 0 : o.size() - star - 1;
        const bool matches =
            star == std::string::npos
                ? name == o
                : name.size() >= o.size() - 1 && name.compare(0, star, o, 0, star) == 0 &&
                      name.compare(name.size() - tail, tail, o, star + 1, tail) == 0;
        if (!matches) continue;
        if (!is_folder && fs::is_directory(fs::symlink_status(entry.path(), ec))) {
          throw InputError(entry.path().string() +
                           ": a folder of an output file's name, which this run would replace; "
                           "it is left as it is: move it or give another --out");
        }
        earlier.push_back(entry.path());
        break;
      }
    }
    if (!earlier.empty() && earlier_run.found && !earlier_run.found(fs::path(dir_))) {
      throw InputError(earlier.front().string() + ": not an earlier run's output (" + dir_ +
                       " holds no " + earlier_run.what +
                       "), and this run would replace it; it is left as it is: move it or give "
                       "another --out");
    }
    for (const auto& path : earlier) {
      // Left in place, an earlier run's file would pass for this run's if this one stops.
      fs::remove_all(path, ec);
      if (ec) {
        throw InputError(path.string() +
                         ": cannot remove this output of an earlier run: " + ec.message());
      }
    }
  }
  // A run that wrote nothing removes the folders it made, its parents' too ("out/a/b").
  ~OutputFolder() {
    if (!created_) return;
    std::error_code ec;
    std::filesystem::path folder = std::filesystem::absolute(dir_, ec).lexically_normal();
    if (folder.filename().empty()) folder = folder.parent_path();
    while (std::filesystem::is_empty(folder, ec) && !ec && std::filesystem::remove(folder, ec)) {
      if (folder == outermost_created_ || !folder.has_parent_path()) break;
      folder = folder.parent_path();
    }
  }
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

 private:
  std::string dir_;
  bool created_ = false;
  std::filesystem::path outermost_created_;
};

// What a dataset write stopped half-way leaves in `out`: it does not open (its poses.csv is
// written last), and the same command (`again`: "render", "run") replaces it.
inline std::string unfinished_dataset_note(const std::string& out, const std::string& again) {
  return out + " holds an unfinished dataset (no poses.csv, it does not open); " + again +
         " again to replace it";
}

// For the catch-all of a dataset write into `out` (label-ball, recording): removes `out` if the
// run made it (`out_existed` false) and rethrows the error being handled, a Stopped with what the
// stop leaves.
[[noreturn]] inline void rethrow_after_dataset_write(const std::string& out, bool out_existed) {
  std::error_code ignored;
  if (!out_existed) std::filesystem::remove_all(out, ignored);
  try {
    throw;
  } catch (const Stopped& e) {
    throw e.with_note(out_existed ? unfinished_dataset_note(out, "run")
                                  : "nothing written (" + out + " removed)");
  }
}

// Runs `check`, a check of option values that throws InputError, and throws its complaint as a
// UsageError (exit 2): a bad option value is a usage error, whichever function finds it.
template <typename F>
void as_usage_error(F&& check) {
  try {
    check();
  } catch (const UsageError&) {
    throw;
  } catch (const InputError& e) {
    throw UsageError(e.what());
  }
}

// What is wrong with `text` as the value of a whole-number option (empty if nothing): an empty
// value, one not in plain decimal digits (CLI11 reads integers as C's strtoll does, so "010" was 8,
// octal, and "0x10" 16), a negative one for an unsigned option (CLI11 wrapped "-1" of a seed to
// 2^64 - 1), or one beyond the option's type (an `int`, or a 64-bit seed; CLI11 said "Could not
// convert"). `range` is what the option's help says of it ("1 to 256 (or 0)", "POSITIVE"), for
// the message.
inline std::string whole_number_problem(const std::string& text, bool is_unsigned,
                                        const std::string& range) {
  if (text.empty()) return "an empty value";
  const std::size_t sign = text[0] == '-' || text[0] == '+' ? 1 : 0;
  const std::string digits = text.substr(sign);
  const bool decimal =
      !digits.empty() && digits.find_first_not_of("0123456789") == std::string::npos;
  if (decimal && digits.size() > 1 && digits[0] == '0') {
    return "'" + text +
           "' is not a whole number in decimal digits (no leading zeros: 010 would read as "
           "octal 8)";
  }
  const std::string largest = is_unsigned ? "18446744073709551615" : "2147483647";
  const std::string smallest = is_unsigned ? "0" : "2147483648";  // without its sign
  const bool negative = text[0] == '-';
  const std::string& limit = negative ? smallest : largest;
  const bool fits = decimal && (digits.size() < limit.size() ||
                                (digits.size() == limit.size() && digits <= limit));
  if (fits) return {};
  // The range in words: "from 1 to 8", "in {1,2,4}", "of at least 1"; the type's own without one.
  const bool bounded = range.find(" to ") != std::string::npos || range.find('{') == 0;
  const std::string type_range =
      "from " + std::string(is_unsigned ? "" : "-") + smallest + " to " + largest;
  std::string words = range == "POSITIVE"           ? "of at least 1"
                      : range == "NONNEGATIVE"      ? "of at least 0"
                      : range.find("at least") == 0 ? "of " + range
                      : range.find('{') == 0        ? "in " + range
                      : bounded                     ? "from " + range
                                                    : type_range;  // "", "SEED"
  // A whole number past what the option's type holds, under a range with no upper bound.
  if (decimal && !negative && !bounded && words != type_range) words += " and at most " + largest;
  return "must be a whole number " + words + ", got " + text;
}

// Puts two checks in front of every option's own, in `app` and its subcommands, both run before
// the option's validators and its conversion:
// - an option's value that is another option's name (`--seeds --out X`, `--out --quiet`): CLI11
//   takes the next word as the value, whatever it is, and the option's own check then said "must
//   be a whole number ..., got --out" (or made a folder named --quiet);
// - whole_number_problem's for a whole-number option: the option's own checks read the value as a
//   floating-point number, so "1.5" or "1e300" passed a range check and failed the conversion
//   with CLI11's "Could not convert: --epochs = 1.5".
inline void check_values_first(CLI::App& app) {
  for (CLI::Option* option : app.get_options()) {
    if (option->get_expected_min() <= 0) continue;          // a flag takes no value
    const std::string full_type = option->get_type_name();  // "INT:1 to 256 (or 0)"
    const std::size_t colon = full_type.find(':');
    const std::string type = full_type.substr(0, colon);
    if (type == "INT" || type == "UINT") {
      const std::string range = colon == std::string::npos ? "" : full_type.substr(colon + 1);
      option->transform(CLI::Validator(
          [is_unsigned = type == "UINT", range](std::string& text) {
            return whole_number_problem(text, is_unsigned, range);
          },
          ""));
    }
    // Added last, so run first (a transform goes in front of the checks before it).
    option->transform(CLI::Validator(
        [&app, name = option->get_name()](std::string& text) -> std::string {
          if (text.size() > 1 && text[0] == '-' && app.get_option_no_throw(text) != nullptr) {
            return "'" + text + "' is an option, not a value: give " + name + " its value";
          }
          return {};
        },
        ""));
  }
  for (CLI::App* sub : app.get_subcommands({})) check_values_first(*sub);
}

// Throws CLI::ValidationError for an option or argument given as an empty string (`--out ""`,
// a shell variable that was never set): no option of these tools means anything by it, and a
// file named "" fails later with a message that names nothing. (Whole numbers and values that
// are options' names were checked before their conversion: check_values_first.)
inline void check_values(const CLI::App& app) {
  for (const CLI::Option* option : app.get_options()) {
    for (const std::string& value : option->results()) {
      if (value.empty() && option->get_expected_min() > 0) {
        throw CLI::ValidationError(option->get_name(), "an empty value");
      }
    }
  }
  for (const CLI::App* sub : app.get_subcommands()) check_values(*sub);
}

// Says a usage error (CLI11's parse errors and UsageError alike) and gives its exit code.
inline int usage_error(const char* what) {
  std::fprintf(stderr, "error: %s\nRun with --help for more information.\n", what);
  return kExitUsage;
}

// Parses argv into `app` and runs `body`; turns every error into a message on stderr and the
// matching exit code.
inline int run_cli(CLI::App& app, int argc, char** argv, const std::function<int()>& body) {
  // A first word that names no subcommand (a typo, a subcommand of the other tool): said so, where
  // CLI11 says only that a subcommand is required.
  const std::vector<CLI::App*> subcommands = app.get_subcommands({});
  if (argc > 1 && argv[1][0] != '-' && !subcommands.empty() &&
      std::none_of(subcommands.begin(), subcommands.end(),
                   [&](const CLI::App* sub) { return sub->check_name(argv[1]); })) {
    std::string known;
    for (const CLI::App* sub : subcommands) known += (known.empty() ? "" : ", ") + sub->get_name();
    std::fprintf(stderr,
                 "error: unknown subcommand '%s' (known: %s)\nRun with --help for more "
                 "information.\n",
                 argv[1], known.c_str());
    return kExitUsage;
  }
  // --version: the project's version (tools/CMakeLists.txt gives it).
  app.set_version_flag("--version",
                       std::filesystem::path(argv[0]).filename().string() + " " + PG_VERSION);
  check_values_first(app);
  try {
    app.parse(argc, argv);
    check_values(app);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ArgumentMismatch& e) {
    // An option of one value given twice: CLI11 says "--out: At Most 1 required but received 2".
    std::string what = e.what();
    const std::string says = ": At Most 1 required but received ";
    const std::size_t at = what.find(says);
    if (at != std::string::npos) {
      what = what.substr(0, at) + ": given " + what.substr(at + says.size()) +
             " times; it takes one value (give it once)";
    }
    return usage_error(what.c_str());
  } catch (const CLI::RequiredError& e) {
    // An option the tool does not know is the likelier mistake (a misspelt --out leaves --out
    // unset): said first, as it is when nothing is missing.
    const std::vector<std::string> unknown = app.remaining(true);
    if (!unknown.empty()) return usage_error(CLI::ExtrasError(unknown).what());
    return usage_error(e.what());
  } catch (const CLI::ParseError& e) {  // said as the tools' own usage errors are
    return usage_error(e.what());
  }
  try {
    return body();
  } catch (const Stopped& e) {
    // On a terminal the progress line it stopped is still open.
    std::fprintf(stderr, "%serror: %s\n", isatty(fileno(stderr)) ? "\n" : "", e.what());
    return e.exit_code();
  } catch (const UsageError& e) {
    return usage_error(e.what());
  } catch (const InputError& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
  } catch (const std::filesystem::filesystem_error& e) {
    // A folder that cannot be listed or a path that cannot be looked at (no permission): the path
    // and the cause, not the library's "filesystem error: status: ..." wording.
    if (e.path1().empty()) {
      std::fprintf(stderr, "error: %s\n", e.code().message().c_str());
    } else {
      std::fprintf(stderr, "error: %s: %s\n", e.path1().c_str(), e.code().message().c_str());
    }
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr,
                 "error: out of memory: the images, frames or threads asked for need more memory "
                 "than is free (smaller images, fewer threads or a shorter run need less)\n");
  } catch (const std::exception& e) {
    // LibTorch's errors carry a C++ backtrace after their message: keep the message.
    std::string what = e.what();
    what = what.substr(0, std::min(what.find("\nframe #"), what.find("\nException raised from")));
    std::fprintf(stderr, "error: %s\n", what.c_str());
  }
  return kExitFailure;
}

}  // namespace pg
