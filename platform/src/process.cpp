// SPDX-License-Identifier: MIT
// fork/exec with a pipe for the merged output. The child gets stdin from /dev/null so a program
// that prompts cannot hang an ingest run, and the exec failure is reported back through a
// close-on-exec pipe so "not found" is an error rather than exit code 127.
#include "gs/platform/process.h"

#include <fcntl.h>
#include <poll.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "gs/platform/clock.h"
#include "errno_text.h"

namespace gs::platform {
namespace {

using detail::errno_text;

bool is_executable_file(const std::string& path) {
  struct stat st;
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

}  // namespace

std::string find_program(const std::string& program) {
  if (program.empty()) return {};
  if (program.find('/') != std::string::npos) return is_executable_file(program) ? program : std::string();
  const char* path = std::getenv("PATH");
  std::string dirs = path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin";
  size_t start = 0;
  while (start <= dirs.size()) {
    size_t end = dirs.find(':', start);
    if (end == std::string::npos) end = dirs.size();
    const std::string dir = end > start ? dirs.substr(start, end - start) : ".";
    const std::string candidate = dir + "/" + program;
    if (is_executable_file(candidate)) return candidate;
    start = end + 1;
  }
  return {};
}

Expected<ProcessResult> run_process(const std::vector<std::string>& argv, const std::string& log_path,
                                    const std::function<void(const std::string&)>& on_line) {
  if (argv.empty()) return invalid_argument("run_process: empty command");
  const std::string exe = find_program(argv[0]);
  if (exe.empty()) return io_error("cannot run '" + argv[0] + "': not found on PATH");

  FILE* log = nullptr;
  if (!log_path.empty()) {
    log = std::fopen(log_path.c_str(), "ab");
    if (log == nullptr) return io_error("cannot open log '" + log_path + "': " + errno_text(errno));
    std::string line = "$";
    for (const std::string& a : argv) line += " " + a;
    std::fprintf(log, "%s\n", line.c_str());
  }
  auto close_log = [&] {
    if (log != nullptr) std::fclose(log);
    log = nullptr;
  };

  int out_pipe[2], err_pipe[2];
  if (::pipe2(out_pipe, O_CLOEXEC) != 0 || ::pipe2(err_pipe, O_CLOEXEC) != 0) {
    close_log();
    return io_error("pipe: " + errno_text(errno));
  }
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);

  const double t0 = now_seconds();
  const pid_t pid = ::fork();
  if (pid < 0) {
    close_log();
    return io_error("fork: " + errno_text(errno));
  }
  if (pid == 0) {
    const int devnull = ::open("/dev/null", O_RDONLY);
    if (devnull >= 0) ::dup2(devnull, 0);
    ::dup2(out_pipe[1], 1);
    ::dup2(out_pipe[1], 2);
    ::execv(exe.c_str(), args.data());
    const int err = errno;
    ssize_t ignored = ::write(err_pipe[1], &err, sizeof err);
    (void)ignored;
    ::_exit(127);
  }
  ::close(out_pipe[1]);
  ::close(err_pipe[1]);
  int exec_errno = 0;
  const ssize_t got = ::read(err_pipe[0], &exec_errno, sizeof exec_errno);
  ::close(err_pipe[0]);

  std::string pending;
  char buf[4096];
  for (;;) {
    const ssize_t n = ::read(out_pipe[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    if (log != nullptr) std::fwrite(buf, 1, size_t(n), log);
    pending.append(buf, size_t(n));
    size_t pos;
    while ((pos = pending.find_first_of("\r\n")) != std::string::npos) {
      if (pos > 0 && on_line) on_line(pending.substr(0, pos));
      pending.erase(0, pos + 1);
    }
  }
  if (!pending.empty() && on_line) on_line(pending);
  ::close(out_pipe[0]);

  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  close_log();
  if (got == sizeof exec_errno) return io_error("cannot run '" + exe + "': " + errno_text(exec_errno));
  ProcessResult r;
  r.seconds = now_seconds() - t0;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

}  // namespace gs::platform
