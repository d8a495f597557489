// SPDX-License-Identifier: MIT
// Paths built from data (image names from a dataset, names in a run folder): a name read from a file
// must never take an output outside the folder it is meant for. A downloaded dataset naming an image
// "../../x.png" must not make a render overwrite x.png two folders up.
#pragma once

#include <string>

#include "gs/status.h"

namespace gs::platform {

// Why `name` cannot be used as a relative name below a folder: empty, a NUL byte, absolute, or a
// ".." component; "" when it can. Sub-folders ("cam1/0001.png") are fine.
std::string relative_name_problem(const std::string& name);

// folder/name, refused with a message naming both when name has a relative_name_problem or when an
// existing symbolic link below folder takes the result outside it.
Expected<std::string> join_inside(const std::string& folder, const std::string& name);

// True when path is folder itself or lies below it, comparing the paths with every existing
// symbolic link resolved (paths that do not exist yet are compared lexically past the last
// existing folder).
bool path_is_inside(const std::string& path, const std::string& folder);

}  // namespace gs::platform
