#include "vision/dt3/directional_distance_transform.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <omp.h>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace mfcd::vision {

void Dt3Params::validate() const {
  if (q <= 0 || q > kMaxChannels) throw std::invalid_argument("DT3: q must be in 1..180");
  if (oriented && q % 2 != 0) throw std::invalid_argument("DT3: oriented channels need an even q");
  if (!(polarityPenalty >= 0)) throw std::invalid_argument("DT3: polarityPenalty must be >= 0 px");
  if (!(lambda >= 0 && lambda <= 30)) throw std::invalid_argument("DT3: lambda must be in [0, 30] px per channel step");
  if (!(maxCost > 0 && maxCost * kCostScale <= 255.0))
    throw std::invalid_argument("DT3: maxCost must be in (0, 31.875] px (one byte at 1/8 px)");
}
int Dt3Params::lambdaUnits() const { return static_cast<int>(std::lround(lambda * kCostScale)); }
int Dt3Params::capUnits() const { return static_cast<int>(std::lround(maxCost * kCostScale)); }
int Dt3Params::polarityPenaltyUnits() const {
  if (polarityPenalty >= maxCost) return capUnits();
  return std::min(capUnits(), static_cast<int>(std::lround(polarityPenalty * kCostScale)));
}

void DirectionalDistanceTransform::compute(const cv::Mat1b& channelMap, const Dt3Params& params) {
  params.validate();
  if (channelMap.empty()) throw std::invalid_argument("DT3: empty channel map");
  params_ = params;
  width_ = channelMap.cols;
  height_ = channelMap.rows;
  q_ = params.q;
  data_.resize(static_cast<size_t>(q_) * width_ * height_);

  const int cap = params.capUnits();
  // Distances beyond maxCost are truncated, so only squared distances < (D)^2 matter.
  const int far = static_cast<int>(std::floor(params.maxCost)) + 1;
  sqrtTable_.resize(static_cast<size_t>(2 * far * far + 1));
  for (size_t d2 = 0; d2 < sqrtTable_.size(); ++d2)
    sqrtTable_[d2] = static_cast<uint8_t>(std::min<long>(cap, std::lround(kCostScale * std::sqrt(double(d2)))));

  // Bucket the edge pixels by channel: a counting sort into one buffer of image size (in scan
  // order within a channel). Per-channel lists would grow whenever a frame brought a channel
  // more pixels than any before it.
  channelStart_.assign(static_cast<size_t>(q_) + 1, 0);
  channelPixels_.resize(static_cast<size_t>(width_) * height_);
  if (scratch_.size() < static_cast<size_t>(omp_get_max_threads()))
    scratch_.resize(static_cast<size_t>(omp_get_max_threads()));
  // Every thread's scratch at its full size now: which thread meets which channel is decided at
  // run time, so growing them on first use would allocate in any later cycle.
  for (Scratch& s : scratch_) {
    s.g.resize(static_cast<size_t>(width_) * height_);
    s.v.resize(static_cast<size_t>(width_));
    s.z.resize(static_cast<size_t>(width_) + 1);
  }
  for (int y = 0; y < height_; ++y) {
    const uint8_t* r = channelMap.ptr<uint8_t>(y);
    for (int x = 0; x < width_; ++x) {
      if (r[x] == kNoChannel) continue;
      if (r[x] >= q_)
        throw std::invalid_argument("DT3: channel map holds channel " + std::to_string(r[x]) +
                                    " but q = " + std::to_string(q_));
      ++channelStart_[r[x] + 1u];
    }
  }
  for (int c = 0; c < q_; ++c) channelStart_[c + 1u] += channelStart_[static_cast<size_t>(c)];
  {
    size_t* next = channelStart_.data();  // advanced per placed pixel, restored below
    for (int y = 0; y < height_; ++y) {
      const uint8_t* r = channelMap.ptr<uint8_t>(y);
      for (int x = 0; x < width_; ++x)
        if (r[x] != kNoChannel) channelPixels_[next[r[x]]++] = y * width_ + x;
    }
    for (int c = q_; c > 0; --c) channelStart_[static_cast<size_t>(c)] = channelStart_[static_cast<size_t>(c) - 1];
    channelStart_[0] = 0;
  }

#pragma omp parallel
  {
    Scratch& scratch = scratch_[static_cast<size_t>(omp_get_thread_num())];
#pragma omp for schedule(dynamic, 1)
    for (int c = 0; c < q_; ++c)
      channelDistance(c,
                      std::span<const int>(channelPixels_.data() + channelStart_[static_cast<size_t>(c)],
                                           channelStart_[c + 1u] - channelStart_[static_cast<size_t>(c)]),
                      scratch);
#pragma omp for schedule(static)
    for (int y = 0; y < height_; ++y) orientationRecursion(y);
  }
}

