// SPDX-License-Identifier: MIT
// The image files of a folder, in the order frame sources play them (gs/io/image.h).
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <system_error>

#include "gs/io/image.h"

namespace gs::io {

bool is_image_file_name(const std::string& name) {
  const size_t dot = name.rfind('.');
  if (dot == std::string::npos || dot == 0) return false;  // no extension, or a hidden dotfile
  std::string ext = name.substr(dot + 1);
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  return ext == "png" || ext == "jpg" || ext == "jpeg";
}

Expected<std::vector<std::string>> list_image_files(const std::string& folder) {
  namespace fs = std::filesystem;
  std::vector<std::string> files;
  std::error_code ec;
  for (fs::directory_iterator it(folder, ec), end; !ec && it != end; it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_directory(type_ec)) continue;
    const std::string n = it->path().filename().string();
    if (is_image_file_name(n)) files.push_back(n);
  }
  if (ec) return io_error("cannot list: " + ec.message());
  std::sort(files.begin(), files.end());
  return files;
}

}  // namespace gs::io
