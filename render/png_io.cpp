#include <png.h>

#include <cstdio>
#include <string>

#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "render/image.h"

namespace incise {
namespace {

// libpng reports through these instead of printing; the message ends up in the Error.
void on_error(png_structp png, png_const_charp msg) {
  *static_cast<std::string*>(png_get_error_ptr(png)) = msg;
  png_longjmp(png, 1);
}
void on_warning(png_structp, png_const_charp) {}

struct File {
  std::FILE* f;
  ~File() {
    if (f) std::fclose(f);
  }
};

}  // namespace

void write_png(const Image& img, const std::string& path) {
  if (img.width <= 0 || img.height <= 0 || img.rgb.size() != 3u * img.width * img.height)
    throw Error(path + ": cannot write an empty or inconsistent image");
  // Encoded in memory, then written atomically (engine/util/file_io.h): a
  // failed write leaves neither a partial image nor a temporary file.
  std::string bytes;
  std::string why;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &why, on_error, on_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw Error(path + ": libpng could not start");
  }
  std::vector<png_bytep> rows(img.height);
  for (int y = 0; y < img.height; ++y)
    rows[y] = const_cast<png_bytep>(img.rgb.data() + 3 * static_cast<size_t>(y) * img.width);
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    throw Error(path + ": libpng write failed: " + why);
  }
  png_set_write_fn(
      png, &bytes,
      [](png_structp p, png_bytep data, png_size_t n) {
        static_cast<std::string*>(png_get_io_ptr(p))->append(reinterpret_cast<const char*>(data), n);
      },
      [](png_structp) {});
  png_set_compression_level(png, 3);  // frames are many; speed over the last few percent of size
  png_set_IHDR(png, info, img.width, img.height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_set_rows(png, info, rows.data());
  png_write_png(png, info, PNG_TRANSFORM_IDENTITY, nullptr);
  png_destroy_write_struct(&png, &info);
  write_file_atomic(path, bytes);
}

Image read_png(const std::string& path) {
  File file{std::fopen(path.c_str(), "rb")};
  if (!file.f) throw Error(path + ": cannot open PNG");
  std::string why;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &why, on_error, on_warning);
  png_infop info = png ? png_create_info_struct(png) : nullptr;
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw Error(path + ": libpng could not start");
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    throw Error(path + ": not a readable PNG (" + why + ")");
  }
  png_init_io(png, file.f);
  png_read_png(png, info, PNG_TRANSFORM_STRIP_16 | PNG_TRANSFORM_PACKING | PNG_TRANSFORM_EXPAND, nullptr);
  Image img;
  img.width = static_cast<int>(png_get_image_width(png, info));
  img.height = static_cast<int>(png_get_image_height(png, info));
  const int channels = png_get_channels(png, info);
  png_bytepp rows = png_get_rows(png, info);
  const bool ok = channels == 3 || channels == 4;
  if (ok) {
    img.rgb.resize(3u * img.width * img.height);
    for (int y = 0; y < img.height; ++y)
      for (int x = 0; x < img.width; ++x)
        for (int c = 0; c < 3; ++c) img.rgb[3 * (static_cast<size_t>(y) * img.width + x) + c] = rows[y][channels * x + c];
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (!ok) throw Error(path + ": PNG must be RGB or RGBA, has " + std::to_string(channels) + " channel(s)");
  return img;
}

}  // namespace incise
