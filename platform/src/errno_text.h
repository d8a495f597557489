// SPDX-License-Identifier: MIT
// The text of an errno value for error messages, shared by platform/'s sources (private header).
#pragma once

#include <string>
#include <system_error>

namespace gs::platform::detail {

inline std::string errno_text(int err) { return std::generic_category().message(err); }

}  // namespace gs::platform::detail
