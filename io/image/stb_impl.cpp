// SPDX-License-Identifier: MIT
// The single translation unit that compiles stb_image (PNG + JPEG decode from memory only) and
// stb_image_write (PNG encode to a callback). Nothing in hbgs lets stb open files itself. Compiled
// with -fwrapv (io/CMakeLists.txt): stb's JPEG DC arithmetic overflows int on corrupt streams.
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STBI_NO_STDIO
#define STBI_WRITE_NO_STDIO
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG
#include <stb_image.h>
#include <stb_image_write.h>
