// SPDX-License-Identifier: MIT
// Status and Expected<T>: how hbgs reports errors without exceptions. Validation happens at
// load/plan time and returns a Status with a message that names the file, record and problem;
// hot loops only use GS_DCHECK (compiled out in release builds).
#pragma once

#include <cassert>
#include <string>
#include <utility>

namespace gs {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,   // caller passed something out of contract (NaN, wrong size, bad flag)
  kCapacityExceeded,  // a planned capacity (Gaussians, tile intersections, arena bytes) was too small
  kIoError,           // the OS refused (open, read, write, rename)
  kParseError,        // a file's contents are malformed (truncated, bad magic, wrong counts)
  kUnsupported,       // well-formed but not something hbgs handles (camera model, PLY property)
  kInternal,
  kNumerical,         // a computation kept producing NaN or infinity (training diverged)
};

const char* status_code_name(StatusCode code);

class Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}
  static Status Ok() { return Status(); }

  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "<code name>: <message>", for printing.
  std::string to_string() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status invalid_argument(std::string m) { return Status(StatusCode::kInvalidArgument, std::move(m)); }
inline Status parse_error(std::string m) { return Status(StatusCode::kParseError, std::move(m)); }
inline Status io_error(std::string m) { return Status(StatusCode::kIoError, std::move(m)); }
inline Status unsupported(std::string m) { return Status(StatusCode::kUnsupported, std::move(m)); }
inline Status capacity_exceeded(std::string m) { return Status(StatusCode::kCapacityExceeded, std::move(m)); }
inline Status numerical_error(std::string m) { return Status(StatusCode::kNumerical, std::move(m)); }

// Either a value or an error Status. Minimal C++17 stand-in for std::expected.
template <class T>
class Expected {
 public:
  Expected(T value) : value_(std::move(value)), has_value_(true) {}  // NOLINT: implicit by design
  Expected(Status status) : status_(std::move(status)), has_value_(false) {  // NOLINT
    assert(!status_.ok() && "Expected<T> built from an OK status");
  }
  bool ok() const { return has_value_; }
  explicit operator bool() const { return has_value_; }
  const Status& status() const { return status_; }
  T& value() & { assert(has_value_); return value_; }
  const T& value() const& { assert(has_value_); return value_; }
  T&& value() && { assert(has_value_); return std::move(value_); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() { return value(); }
  const T& operator*() const { return value(); }

 private:
  T value_{};
  Status status_;
  bool has_value_ = false;
};

}  // namespace gs

#define GS_RETURN_IF_ERROR(expr)                 \
  do {                                           \
    ::gs::Status gs_status_ = (expr);            \
    if (!gs_status_.ok()) return gs_status_;     \
  } while (0)

#ifdef NDEBUG
#define GS_DCHECK(cond) ((void)0)
#else
#define GS_DCHECK(cond) assert(cond)
#endif
