// sirad tests: closed forms the final gather and the baked lightmaps are checked against.
#pragma once
#include <cmath>
#include <numbers>

namespace sirad::test {

// Reflected radiance at (px, py, 0) on a floor of reflectance rho under a square emitter of
// radiance E, side [x0, x1] x [y0, y1] at height c facing down: rho E F, F the form factor from
// the point to the rectangle (the corner formula, odd in each offset, by superposition).
inline double floor_radiance(double px, double py, double x0, double x1, double y0, double y1, double c, double rho, double E) {
  auto f = [c](double u, double v) {
    const double su = std::sqrt(c * c + u * u), sv = std::sqrt(c * c + v * v);
    return (u / su * std::atan(v / su) + v / sv * std::atan(u / sv)) / (2.0 * std::numbers::pi);
  };
  const double F = f(x1 - px, y1 - py) - f(x0 - px, y1 - py) - f(x1 - px, y0 - py) + f(x0 - px, y0 - py);
  return rho * E * F;
}

}  // namespace sirad::test
