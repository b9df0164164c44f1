#include "mfcd/hal/rendered_cell_scene.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace mfcd::hal {

RenderedCellScene::RenderedCellScene(vision::MfcRenderer& renderer, std::vector<vision::ScenePart> parts)
    : renderer_(renderer), parts_(std::move(parts)) {}

void RenderedCellScene::set_parts(std::vector<vision::ScenePart> parts) {
  parts_ = std::move(parts);
  stale_ = true;
}

void RenderedCellScene::render(LedMask lit, std::uint64_t exposure_index, Image& out) {
  const ImageFormat& f = out.format();
  const cv::Size size = renderer_.camera().image_size;
  if (f.width != size.width || f.height != size.height)
    throw std::invalid_argument("simulated cell: camera format " + std::to_string(f.width) + "x" +
                                std::to_string(f.height) + " differs from the renderer's image size " +
                                std::to_string(size.width) + "x" + std::to_string(size.height));
  // A new FrameSet starts with LED 0 alone: render the scene once for the whole set, with fresh
  // sensor noise (seeded by the exposure index, so runs are reproducible).
  if (stale_ || lit == LedMask{1}) {
    renderer_.render(parts_, render_, exposure_index + 1);
    stale_ = false;
    ++renders_;
  }
  const vision::MfcFrames& frames = render_.frames;
  const bool wide = f.bits_per_pixel == 16;
  // One LED (or none): exactly that rendered exposure. Several: light adds, so the ambient plus
  // what each lit LED contributes on top of it (saturating like a sensor).
  const bool single = lit == 0 || (lit & (lit - 1)) == 0;
  const cv::Mat1b* source = &frames.ambient;
  if (lit != 0 && single)
    for (int i = 0; i < kLedCount; ++i)
      if (lit == (1u << i)) source = &frames.flash.at(static_cast<size_t>(i));
  for (int y = 0; y < f.height; ++y) {
    const uint8_t* src = source->ptr<uint8_t>(y);
    const uint8_t* amb = frames.ambient.ptr<uint8_t>(y);
    uint8_t* o8 = out.row(y);
    auto* o16 = reinterpret_cast<uint16_t*>(out.row(y));
    for (int x = 0; x < f.width; ++x) {
      int v = src[x];
      if (!single) {
        v = amb[x];
        for (int i = 0; i < kLedCount && i < static_cast<int>(frames.flash.size()); ++i)
          if (lit & (1u << i)) v += std::max(0, frames.flash[i](y, x) - amb[x]);
        v = std::min(v, 255);
      }
      if (wide)
        o16[x] = static_cast<uint16_t>(v * 257);
      else
        o8[x] = static_cast<uint8_t>(v);
    }
  }
}

}  // namespace mfcd::hal
