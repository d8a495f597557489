// SPDX-License-Identifier: MIT
// `hbgs bench`: runs the bench_render benchmark built next to this program
// (<bin>/../bench/bench_render), passing the remaining arguments through unchanged.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "common.h"
#include "gs/platform/file.h"

namespace hbgs::cli {
namespace {

// Folder of the running executable, from /proc/self/exe (Linux); "" if unreadable.
// TODO(platform): move into gs/platform as executable_path() if another tool needs it.
std::string executable_dir() {
  std::vector<char> buf(4096);
  const ssize_t n = ::readlink("/proc/self/exe", buf.data(), buf.size() - 1);
  if (n <= 0) return "";
  const std::string path(buf.data(), size_t(n));
  const size_t slash = path.rfind('/');
  return slash == std::string::npos ? std::string(".") : path.substr(0, slash);
}

}  // namespace

int run_bench(const std::vector<std::string>& pass_through) {
  const std::string dir = executable_dir();
  if (dir.empty()) return fail("bench", std::string("cannot locate the hbgs executable: ") + std::strerror(errno));
  const std::string exe = dir + "/../bench/bench_render";
  if (!gs::platform::file_exists(exe) || gs::platform::is_directory(exe))
    return fail("bench", exe + " not found: this build has GS_BUILD_BENCH=OFF (reconfigure with "
                               "-DGS_BUILD_BENCH=ON and build the bench_render target)");

  std::vector<char*> argv;
  std::string arg0 = exe;
  argv.push_back(arg0.data());
  std::vector<std::string> args = pass_through;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(nullptr);
  ::execv(exe.c_str(), argv.data());  // returns only on failure
  return fail("bench", "cannot run " + exe + ": " + std::strerror(errno));
}

bool bench_passes_through(int argc, char** argv) {
  if (argc < 2 || std::strcmp(argv[1], "bench") != 0) return false;
  const bool only_help = argc == 3 && (std::strcmp(argv[2], "-h") == 0 || std::strcmp(argv[2], "--help") == 0);
  return !only_help;
}

// Registered for `hbgs --help` and `hbgs bench --help`; main() hands every other `hbgs bench ...`
// to run_bench before CLI11 sees it, because CLI11 would interpret options meant for bench_render.
Command add_bench_command(CLI::App& parent) {
  CLI::App* sub = parent.add_subcommand("bench", "Run the bench_render benchmark with the given arguments");
  sub->allow_extras();
  sub->footer(
      "All arguments after `bench` go to bench_render unchanged (a leading `--` is dropped).\n"
      "Example: hbgs bench -- --help   (bench_render's own options)");
  return {sub, [sub] { return run_bench(sub->remaining()); }};
}

}  // namespace hbgs::cli
