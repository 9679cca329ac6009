// sirad: the camera convention every image of sirad follows (the rasteriser of io/write.h
// and the final gather of render/gather.h), that of pbrt and of Cycles with a square or landscape
// sensor fit to the height: the image plane spans raster x in [0, width] left to right and y in
// [0, height] top to bottom; pixel (i, j) is the square [i, i+1] x [j, j+1] and its centre is
// (i + 0.5, j + 0.5); `vfov_deg` is the field of view across the height, centred on the view
// direction; the frame is right-handed: right = forward x up.
#pragma once
#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <numbers>

#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "scene/scene.h"
#include "util/error.h"

namespace sirad {

struct CameraFrame {
  glm::dvec3 eye, right, up, forward;
  double tan_half = 1.0;  // tan(vfov / 2)
  double aspect = 1.0;    // width / height
  int width = 0, height = 0;

  // The view direction (unit) through raster point (x, y).
  glm::dvec3 direction(double x, double y) const {
    const double nx = 2.0 * x / width - 1.0, ny = 1.0 - 2.0 * y / height;
    return glm::normalize(forward + right * (nx * tan_half * aspect) + up * (ny * tan_half));
  }
  // Raster position of camera-space point (x right, y up, z > 0 along forward).
  std::pair<double, double> raster(double x, double y, double z) const {
    const double nx = x / (z * tan_half * aspect), ny = y / (z * tan_half);
    return {(nx + 1.0) * 0.5 * width, (1.0 - ny) * 0.5 * height};
  }
};

// The frame of `camera` for a width x height image. Throws sirad::Error (`what` first) for an
// empty image, a field of view outside (0, 180) degrees, or eye, look_at and up that define no
// view direction.
inline CameraFrame camera_frame(const Camera& camera, int width, int height, const char* what = "cannot render view") {
  if (width <= 0 || height <= 0) fail("{}: image size {}x{}", what, width, height);
  const glm::dvec3 eye(camera.eye);
  const glm::dvec3 forward_raw = glm::dvec3(camera.look_at) - eye;
  const glm::dvec3 right_raw = glm::cross(forward_raw, glm::dvec3(camera.up));
  if (!(glm::length(forward_raw) > 0.0) || !(glm::length(right_raw) > 0.0) || !std::isfinite(glm::length(right_raw)))
    fail("{}: camera eye, look_at and up do not define a view direction", what);
  if (!(camera.vfov_deg > 0.0f && camera.vfov_deg < 180.0f))
    fail("{}: camera field of view {} is not in (0, 180) degrees", what, camera.vfov_deg);
  CameraFrame f;
  f.eye = eye;
  f.forward = glm::normalize(forward_raw);
  f.right = glm::normalize(right_raw);
  f.up = glm::cross(f.right, f.forward);
  f.tan_half = std::tan(camera.vfov_deg * std::numbers::pi / 360.0);
  f.aspect = static_cast<double>(width) / height;
  f.width = width;
  f.height = height;
  return f;
}

// How far from a scene its camera may stand, in radii of the scene's bounding sphere. At 1e4
// radii a float ray's origin is still placed to 1e-3 of the scene (float's spacing there is
// 1e4 * 1.2e-7 radii), and the scene fills a view of about 0.01 degrees; much farther, rays
// lose the scene to rounding, and Embree refuses (aborts on) origins beyond about 1.8e18.
inline constexpr double kMaxEyeDistanceRadii = 1e4;

// Throws sirad::Error (`what` first) for a camera with a non-finite number or whose eye is more
// than kMaxEyeDistanceRadii radii from the scene's bounding sphere (`centre`, `radius`): a
// camera that renders nothing a float can place, checked where a view meets its scene (the
// scene check of every run, and each final gather).
inline void check_camera_reach(const Camera& camera, const glm::vec3& centre, float radius, const char* what) {
  for (const glm::vec3& v : {camera.eye, camera.look_at, camera.up})
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z) || !std::isfinite(camera.vfov_deg))
      fail("{}: the camera has a number that is not finite", what);
  const double r = std::max(static_cast<double>(radius), 1e-6);
  const double d = glm::length(glm::dvec3(camera.eye) - glm::dvec3(centre));
  if (!(d <= kMaxEyeDistanceRadii * r))
    fail("{}: the camera's eye is {:.3g} from the scene's centre, over {:.0g} times the scene's radius {:.3g}", what, d,
         kMaxEyeDistanceRadii, r);
}

}  // namespace sirad
