// SPDX-License-Identifier: MIT
// Image output: PNG and JPEG encoding through stb_image_write (to memory, then an atomic file
// write) and the float RGB -> 8-bit conversion used for rendered frames.
#define STBI_WRITE_NO_STDIO
#include <stb_image_write.h>

#include <climits>

#include "../io_util.h"
#include "gs/io/image.h"
#include "gs/platform/file.h"

namespace gs::io {
namespace {

struct EncodeSink {
  std::vector<uint8_t>* out;
  bool failed = false;
};

// Called by stb (C code): must not throw through it.
void encode_write_cb(void* context, void* data, int size) {
  auto* sink = static_cast<EncodeSink*>(context);
  if (sink->failed || size <= 0) return;
  try {
    const auto* p = static_cast<const uint8_t*>(data);
    sink->out->insert(sink->out->end(), p, p + size);
  } catch (...) {
    sink->failed = true;
  }
}

Status check_image(const Image8& image, const char* what) {
  const std::string w(what);
  if (image.width <= 0 || image.height <= 0 || image.channels < 1 || image.channels > 4)
    return invalid_argument(w + ": bad image shape " + std::to_string(image.width) + "x" +
                            std::to_string(image.height) + "x" + std::to_string(image.channels));
  if (image.width > INT_MAX / image.channels)
    return invalid_argument(w + ": image too wide");
  if (image.pixels.size() != size_t(image.width) * size_t(image.height) * size_t(image.channels))
    return invalid_argument(w + ": pixel buffer size does not match width x height x channels");
  return Status::Ok();
}

// Encodes to memory with an image file path's atomic write around it.
template <class Encode>
Status write_encoded(const std::string& path, Encode&& encode) {
  return detail::guarded(path, [&]() -> Status {
    Expected<std::vector<uint8_t>> bytes = encode();
    if (!bytes.ok()) return Status(bytes.status().code(), path + ": " + bytes.status().message());
    return platform::write_file_atomic(path, bytes->data(), bytes->size());
  });
}

}  // namespace

Expected<std::vector<uint8_t>> encode_png(const Image8& image) {
  return detail::guarded("encode_png", [&]() -> Expected<std::vector<uint8_t>> {
    GS_RETURN_IF_ERROR(check_image(image, "encode_png"));
    std::vector<uint8_t> out;
    EncodeSink sink{&out};
    const int ok = stbi_write_png_to_func(encode_write_cb, &sink, image.width, image.height, image.channels,
                                          image.pixels.data(), image.width * image.channels);
    if (!ok || sink.failed) return Status(StatusCode::kInternal, "encode_png: PNG encoder failed");
    return out;
  });
}

Status write_png(const std::string& path, const Image8& image) {
  return write_encoded(path, [&] { return encode_png(image); });
}

Expected<std::vector<uint8_t>> encode_jpeg(const Image8& image, int quality) {
  return detail::guarded("encode_jpeg", [&]() -> Expected<std::vector<uint8_t>> {
    GS_RETURN_IF_ERROR(check_image(image, "encode_jpeg"));
    if (image.channels != 1 && image.channels != 3)
      return invalid_argument("encode_jpeg: JPEG holds 1 or 3 channels, not " + std::to_string(image.channels));
    if (quality < 1 || quality > 100) return invalid_argument("encode_jpeg: quality " + std::to_string(quality) + " outside 1..100");
    std::vector<uint8_t> out;
    EncodeSink sink{&out};
    const int ok = stbi_write_jpg_to_func(encode_write_cb, &sink, image.width, image.height, image.channels,
                                          image.pixels.data(), quality);
    if (!ok || sink.failed) return Status(StatusCode::kInternal, "encode_jpeg: JPEG encoder failed");
    return out;
  });
}

Status write_jpeg(const std::string& path, const Image8& image, int quality) {
  return write_encoded(path, [&] { return encode_jpeg(image, quality); });
}

Image8 image_from_float_rgb(const float* rgb, int width, int height) {
  Image8 img;
  if (rgb == nullptr || width <= 0 || height <= 0) return img;
  try {
    img.pixels.resize(size_t(width) * size_t(height) * 3);
  } catch (...) {
    return Image8{};
  }
  img.width = width;
  img.height = height;
  img.channels = 3;
  for (size_t i = 0; i < img.pixels.size(); ++i) {
    const float x = rgb[i];
    // Written so that NaN lands on 0 (both comparisons are false).
    const float c = x > 0.0f ? (x < 1.0f ? x : 1.0f) : 0.0f;
    img.pixels[i] = uint8_t(c * 255.0f + 0.5f);
  }
  return img;
}

}  // namespace gs::io
