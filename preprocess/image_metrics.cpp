// Image metrics beyond compareImages' per-pixel differences: the structural similarity.
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "strata/strata.h"

namespace strata {

namespace {

constexpr int kRadius = (kSsimMinSize - 1) / 2;
constexpr double kSigma = 1.5;
constexpr double kC1 = (0.01 * 255.0) * (0.01 * 255.0), kC2 = (0.03 * 255.0) * (0.03 * 255.0);

// Index i of a row of n reflected at its ends (d c b a | a b c d | d c b a).
int reflect(int i, int n) {
  while (i < 0 || i >= n) i = i < 0 ? -i - 1 : 2 * n - i - 1;
  return i;
}

// The Gaussian-weighted mean of `v` (w x h) around every pixel: rows, then columns.
std::vector<double> gaussianMean(const std::vector<double>& v, int w, int h,
                                 const std::array<double, kSsimMinSize>& k) {
  std::vector<double> rows(v.size()), out(v.size());
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0.0;
      for (int i = -kRadius; i <= kRadius; ++i)
        s += k[size_t(i + kRadius)] * v[size_t(y) * size_t(w) + size_t(reflect(x + i, w))];
      rows[size_t(y) * size_t(w) + size_t(x)] = s;
    }
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      double s = 0.0;
      for (int i = -kRadius; i <= kRadius; ++i)
        s += k[size_t(i + kRadius)] * rows[size_t(reflect(y + i, h)) * size_t(w) + size_t(x)];
      out[size_t(y) * size_t(w) + size_t(x)] = s;
    }
  return out;
}

}  // namespace

double structuralSimilarity(const Image& a, const Image& b, std::vector<float>* map) {
  if (a.width != b.width || a.height != b.height)
    throw Error("SSIM: the images differ in size (" + std::to_string(a.width) + "x" +
                std::to_string(a.height) + " and " + std::to_string(b.width) + "x" +
                std::to_string(b.height) + ")");
  const int w = a.width, h = a.height;
  if (w < kSsimMinSize || h < kSsimMinSize)
    throw Error("SSIM: the images are " + std::to_string(w) + "x" + std::to_string(h) +
                "; it needs at least " + std::to_string(kSsimMinSize) + " pixels a side");
  std::array<double, kSsimMinSize> k{};
  double total = 0.0;
  for (int i = -kRadius; i <= kRadius; ++i)
    total += k[size_t(i + kRadius)] = std::exp(-double(i * i) / (2.0 * kSigma * kSigma));
  for (double& v : k) v /= total;

  const size_t n = size_t(w) * size_t(h);
  std::vector<double> per_pixel(n, 0.0), x(n), y(n), xx(n), yy(n), xy(n);
  for (int c = 0; c < 3; ++c) {
    for (size_t i = 0; i < n; ++i) {
      x[i] = a.rgba[4 * i + size_t(c)];
      y[i] = b.rgba[4 * i + size_t(c)];
      xx[i] = x[i] * x[i];
      yy[i] = y[i] * y[i];
      xy[i] = x[i] * y[i];
    }
    const std::vector<double> mx = gaussianMean(x, w, h, k), my = gaussianMean(y, w, h, k),
                              mxx = gaussianMean(xx, w, h, k), myy = gaussianMean(yy, w, h, k),
                              mxy = gaussianMean(xy, w, h, k);
    for (size_t i = 0; i < n; ++i) {
      const double vx = mxx[i] - mx[i] * mx[i], vy = myy[i] - my[i] * my[i],
                   cxy = mxy[i] - mx[i] * my[i];
      per_pixel[i] += ((2.0 * mx[i] * my[i] + kC1) * (2.0 * cxy + kC2)) /
                      ((mx[i] * mx[i] + my[i] * my[i] + kC1) * (vx + vy + kC2)) / 3.0;
    }
  }
  double sum = 0.0;
  for (int py = kRadius; py < h - kRadius; ++py)
    for (int px = kRadius; px < w - kRadius; ++px)
      sum += per_pixel[size_t(py) * size_t(w) + size_t(px)];
  if (map) map->assign(per_pixel.begin(), per_pixel.end());
  return sum / (double(w - 2 * kRadius) * double(h - 2 * kRadius));
}

}  // namespace strata
