#pragma once
// The camera sensor of a simulated capture: linear light in, 8-bit images out.

#include "vision/render/mfc_renderer.hpp"

#include <cstdint>

namespace mfcd::vision {

// out.frames from out.flash_linear and out.ambient_linear (DN): with `noise` enabled, shot noise
// (variance proportional to the signal) plus read noise, drawn from a cv::RNG seeded with `seed`
// (one draw per pixel of each image, in order: every capture is reproducible); then rounded and
// clipped to 8 bits. `scratch` holds the draws; it is reallocated only when the size changes,
// and nothing else is allocated once out.frames has its size.
void capture_frames(const SensorNoise& noise, uint64_t seed, MfcRender& out, cv::Mat1f& scratch);

}  // namespace mfcd::vision
