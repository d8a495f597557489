// SPDX-License-Identifier: MIT
// Names from data joined below a folder without escaping it (gs/platform/path.h).
#include "gs/platform/path.h"

#include <filesystem>
#include <iterator>
#include <system_error>

namespace gs::platform {
namespace {

namespace fs = std::filesystem;

// The path with existing symlinks resolved; the non-existing tail is normalised lexically.
fs::path resolved(const std::string& p) {
  std::error_code ec;
  fs::path abs = fs::absolute(p, ec);
  if (ec) abs = fs::path(p);
  fs::path r = fs::weakly_canonical(abs, ec);
  return ec ? abs.lexically_normal() : r.lexically_normal();
}

bool below(const fs::path& path, const fs::path& folder) {
  auto f = folder.begin(), p = path.begin();
  for (; f != folder.end(); ++f, ++p) {
    if (f->empty() && std::next(f) == folder.end()) break;  // "a/b/" ends in an empty element
    if (p == path.end() || *p != *f) return false;
  }
  return true;
}

}  // namespace

std::string relative_name_problem(const std::string& name) {
  if (name.empty()) return "it is empty";
  if (name.find('\0') != std::string::npos) return "it contains a NUL byte";
  if (name.front() == '/') return "it is an absolute path";
  size_t start = 0;
  for (;;) {
    const size_t slash = name.find('/', start);
    const std::string part = name.substr(start, slash == std::string::npos ? std::string::npos : slash - start);
    if (part == "..") return "it has a '..' component";
    if (slash == std::string::npos) break;
    start = slash + 1;
  }
  return "";
}

Expected<std::string> join_inside(const std::string& folder, const std::string& name) {
  if (std::string why = relative_name_problem(name); !why.empty())
    return invalid_argument("the name '" + name + "' cannot be used below " + folder + ": " + why);
  const std::string joined = (fs::path(folder) / name).string();
  if (!path_is_inside(joined, folder))
    return invalid_argument("the name '" + name + "' leads outside " + folder + " through a symbolic link (" +
                            resolved(joined).string() + ")");
  return joined;
}

bool path_is_inside(const std::string& path, const std::string& folder) {
  return below(resolved(path), resolved(folder));
}

}  // namespace gs::platform
