"""Ground truth by ray casting through pixel centres (world = Blender camera frame, mm): depth,
which object each pixel sees, and per instance its whole silhouette and visible pixels."""

import math
import numpy as np
from mathutils.bvhtree import BVHTree  # noqa: E402
from benchgen_common import FLIP  # noqa: E402
from bin_layout import merge  # noqa: E402


def pixel_rays(cam, us, vs):
    """World-frame ray directions (not normalised, z component -1) through OpenCV pixel centres."""
    x = (us - cam['cx']) / cam['fx']
    y = (vs - cam['cy']) / cam['fy']
    return np.stack([x, -y, -np.ones_like(x)], axis=-1)


def cast(tree, dirs):
    """Return (hit polygon index or -1, depth_mm along the optical axis) per ray."""
    rc, origin = tree.ray_cast, (0.0, 0.0, 0.0)
    idx = np.full(len(dirs), -1, np.int64)
    depth = np.zeros(len(dirs))
    for i, d in enumerate(dirs.tolist()):
        loc, _n, k, _dist = rc(origin, d)
        if loc is not None:
            idx[i], depth[i] = k, -loc[2]
    return idx, depth


def bvh(verts, faces):
    return BVHTree.FromPolygons(verts.tolist(), faces.tolist(), all_triangles=True, epsilon=0.0)


def ground_truth(cam, parts, bin_vf, table_vf):
    """parts: list of (world verts, faces). Returns depth (H, W) mm, owner map, per-instance masks/info."""
    W, H = cam['width'], cam['height']
    blocks = [bin_vf, table_vf] + parts
    owners = np.concatenate([np.full(len(f), g - 2) for g, (_v, f) in enumerate(blocks)])  # -2 bin, -1 table
    verts, faces = merge(blocks)
    vs, us = np.mgrid[0:H, 0:W]
    idx, depth = cast(bvh(verts, faces), pixel_rays(cam, us.ravel().astype(float), vs.ravel().astype(float)))
    owner = np.where(idx >= 0, owners[np.maximum(idx, 0)], -3).reshape(H, W)
    depth = depth.reshape(H, W)
    insts = [instance_gt(cam, v, f, g, owner, depth) for g, (v, f) in enumerate(parts)]
    return depth, owner, insts


def instance_gt(cam, verts, faces, g, owner, depth):
    """Silhouette of instance g alone over its projected box (may pass the image border), BOP info."""
    W, H = cam['width'], cam['height']
    p = (FLIP @ verts.T).T
    u = cam['fx'] * p[:, 0] / p[:, 2] + cam['cx']
    v = cam['fy'] * p[:, 1] / p[:, 2] + cam['cy']
    u0, u1 = int(math.floor(u.min())) - 1, int(math.ceil(u.max())) + 1
    v0, v1 = int(math.floor(v.min())) - 1, int(math.ceil(v.max())) + 1
    vs, us = np.mgrid[v0:v1 + 1, u0:u1 + 1]
    idx, _d = cast(bvh(verts, faces), pixel_rays(cam, us.ravel().astype(float), vs.ravel().astype(float)))
    hit = idx >= 0
    xs, ys = us.ravel()[hit], vs.ravel()[hit]
    mask = np.zeros((H, W), bool)
    inside = (xs >= 0) & (xs < W) & (ys >= 0) & (ys < H)
    mask[ys[inside], xs[inside]] = True
    visib = mask & (owner == g)
    info = {'bbox_obj': box(xs, ys), 'bbox_visib': box(*np.nonzero(visib)[::-1]),
            'px_count_all': int(hit.sum()), 'px_count_valid': int((mask & (depth > 0)).sum()),
            'px_count_visib': int(visib.sum())}
    info['visib_fract'] = info['px_count_visib'] / info['px_count_all'] if info['px_count_all'] else 0.0
    return {'mask': mask, 'visib': visib, 'info': info}


def box(xs, ys):
    if len(xs) == 0:
        return [-1, -1, -1, -1]
    return [int(xs.min()), int(ys.min()), int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)]
