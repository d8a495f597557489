// SPDX-License-Identifier: MIT
// gs::Span<T>: a pointer + element count, the type public orchestration APIs take (TFLM-style
// span for C++17). Kernels below the orchestration layer take raw pointers and sizes instead.
#pragma once

#include <cstddef>

namespace gs {

template <class T>
class Span {
 public:
  constexpr Span() = default;
  constexpr Span(T* data, size_t size) : data_(data), size_(size) {}
  template <class Container>
  constexpr Span(Container& c) : data_(c.data()), size_(c.size()) {}  // NOLINT: implicit like std::span
  constexpr T* data() const { return data_; }
  constexpr size_t size() const { return size_; }
  constexpr bool empty() const { return size_ == 0; }
  constexpr T& operator[](size_t i) const { return data_[i]; }
  constexpr T* begin() const { return data_; }
  constexpr T* end() const { return data_ + size_; }

 private:
  T* data_ = nullptr;
  size_t size_ = 0;
};

}  // namespace gs
