#pragma once
// Ctrl-C (SIGINT) and SIGTERM stop a long job at its next step (a frame, a batch) instead of
// killing it where it stands: the error unwinds, so an output folder the run made and left empty
// goes again, no temporary file stays, and run_cli exits with 128 + the signal's number, as a
// shell reports a job it stopped. Only inside a StopOnSignals scope, around work that checks
// (stop_if_asked, Progress::update); elsewhere a signal ends the process at once, as by default.
// A second signal, of either kind, ends the process at once, unless it comes within
// kRepeatedStopNs of the first: that is the same stop asked twice (coreutils `timeout` signals
// the job and then its whole process group), which would otherwise end the run before it
// cleaned up.
#include <signal.h>
#include <time.h>

#include <atomic>
#include <csignal>
#include <exception>
#include <stdexcept>
#include <string>

namespace pg {

inline std::atomic<int> g_stop_signal{0};
inline std::atomic<long long> g_stop_signal_ns{0};  // when it came, CLOCK_MONOTONIC
static_assert(std::atomic<int>::is_always_lock_free, "read in a signal handler");
static_assert(std::atomic<long long>::is_always_lock_free, "read in a signal handler");
inline constexpr long long kRepeatedStopNs = 500'000'000;

inline void on_stop_signal(int signal_number) {
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);  // async-signal-safe
  const long long now_ns = now.tv_sec * 1'000'000'000LL + now.tv_nsec;
  if (g_stop_signal.load() == 0) {
    g_stop_signal_ns.store(now_ns);
    g_stop_signal.store(signal_number);
    return;
  }
  if (now_ns - g_stop_signal_ns.load() < kRepeatedStopNs) return;  // the first one again
  // A later one: handled as without a handler, once this one returns (it is blocked until then).
  struct sigaction fallback {};
  fallback.sa_handler = SIG_DFL;
  sigemptyset(&fallback.sa_mask);
  sigaction(SIGINT, &fallback, nullptr);
  sigaction(SIGTERM, &fallback, nullptr);
  raise(signal_number);
}

// While it lives, SIGINT and SIGTERM set the flag that stop_if_asked turns into Stopped, except
// where the signal is ignored (a job started with nohup, or in the background of a script, keeps
// ignoring it). Ending normally with a signal come after the last check, it restores the old
// handling and raises the signal again: the process stops then, as it would have without.
class StopOnSignals {
 public:
  StopOnSignals() {
    for (int k = 0; k < 2; ++k) {
      sigaction(kSignals[k], nullptr, &previous_[k]);
      if (previous_[k].sa_handler == SIG_IGN) continue;
      struct sigaction action {};
      action.sa_handler = on_stop_signal;
      sigemptyset(&action.sa_mask);
      action.sa_flags = SA_RESTART;
      sigaction(kSignals[k], &action, nullptr);
    }
  }
  ~StopOnSignals() {
    const int pending = g_stop_signal.load();
    // Stopping (the Stopped error unwinding to its message and exit status): the handler stays,
    // so that the same stop asked again at once (coreutils `timeout`) does not end the process
    // before it has said so.
    if (pending != 0 && std::uncaught_exceptions() > 0) return;
    for (int k = 0; k < 2; ++k) sigaction(kSignals[k], &previous_[k], nullptr);
    if (pending != 0) raise(pending);
  }
  StopOnSignals(const StopOnSignals&) = delete;
  StopOnSignals& operator=(const StopOnSignals&) = delete;

 private:
  static constexpr int kSignals[2] = {SIGINT, SIGTERM};
  struct sigaction previous_[2]{};
};

// A job stopped by a signal; `what()` says which, and what the job leaves behind where a command
// adds that (see `with_note`).
class Stopped : public std::runtime_error {
 public:
  Stopped(int signal_number, const std::string& message)
      : std::runtime_error(message), signal_number_(signal_number) {}
  explicit Stopped(int signal_number)
      : Stopped(signal_number,
                signal_number == SIGINT
                    ? "interrupted (SIGINT, Ctrl-C)"
                    : "stopped by signal " + std::to_string(signal_number) +
                          (signal_number == SIGTERM ? " (SIGTERM)" : std::string())) {}
  int signal_number() const { return signal_number_; }
  int exit_code() const { return 128 + signal_number_; }
  // The same stop, its message followed by `note` (what the stopped job leaves).
  Stopped with_note(const std::string& note) const {
    return Stopped(signal_number_, std::string(what()) + ": " + note);
  }

 private:
  int signal_number_;
};

// Throws Stopped once SIGINT or SIGTERM has come inside a StopOnSignals scope. Long loops call it
// at each step (Progress's update does).
inline void stop_if_asked() {
  const int signal_number = g_stop_signal.load();
  if (signal_number != 0) throw Stopped(signal_number);
}

}  // namespace pg
