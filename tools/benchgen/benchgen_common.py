"""Constants and helpers shared by the renderer's modules."""

import sys
import numpy as np


FLIP = np.diag([1.0, -1.0, -1.0])  # OpenCV camera frame <-> Blender world frame (its own inverse)
N_FLASH = 8
# Light paths: few bounces, no caustics, indirect samples clamped at ~2x a flash-lit floor's
# radiance (a floor of albedo a has radiance ~a under a flash, see add_lights). One diffuse bounce:
# a second one added ~5 % light on the bin floor but doubled its noise at 24 samples.
CYCLES = {'max_bounces': 3, 'diffuse_bounces': 1, 'glossy_bounces': 2, 'blur_glossy': 1.0,
          'sample_clamp_indirect': 1.5}
# Bullet collision margin of the parts, mm. Larger is steadier (parts fall asleep sooner); a part
# resting on an edge of its hull sinks by up to margin * (sqrt(2) - 1) for a right-angled edge.
HULL_MARGIN_MM = 0.3



def log(msg):
    print('[benchgen] ' + msg, file=sys.stderr, flush=True)


def shrunk_hull(v, hull):
    """Bullet pads a convex hull by its collision margin; Blender embeds none when the margin is
    set. So the physics proxy is the hull moved inward by the margin (1 mm, less for thin parts):
    hull + margin = the part's hull with edges rounded by the margin. Returns (margin, verts, faces)."""
    from scipy.spatial import ConvexHull, HalfspaceIntersection
    c = v[hull.vertices].mean(0)
    inradius = float(-(hull.equations[:, :3] @ c + hull.equations[:, 3]).max())
    margin = min(HULL_MARGIN_MM, 0.3 * inradius)
    planes = hull.equations.copy()
    planes[:, 3] += margin
    pts = HalfspaceIntersection(planes, c).intersections
    inner = ConvexHull(pts)
    return margin, pts[inner.vertices], np.searchsorted(inner.vertices, inner.simplices)


def second_view_pose(deg, floor_mm):
    """Camera 1 of a scene rendered with --second-view-deg: camera 0 turned by deg about the axis
    parallel to camera 0's x axis through the pivot c = (0, 0, floor_mm) (OpenCV camera-0 frame).
    Returns (R, t) with p1 = R p0 + t (OpenCV camera frames, mm): R = Rx(deg), t = c - R c, so the
    pivot stays at (0, 0, floor_mm) in camera 1. Camera 1's centre is at (0, -floor sin deg,
    floor (1 - cos deg)) in camera 0's frame: deg > 0 moves it towards the top edge of image 0
    (OpenCV -y) and tilts its optical axis (0, sin deg, cos deg) back onto the pivot."""
    a = np.radians(deg)
    R = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)], [0.0, np.sin(a), np.cos(a)]])
    c = np.array([0.0, 0.0, float(floor_mm)])
    return R, c - R @ c


def cycles_seed(args, k):
    return (args.seed * 1000003 + args.scene_id * 7919 + k * 104729) % (2 ** 31 - 1)

