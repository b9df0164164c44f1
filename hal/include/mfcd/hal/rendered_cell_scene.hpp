#pragma once
// The simulated cell behind SimulatedCamera: a SceneRenderer backed by the offscreen multi-flash
// renderer (vision/render). The parts in the bin are rendered with all eight flashes plus the
// ambient image at the start of every FrameSet (the exposure lit by LED 0 alone) and whenever the
// scene changes; each exposure then serves the image of whichever LEDs are lit at that moment, so
// the sequencer's lockstep is what decides which shadows the camera sees.
//
// Lives in its own library (mfcd_hal_sim_cell) so that mfcd_hal itself does not depend on vision/.
#include <cstdint>
#include <vector>

#include "mfcd/hal/simulated.hpp"
#include "vision/render/mfc_renderer.hpp"

namespace mfcd::hal {

class RenderedCellScene final : public SceneRenderer {
 public:
  // `renderer` is borrowed and must be used from the thread that calls render() (its EGL context
  // is current there). The camera format must match the renderer's image size.
  RenderedCellScene(vision::MfcRenderer& renderer, std::vector<vision::ScenePart> parts);

  // Replaces the bin contents; the next exposure re-renders. Not for the frame path (allocates).
  void set_parts(std::vector<vision::ScenePart> parts);
  const vision::MfcRender& last_render() const { return render_; }
  std::uint64_t renders() const { return renders_; }

  void render(LedMask lit, std::uint64_t exposure_index, Image& out) override;

 private:
  vision::MfcRenderer& renderer_;
  std::vector<vision::ScenePart> parts_;
  vision::MfcRender render_;
  bool stale_ = true;
  std::uint64_t renders_ = 0;
};

}  // namespace mfcd::hal
