#pragma once
// An 8-bit RGB image and its PNG form (libpng).
#include <string>
#include <vector>

namespace incise {

struct Image {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;  // (height, width, 3), top row first
  const unsigned char* at(int x, int y) const { return &rgb[3 * (static_cast<size_t>(y) * width + x)]; }
};

// Written to a temporary file and renamed (no half-written frame). Throws incise::Error.
void write_png(const Image& image, const std::string& path);
// Reads 8-bit RGB or RGBA (alpha dropped); throws incise::Error naming the file.
Image read_png(const std::string& path);

}  // namespace incise
