#pragma once
// What a benchmark report says about the machine it was measured on.
#include <ctime>
#include <fstream>
#include <string>
#include <thread>

namespace pg {

inline std::string cpu_model() {
  std::ifstream in("/proc/cpuinfo");
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("model name", 0) == 0) return line.substr(line.find(':') + 2);
  }
  return "unknown CPU";
}

inline std::string load_average() {
  std::ifstream in("/proc/loadavg");
  std::string one, five, fifteen;
  in >> one >> five >> fifteen;
  return in ? one + " " + five + " " + fifteen : "unknown";
}

inline std::string utc_now() {
  const std::time_t now = std::time(nullptr);
  char text[64];
  std::strftime(text, sizeof(text), "%Y-%m-%d %H:%M UTC", std::gmtime(&now));
  return text;
}

// "Machine: <cpu>, N logical CPUs (nproc), load average a b c at the start"
inline std::string machine_line() {
  return "Machine: " + cpu_model() + ", " + std::to_string(std::thread::hardware_concurrency()) +
         " logical CPUs (nproc), load average " + load_average() + " at the start";
}

}  // namespace pg
