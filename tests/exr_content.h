// sirad tests: an EXR's content as one string (every channel's pixels, and the sirad.*
// attributes), for comparing the outputs of runs that must agree bit for bit.
#pragma once
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include <OpenEXR/ImfAttribute.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <fmt/format.h>

namespace sirad::test {

// Every channel of an open EXR by name, its pixels row by row as floats.
inline std::map<std::string, std::vector<float>> exr_channels(Imf::InputFile& in) {
  const Imath::Box2i dw = in.header().dataWindow();
  const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
  std::map<std::string, std::vector<float>> channels;
  Imf::FrameBuffer fb;
  for (auto c = in.header().channels().begin(); c != in.header().channels().end(); ++c) {
    auto& v = channels[c.name()];
    v.resize(static_cast<std::size_t>(w) * h);
    fb.insert(c.name(), Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(v.data() - dw.min.x - dw.min.y * w), sizeof(float),
                                   sizeof(float) * w));
  }
  in.setFrameBuffer(fb);
  in.readPixels(dw.min.y, dw.max.y);
  return channels;
}

inline std::map<std::string, std::vector<float>> exr_channels(const std::filesystem::path& path) {
  Imf::InputFile in(path.c_str());
  return exr_channels(in);
}

// An EXR's pixels (every channel, row by row; or only the channels' names without `pixels`)
// and its attributes but the device's description (the machine's), the version, the time and
// the rates, as one string.
inline std::string exr_content(const std::filesystem::path& path, bool pixels = true) {
  Imf::InputFile in(path.c_str());
  const Imath::Box2i dw = in.header().dataWindow();
  std::string out = fmt::format("{}x{}\n", dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1);
  const std::map<std::string, std::vector<float>> channels = exr_channels(in);
  for (const auto& [name, v] : channels)
    out += name + ":" + (pixels ? std::string(reinterpret_cast<const char*>(v.data()), v.size() * 4) : std::string());
  for (auto a = in.header().begin(); a != in.header().end(); ++a) {
    const std::string name = a.name();
    if (name.rfind("sirad.", 0) != 0 || name == "sirad.device" || name == "sirad.version") continue;
    // The run's time and rates (real runs: the clock's) are not part of the result.
    if (name == "sirad.seconds" || name.ends_with("_per_s")) continue;
    // The attribute's value as OpenEXR writes it.
    Imf::Attribute* copy = a.attribute().copy();
    const std::string type = copy->typeName();
    std::string value;
    if (auto* s = dynamic_cast<Imf::TypedAttribute<std::string>*>(copy)) value = s->value();
    else if (auto* i = dynamic_cast<Imf::TypedAttribute<int>*>(copy)) value = std::to_string(i->value());
    else if (auto* d = dynamic_cast<Imf::TypedAttribute<double>*>(copy)) value = fmt::format("{}", d->value());
    else if (auto* f = dynamic_cast<Imf::TypedAttribute<float>*>(copy)) value = fmt::format("{}", f->value());
    else value = "?";
    delete copy;
    out += fmt::format("\n{} {} {}", name, type, value);
  }
  return out;
}

}  // namespace sirad::test
