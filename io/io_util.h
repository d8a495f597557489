// SPDX-License-Identifier: MIT
// Private helpers shared by the gs_io sources: path joining, the byte access of gs/bytes.h, and the
// exception-to-Status guard used at every public entry point (IO code may throw internally, e.g.
// std::bad_alloc, but never past the API).
#pragma once

#include <cstdint>
#include <cstring>
#include <exception>
#include <string>
#include <utility>
#include <vector>

#include "gs/bytes.h"
#include "gs/status.h"

namespace gs::io::detail {

inline std::string join_path(const std::string& a, const std::string& b) {
  if (a.empty()) return b;
  if (a.back() == '/') return a + b;
  return a + "/" + b;
}

// Runs f() and turns any escaping exception into a kInternal Status naming `what`.
// F returns Status or Expected<T>; both are constructible from a Status.
template <class F>
auto guarded(const std::string& what, F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const std::bad_alloc&) {
    return Status(StatusCode::kInternal, what + ": out of memory");
  } catch (const std::exception& e) {
    return Status(StatusCode::kInternal, what + ": " + e.what());
  }
}

// Byte access lives in base (gs/bytes.h) for every layer; io's sources use it unqualified.
using bytes::append_f32;
using bytes::append_f64;
using bytes::append_le;
using bytes::append_u32;
using bytes::append_u64;
using bytes::load_f32;
using bytes::load_f64;
using bytes::load_le;
using bytes::load_u32;
using bytes::load_u64;

}  // namespace gs::io::detail
