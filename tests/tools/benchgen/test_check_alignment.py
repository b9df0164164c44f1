"""tools/benchgen/check_scene.py's edge alignment on images made in code: a correct camera reads
~0 px although the parts darken towards their rims, a camera off by half a pixel reads it."""

import os
import sys
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), '..', '..', '..', 'tools', 'benchgen'))
import check_scene  # noqa: E402

SUPER = 8  # sub-samples per pixel and axis (box filter)


def scene(shift_px, seed):
    """Depth (0.1 mm units, at pixel centres) and 8 flash images (box-filtered, with the camera's
    image shifted by shift_px in x) of discs lying on a floor. Disc brightness falls off towards
    its rim (a surface turning away), so the intensity edge alone sits inside the true contour."""
    rng = np.random.default_rng(seed)
    H, W = 120, 160
    discs = [(rng.uniform(25, 135), rng.uniform(25, 95), rng.uniform(10, 22)) for _ in range(3)]

    def render(xs, ys):
        near = np.zeros(xs.shape, bool)
        shade = np.full(xs.shape, 60.0)  # floor
        for cx, cy, r in discs:
            d = np.hypot(xs - cx, ys - cy) / r
            inside = d < 1
            shade = np.where(inside, 200.0 * np.sqrt(np.clip(1 - d ** 2, 0, 1)) ** 0.5 + 20, shade)
            near |= inside
        return near, shade

    yc, xc = np.mgrid[0:H, 0:W].astype(float)
    near, _ = render(xc, yc)
    depth = np.where(near, 2800, 3000).astype(np.uint16)  # 280 mm parts on a 300 mm floor
    o = (np.arange(SUPER) + 0.5) / SUPER - 0.5
    ys, xs = np.mgrid[0:H * SUPER, 0:W * SUPER].astype(float)
    ys = ys // SUPER + o[(ys % SUPER).astype(int)]
    xs = xs // SUPER + o[(xs % SUPER).astype(int)] + shift_px
    _, shade = render(xs, ys)
    img = shade.reshape(H, SUPER, W, SUPER).mean(axis=(1, 3))
    return depth, [img.copy() for _ in range(8)]


class EdgeAlignment(unittest.TestCase):
    def pooled(self, shift):
        pooled = None
        for seed in range(6):
            depth, flashes = scene(shift, seed)
            pooled = check_scene.add_profiles(pooled, check_scene.alignment_profiles(flashes, depth, 0.1))
        return check_scene.alignment_offsets(pooled)

    def test_correct_camera_reads_zero_despite_rim_shading(self):
        (ox, nx), (oy, ny) = self.pooled(0.0)
        self.assertGreater(min(nx, ny), 100)
        self.assertLess(abs(ox), check_scene.ALIGN_SPLIT_TOL_PX)
        self.assertLess(abs(oy), check_scene.ALIGN_SPLIT_TOL_PX)

    def test_half_pixel_camera_offset_is_read(self):
        # The image content moves by -shift when the camera samples at x + shift.
        (ox, _), (oy, _) = self.pooled(0.5)
        self.assertGreater(abs(ox), check_scene.ALIGN_SPLIT_TOL_PX)
        self.assertAlmostEqual(abs(ox), 0.5, delta=0.15)
        self.assertLess(abs(oy), check_scene.ALIGN_SPLIT_TOL_PX)

    def test_one_kind_alone_is_biased_by_the_rim(self):
        # What the two kinds' mean removes: each kind alone reads the rim shading's bias.
        depth, flashes = scene(0.0, 1)
        (first, n1), (second, n2) = check_scene.alignment_profiles(flashes, depth, 0.1)[0]
        a, b = check_scene.profile_peak(first), check_scene.profile_peak(second)
        self.assertGreater(abs(a - b), 0.05)


if __name__ == '__main__':
    unittest.main()
