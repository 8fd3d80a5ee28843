#pragma once
// A 2D image, row-major, row 0 the top row; pixel (u, v) = (column, row).
#include <cstddef>
#include <cstdint>
#include <vector>

namespace fluoro {

template <class T>
struct ImageT {
  int width = 0;
  int height = 0;
  std::vector<T> pixels;

  ImageT() = default;
  ImageT(int w, int h, T fill = T{}) : width(w), height(h), pixels(size_t(w) * size_t(h), fill) {}
  T at(int u, int v) const { return pixels[size_t(v) * size_t(width) + size_t(u)]; }
  T& at(int u, int v) { return pixels[size_t(v) * size_t(width) + size_t(u)]; }
  bool empty() const { return pixels.empty(); }
};

using Image = ImageT<float>;
using ImageU16 = ImageT<uint16_t>;
using ImageU8 = ImageT<uint8_t>;

}  // namespace fluoro
