// SPDX-License-Identifier: MIT
// Helpers of the tests that drive the hbgs program: run a command line quietly (logged in the test's
// output), and a fresh folder under the test's temporary root.
#pragma once

#include <doctest/doctest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

namespace gs::test {

// Runs `command` through the shell with its output discarded; returns std::system's status.
inline int run(const std::string& command) {
  MESSAGE(command);
  return std::system((command + " > /dev/null 2>&1").c_str());
}

// root/name, emptied and created.
inline std::filesystem::path fresh_dir(const std::filesystem::path& root, const std::string& name) {
  const std::filesystem::path dir = root / name;
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir);
  return dir;
}

}  // namespace gs::test
