#pragma once
// Helpers shared by the test suites: a per-test temporary folder, and running a command line.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "pg/core/error.h"

namespace pg::testing_support {

// A fresh folder named after the running test, removed afterwards.
struct TempDir {
  std::filesystem::path path;
  TempDir() {
    path = std::filesystem::temp_directory_path() /
           ("pg_test_" + std::to_string(::getpid()) + "_" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(path);
    std::filesystem::create_directories(path);
  }
  ~TempDir() { std::filesystem::remove_all(path); }
  std::string str(const std::string& sub = "") const { return (path / sub).string(); }
};

struct CliRun {
  int code = -1;    // the exit status (-1 if the command did not exit normally)
  std::string out;  // stdout and stderr together
};

inline CliRun run_command(const std::string& binary, const std::string& args) {
  const std::string cmd = binary + " " + args + " 2>&1";
  CliRun r;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return r;
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), int(buf.size()), pipe)) r.out += buf.data();
  const int status = pclose(pipe);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The options of `binary subcommand` whose --help type starts with one of `types` ("INT",
// "FLOAT"), each given `per_option` of `values` in turn, so that the options together meet every
// value (a run of patchgraph takes 0.7 s, LibTorch's loading). Returns what went wrong
// ("--epochs 1.5: exit 0, ..."), empty when each was refused as a usage error (exit 2) in the
// tools' own words, naming the option. Fails also when the help shows fewer than `at_least` such
// options, so that a changed help layout cannot pass unchecked.
inline std::vector<std::string> typed_options_refused(
    const std::string& binary, const std::string& subcommand, const std::vector<std::string>& types,
    const std::vector<std::string>& values, std::size_t at_least, std::size_t per_option) {
  std::vector<std::string> problems;
  const CliRun help = run_command(binary, subcommand + " --help");
  std::istringstream lines(help.out);
  std::vector<std::string> options;
  for (std::string line; std::getline(lines, line);) {
    std::istringstream words(line);
    std::string names, type;
    words >> names >> type;  // "-o,--out TEXT", "--window INT:NONNEGATIVE"
    const bool typed = std::any_of(types.begin(), types.end(),
                                   [&](const std::string& t) { return type.rfind(t, 0) == 0; });
    if (names.rfind("-", 0) == 0 && typed) options.push_back(names.substr(names.rfind(',') + 1));
  }
  if (options.size() < at_least) {
    problems.push_back(subcommand + ": " + std::to_string(options.size()) +
                       " such options in its --help, expected at least " +
                       std::to_string(at_least) + ":\n" + help.out);
  }
  std::size_t next = 0;
  for (const std::string& option : options) {
    for (std::size_t k = 0; k < per_option; ++k) {
      const std::string& value = values[next++ % values.size()];
      const CliRun r = run_command(binary, subcommand + " " + option + " " + value);
      const bool clear = r.code == 2 && r.out.rfind("error: " + option + ": ", 0) == 0 &&
                         r.out.find("Could not convert") == std::string::npos &&
                         r.out.find("not in range") == std::string::npos;
      if (!clear) {
        problems.push_back(subcommand + " " + option + " " + value + ": exit " +
                           std::to_string(r.code) + ", " + r.out);
      }
    }
  }
  return problems;
}

// Every whole-number option (--help's INT or UINT) given values that are no whole number it
// takes: a fraction, exponents, numbers past an int's or a 64-bit seed's range, a word, hex.
inline std::vector<std::string> whole_number_options_refused(const std::string& binary,
                                                             const std::string& subcommand,
                                                             std::size_t at_least,
                                                             std::size_t per_option = 2) {
  return typed_options_refused(
      binary, subcommand, {"INT", "UINT"},
      {"1.5", "1e300", "18446744073709551616", "abc", "-99999999999", "0x10", "1e-12"}, at_least,
      per_option);
}

// Every real-number option (--help's FLOAT) given what is no number: NaN, which compares false
// with any bound (CLI11's own range check let it through), and a word.
inline std::vector<std::string> real_number_options_refused(const std::string& binary,
                                                            const std::string& subcommand,
                                                            std::size_t at_least) {
  return typed_options_refused(binary, subcommand, {"FLOAT"}, {"nan", "abc"}, at_least, 1);
}

// The whole text of a file ("" when it cannot be read).
inline std::string file_text(const std::string& path) {
  std::ifstream in(path);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

// Runs `binary args` (through /bin/sh, SIGINT and SIGTERM at their defaults, as from a terminal),
// sends it `signal_number` once its output (stdout and stderr together, in `log`) holds `text`,
// and waits for it to end. code: its exit status; -1 if it never showed `text` (it ended first,
// or not within 5 minutes), was killed outright by the signal, or the log could not be made. A
// run that ends on its own between showing `text` and the signal gives its own exit status
// (the callers' runs take a second or more after the text they wait for). `times` > 1 sends the
// signal that many times, 2 ms apart (as coreutils `timeout` does: the job, then its group).
inline CliRun run_and_signal(const std::string& binary, const std::string& args,
                             const std::string& text, int signal_number, const std::string& log,
                             int times = 1) {
  const std::string command = "exec " + binary + " " + args;
  // Emptied before the run starts: an earlier run's log holds `text` already.
  std::ofstream(log, std::ios::trunc).close();
  const pid_t pid = fork();
  if (pid == 0) {
    std::signal(SIGINT, SIG_DFL);
    std::signal(SIGTERM, SIG_DFL);
    const int fd = open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (fd < 0) _exit(126);
    dup2(fd, 1);
    dup2(fd, 2);
    execl("/bin/sh", "sh", "-c", command.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  const auto read_log = [&] { return file_text(log); };
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::minutes(5);
  int status = 0;
  bool signalled = false, ended = false;
  while (!ended && std::chrono::steady_clock::now() < deadline) {
    ended = waitpid(pid, &status, WNOHANG) == pid;
    if (!ended && !signalled && read_log().find(text) != std::string::npos) {
      for (int k = 0; k < times; ++k) {
        if (k > 0) usleep(2000);  // the first one handled by then
        kill(pid, signal_number);
      }
      signalled = true;
    }
    if (!ended) usleep(10000);
  }
  if (!ended) {
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
  }
  CliRun r;
  r.out = read_log();
  r.code = signalled && ended && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

// The comma-separated cells of one CSV line (the project's CSV files quote nothing).
inline std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> cells;
  std::stringstream ss(line);
  for (std::string c; std::getline(ss, c, ',');) cells.push_back(c);
  return cells;
}

// A CSV file with a header row (results.csv, bench.csv): its columns by name and its rows. A
// column it lacks, or a row short of it, throws std::out_of_range from cell(), failing the test.
struct CsvTable {
  std::map<std::string, std::size_t> column;
  std::vector<std::vector<std::string>> rows;
  const std::string& cell(std::size_t row, const std::string& name) const {
    return rows.at(row).at(column.at(name));
  }
};
inline CsvTable read_csv_table(const std::string& path) {
  CsvTable table;
  std::ifstream in(path);
  std::string line;
  if (!std::getline(in, line)) return table;
  const std::vector<std::string> header = split_csv_line(line);
  for (std::size_t i = 0; i < header.size(); ++i) table.column[header[i]] = i;
  while (std::getline(in, line)) table.rows.push_back(split_csv_line(line));
  return table;
}

// Runs f and expects an InputError whose message contains every one of `parts` (a file name, a
// field, what was expected).
template <typename F>
void expect_input_error(F&& f, std::initializer_list<std::string> parts) {
  try {
    f();
    ADD_FAILURE() << "expected an InputError";
  } catch (const InputError& e) {
    for (const auto& part : parts) {
      EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
          << "'" << part << "' not in: " << e.what();
    }
  }
}

}  // namespace pg::testing_support
