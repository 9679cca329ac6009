// sirad bench: an EXR's R, G, B (or one layer's) as an Image, one channel alone, and the
// luminance they are compared by: what the benches that compare with Cycles share
// (image_bench.cpp, lightmap_bench.cpp).
#pragma once
#include <cstddef>
#include <string>
#include <vector>

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>

#include "io/write.h"
#include "util/error.h"

namespace sirad::bench {

// Rec. 709 luminance of linear RGB.
inline double luminance(const glm::vec3& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

// The RGB of `layer` (LAYER.R, ...); with no layer, the plain R, G, B or else a multilayer EXR's
// combined image (render_obj.py ... passes writes ViewLayer.Combined.R, ...).
inline Image read_rgb(const std::string& path, std::string layer = "") {
  Imf::InputFile in(path.c_str());
  if (layer.empty() && !in.header().channels().findChannel("R") && in.header().channels().findChannel("ViewLayer.Combined.R"))
    layer = "ViewLayer.Combined";
  const Imath::Box2i dw = in.header().dataWindow();
  Image image;
  image.width = dw.max.x - dw.min.x + 1;
  image.height = dw.max.y - dw.min.y + 1;
  image.pixels.assign(static_cast<std::size_t>(image.width) * image.height, glm::vec3(0.0f));
  char* base = reinterpret_cast<char*>(image.pixels.data()) - (dw.min.x + static_cast<std::ptrdiff_t>(dw.min.y) * image.width) * sizeof(glm::vec3);
  Imf::FrameBuffer fb;
  for (int c = 0; c < 3; ++c) {
    const std::string name = (layer.empty() ? "" : layer + ".") + std::string(1, "RGB"[c]);
    if (!in.header().channels().findChannel(name)) fail("{}: no channel {}", path, name);  // OpenEXR would read zeros
    fb.insert(name, Imf::Slice(Imf::FLOAT, base + c * sizeof(float), sizeof(glm::vec3), sizeof(glm::vec3) * image.width));
  }
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return image;
}

// One channel (`name`, as the file spells it), row by row; fails if the file has none.
inline std::vector<float> read_channel(const std::string& path, const std::string& name, int& width, int& height) {
  Imf::InputFile in(path.c_str());
  if (!in.header().channels().findChannel(name)) fail("{}: no channel {}", path, name);
  const Imath::Box2i dw = in.header().dataWindow();
  width = dw.max.x - dw.min.x + 1;
  height = dw.max.y - dw.min.y + 1;
  std::vector<float> out(static_cast<std::size_t>(width) * height, 0.0f);
  char* base = reinterpret_cast<char*>(out.data()) - (dw.min.x + static_cast<std::ptrdiff_t>(dw.min.y) * width) * sizeof(float);
  Imf::FrameBuffer fb;
  fb.insert(name, Imf::Slice(Imf::FLOAT, base, sizeof(float), sizeof(float) * width));
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return out;
}

}  // namespace sirad::bench
