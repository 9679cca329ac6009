// sirad tests: scenes made of quads by hand (the gather's and the camera's tests).
#pragma once
#include <cstdint>

#include <fmt/format.h>
#include <glm/vec3.hpp>

#include "scene/scene.h"

namespace sirad::test {

// A scene of quads, each two triangles (a b c) and (a c d), counter-clockwise seen from the front.
struct QuadScene {
  Scene scene = [] {
    Scene s;
    s.name = "quads";
    s.objects = {"quads"};
    return s;
  }();
  uint32_t material(glm::vec3 rho, glm::vec3 emission) {
    scene.materials.push_back({fmt::format("m{}", scene.materials.size()), rho, emission});
    return static_cast<uint32_t>(scene.materials.size() - 1);
  }
  void quad(glm::vec3 a, glm::vec3 b, glm::vec3 c, glm::vec3 d, uint32_t m) {
    scene.triangles.push_back({{a, b, c}, m});
    scene.triangles.push_back({{a, c, d}, m});
  }
};

}  // namespace sirad::test