// Exact Euclidean distance to the channel's pixels, truncated: a column pass of vertical
// distances followed by Felzenszwalb's lower envelope per row, restricted to the rows and columns
// that can be within `far` of a pixel of this channel.
void DirectionalDistanceTransform::channelDistance(int channel, std::span<const int> pixels, Scratch& scratch) {
  std::vector<uint8_t>& g = scratch.g;
  uint8_t* out = data_.data() + static_cast<size_t>(channel) * width_ * height_;
  const int cap = params_.capUnits();
  const int far = static_cast<int>(std::floor(params_.maxCost)) + 1;
  if (pixels.empty()) {
    std::memset(out, cap, static_cast<size_t>(width_) * height_);
    return;
  }
  const int y0 = std::max(0, pixels.front() / width_ - far);
  const int y1 = std::min(height_ - 1, pixels.back() / width_ + far);
  std::memset(out, cap, static_cast<size_t>(y0) * width_);
  std::memset(out + static_cast<size_t>(y1 + 1) * width_, cap, static_cast<size_t>(height_ - 1 - y1) * width_);

  // Column pass over rows y0..y1: g = vertical distance to a pixel of this channel, capped at far.
  g.resize(static_cast<size_t>(width_) * height_);
  std::memset(g.data() + static_cast<size_t>(y0) * width_, far, static_cast<size_t>(y1 - y0 + 1) * width_);
  for (int idx : pixels) g[idx] = 0;
  for (int y = y0 + 1; y <= y1; ++y) {
    uint8_t* cur = g.data() + static_cast<size_t>(y) * width_;
    const uint8_t* prev = cur - width_;
    for (int x = 0; x < width_; ++x) cur[x] = std::min<uint8_t>(cur[x], static_cast<uint8_t>(prev[x] + 1));
  }
  for (int y = y1 - 1; y >= y0; --y) {
    uint8_t* cur = g.data() + static_cast<size_t>(y) * width_;
    const uint8_t* next = cur + width_;
    for (int x = 0; x < width_; ++x) cur[x] = std::min<uint8_t>(cur[x], static_cast<uint8_t>(next[x] + 1));
  }

  // Row pass: lower envelope of the parabolas g(p)^2 + (x - p)^2 over sites with g(p) < far.
  std::vector<int>& v = scratch.v;
  std::vector<float>& z = scratch.z;
  v.resize(static_cast<size_t>(width_));
  z.resize(static_cast<size_t>(width_) + 1);
  const int far2 = far * far;
  for (int y = y0; y <= y1; ++y) {
    const uint8_t* gr = g.data() + static_cast<size_t>(y) * width_;
    uint8_t* o = out + static_cast<size_t>(y) * width_;
    int k = -1, first = -1, last = -1;
    for (int x = 0; x < width_; ++x) {
      if (gr[x] >= far) continue;
      if (first < 0) first = x;
      last = x;
      const float fx = float(gr[x] * gr[x] + x * x);
      float s = 0;
      while (k >= 0) {
        const int p = v[k];
        s = (fx - float(gr[p] * gr[p] + p * p)) / float(2 * (x - p));
        if (s <= z[k])
          --k;
        else
          break;
      }
      ++k;
      v[k] = x;
      z[k] = k == 0 ? -1e30f : s;
      z[k + 1] = 1e30f;
    }
    if (k < 0) {
      std::memset(o, cap, width_);
      continue;
    }
    const int xa = std::max(0, first - far), xb = std::min(width_ - 1, last + far);
    std::memset(o, cap, xa);
    if (xb + 1 < width_) std::memset(o + xb + 1, cap, width_ - 1 - xb);
    int j = 0;
    for (int x = xa; x <= xb; ++x) {
      while (z[j + 1] < float(x)) ++j;
      const int p = v[j], dx = x - p;
      const int d2 = dx * dx + gr[p] * gr[p];
      o[x] = d2 < far2 ? sqrtTable_[d2] : static_cast<uint8_t>(cap);
    }
  }
}

namespace {
// a[i] = min(a[i], b[i] + lambda) with saturation, over one row.
inline void relax(uint8_t* a, const uint8_t* b, int n, uint8_t lambda) {
  int i = 0;
#if defined(__SSE2__)
  const __m128i l = _mm_set1_epi8(static_cast<char>(lambda));
  for (; i + 16 <= n; i += 16) {
    const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + i));
    const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + i));
    _mm_storeu_si128(reinterpret_cast<__m128i*>(a + i), _mm_min_epu8(va, _mm_adds_epu8(vb, l)));
  }
#endif
  for (; i < n; ++i) a[i] = static_cast<uint8_t>(std::min<int>(a[i], b[i] + lambda));
}
}  // namespace

// Eqs. 10-11. A forward sweep of q + q/2 steps reaches every channel from every channel whose
// forward circular distance is <= q/2, and the backward sweep does the same the other way, so
// after both every entry holds the minimum over all channels of EDT + lambda * circular distance.
void DirectionalDistanceTransform::orientationRecursion(int row) {
  const size_t planeSize = static_cast<size_t>(width_) * height_;
  uint8_t* base = data_.data() + static_cast<size_t>(row) * width_;
  const auto lam = static_cast<uint8_t>(std::min(255, params_.lambdaUnits()));
  if (q_ == 1) return;
  const int steps = q_ + q_ / 2;
  for (int s = 0; s < steps; ++s) {
    const int c = (1 + s) % q_, p = (c + q_ - 1) % q_;
    relax(base + c * planeSize, base + p * planeSize, width_, lam);
  }
  for (int s = 0; s < steps; ++s) {
    const int c = ((q_ - 2 - s) % q_ + q_) % q_, n = (c + 1) % q_;
    relax(base + c * planeSize, base + n * planeSize, width_, lam);
  }
  // The polarity penalty: every entry now holds min over edges of distance + lambda * oriented
  // channel distance; the same with the edges reversed is the reverse channel's entry, so
  // relaxing each pair both ways gives min(lambda * d, lambda * d(reverse) + penalty). (The second
  // relax sees the first's result: min(b, min(a, b + p) + p) = min(b, a + p), saturation included.)
  const int penalty = params_.polarityPenaltyUnits();
  if (params_.oriented && penalty < params_.capUnits())
    for (int c = 0; c < q_ / 2; ++c) {
      uint8_t* forward = base + c * planeSize;
      uint8_t* reverse = base + (c + q_ / 2) * planeSize;
      relax(forward, reverse, width_, static_cast<uint8_t>(penalty));
      relax(reverse, forward, width_, static_cast<uint8_t>(penalty));
    }
}

}  // namespace mfcd::vision
