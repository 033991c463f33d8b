#pragma once
// Ctrl-C (SIGINT) and SIGTERM stop a long job at its next step (a frame, a batch) instead of
// killing it where it stands: the error unwinds, so an output folder the run made and left empty
// goes again, no temporary file stays, and run_cli exits with 128 + the signal's number, as a
// shell reports a job it stopped. A second signal ends the process at once.
#include <signal.h>

#include <csignal>
#include <stdexcept>
#include <string>

namespace pg {

inline volatile std::sig_atomic_t g_stop_signal = 0;

inline void on_stop_signal(int signal_number) { g_stop_signal = signal_number; }

// Installs the handler for SIGINT and SIGTERM, except where the signal is ignored (a job started
// with nohup, or in the background of a script, keeps ignoring it).
inline void stop_on_signals() {
  for (const int signal_number : {SIGINT, SIGTERM}) {
    struct sigaction current {};
    if (sigaction(signal_number, nullptr, &current) != 0 || current.sa_handler == SIG_IGN) continue;
    struct sigaction action {};
    action.sa_handler = on_stop_signal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART | SA_RESETHAND;  // one-shot: the second signal acts as unhandled
    sigaction(signal_number, &action, nullptr);
  }
}

// A job stopped by a signal; `what()` says which, and what the job leaves behind where a command
// adds that (see `with_note`).
class Stopped : public std::runtime_error {
 public:
  Stopped(int signal_number, const std::string& message)
      : std::runtime_error(message), signal_number_(signal_number) {}
  explicit Stopped(int signal_number)
      : Stopped(signal_number, signal_number == SIGINT ? "interrupted (SIGINT, Ctrl-C)"
                                                       : "stopped by signal " +
                                                             std::to_string(signal_number) +
                                                             (signal_number == SIGTERM
                                                                  ? " (SIGTERM)"
                                                                  : std::string())) {}
  int signal_number() const { return signal_number_; }
  int exit_code() const { return 128 + signal_number_; }
  // The same stop, its message followed by `note` (what the stopped job leaves).
  Stopped with_note(const std::string& note) const {
    return Stopped(signal_number_, std::string(what()) + ": " + note);
  }

 private:
  int signal_number_;
};

// Throws Stopped once SIGINT or SIGTERM has come. Long loops call it at each step (Progress's
// update does).
inline void stop_if_asked() {
  if (g_stop_signal != 0) throw Stopped(g_stop_signal);
}

}  // namespace pg
