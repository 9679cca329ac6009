// sirad tests: reading a PNG back (libpng's simplified API), as 8-bit RGB whatever it holds.
#pragma once
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <png.h>

namespace sirad::test {

// The pixels of the PNG at `path` as RGB bytes, row by row; empty (and a test failure) when
// libpng cannot read it. `format`, if given, gets the file's own format (PNG_FORMAT_*).
inline std::vector<unsigned char> read_png(const std::string& path, int& width, int& height, png_uint_32* format = nullptr) {
  png_image image;
  std::memset(&image, 0, sizeof image);
  image.version = PNG_IMAGE_VERSION;
  if (!png_image_begin_read_from_file(&image, path.c_str())) {
    ADD_FAILURE() << "libpng: " << image.message;
    return {};
  }
  if (format) *format = image.format;
  image.format = PNG_FORMAT_RGB;
  width = static_cast<int>(image.width);
  height = static_cast<int>(image.height);
  std::vector<unsigned char> bytes(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, bytes.data(), 0, nullptr)) {
    ADD_FAILURE() << "libpng: " << image.message;
    return {};
  }
  return bytes;
}

}  // namespace sirad::test
