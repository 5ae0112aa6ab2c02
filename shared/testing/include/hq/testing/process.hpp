#pragma once
/// A child process for cross-process tests (hq-onboard, hq-ground, hq-sim --sitl on loopback):
/// posix_spawn with stdout and stderr to one file, stdin from /dev/null; killed and reaped by
/// the destructor if still running, so a failing test leaves no process behind.

#include <string>
#include <sys/types.h>
#include <vector>

namespace hq::testing {

class Process {
 public:
  /// Starts args[0] (a path) with args; started() is false if posix_spawn failed.
  Process(const std::vector<std::string>& args, const std::string& output_path);
  ~Process();
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  [[nodiscard]] bool started() const { return pid_ > 0; }
  [[nodiscard]] pid_t pid() const { return pid_; }
  /// Sends `signal` (e.g. SIGTERM) if the process has not been reaped.
  void signal(int signal);
  /// SIGKILL and reap.
  void kill_now();
  /// Exit code, or -1 if it did not exit within timeout_s or died of a signal.
  int wait_exit(double timeout_s);

 private:
  pid_t pid_ = -1;
  int status_ = 0;
  bool reaped_ = false;
};

}  // namespace hq::testing
