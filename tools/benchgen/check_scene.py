#!/usr/bin/python3
"""Check one BOP scene written by render_bin.py against its own files and the PLY models.

Run: python3 tools/benchgen/check_scene.py --dataset ROOT --split test --scene N [--overlay out.png]
Reads only the scene's files and ROOT/models; knows nothing of the renderer's internals.
Prints one line per disagreement and a summary; exit 1 when anything disagrees.

Rules (camera frame OpenCV, mm; pixel centre of (0, 0) at (0, 0)):
- surface: every mask_visib pixel, back-projected through depth/ and mapped into the model frame by
  the GT pose, lies within 0.1 mm + the depth rounding along its ray (0.05 mm * |ray| / z) of
  the model surface (exact point-to-triangle distance). No exception at silhouette boundaries;
  a mask_visib pixel with depth 0 is itself a failure.
- silhouette: the model's triangles projected with cam_K and the pose and filled at pixel centres
  vs mask/: no XOR pixel farther than 1 px from the projected silhouette's inner boundary.
- gt_info: px_count_visib, bbox_visib, px_count_valid equal what the masks and depth give;
  px_count_all and bbox_obj agree with the projected silhouette (within max(3 px, 0.5 %) and 1 px);
  visib_fract = px_count_visib / px_count_all; mask_visib inside mask; masks only 0/255.
- images: every flash/ambient/depth/mask image present, single channel, 8/16 bit, of the size in
  scene_camera.json, and no flash image beyond the flash positions.
- alignment: at depth steps > 3 mm between neighbouring pixels, the intensity edge of the
  per-pixel maximum over the flash images must be centred between the two pixels, on average over
  near-side-first and near-side-second contours weighted alike: within 0.4 px in one scene, whose
  parts' shading scatters the measure (on 15 correct test scenes up to 0.25 px), and within 0.1 px
  over every scene of a split pooled (--split-alignment; judged with >= 2000 contours of each
  kind), where that scatter averages out and a camera off by half a pixel does not. One scene's axis is judged only with >= 250 contours of
  each kind (a small image with few parts has fewer: its offset is printed, not judged).
- views: every image of the scene is checked by the rules above. A scene of several images (one
  settled bin seen from several cameras: render_bin.py --second-view-deg) must give every image's
  camera pose, cam_R_w2c (a rotation within 1e-6) and cam_t_w2c (mm); an image with one gives
  them all. Every image lists the same instances (obj_id, in order) and each instance's pose in
  image k is image 0's carried over by the cameras' motion: cam_R_m2c_k = A cam_R_m2c_0 and
  cam_t_m2c_k = A cam_t_m2c_0 + b with A = R_w2c_k R_w2c_0^T, b = t_w2c_k - A t_w2c_0 (within
  1e-6 per rotation entry and 1e-3 mm).

Run with --split-alignment instead of --scene: the pooled alignment of every scene of the split.
"""

import argparse, json, math, os, sys
import numpy as np
from PIL import Image, ImageDraw
from scipy.ndimage import distance_transform_edt, binary_erosion
from scipy.spatial import cKDTree

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plymesh  # noqa: E402

SURFACE_TOL_MM = 0.1
DEPTH_ROUND_MM = 0.05
SAMPLE_STEP_MM = 0.5  # triangle samples: every surface point within 2 * step of a sample of its triangle
ALIGN_TOL_PX = 0.4          # one scene: its content scatters the measure (see the rules above)
ALIGN_SPLIT_TOL_PX = 0.1     # every scene of a split pooled
ALIGN_SPLIT_MIN_CONTOURS = 2000  # of each kind, pooled; fewer (a smoke run's one scene): printed, not judged
ALIGN_MIN_CONTOURS = 250  # of each kind; fewer (tiny images, few parts): the offset is printed, not judged
VIEW_R_TOL = 1e-6   # cam_R_w2c orthonormality, and image k's cam_R_m2c against image 0's carried over
VIEW_T_TOL_MM = 1e-3  # image k's cam_t_m2c against image 0's carried over


class Checker:
    def __init__(self):
        self.failures = []

    def fail(self, msg):
        self.failures.append(msg)
        print('FAIL ' + msg, flush=True)


def load_json(path, chk):
    try:
        with open(path) as f:
            return json.load(f)
    except (OSError, ValueError) as e:
        chk.fail('%s: %s' % (path, e))
        return None


def load_png(path, size, bits, chk):
    """Return the image as a numpy array, or None (after a failure line) when absent or malformed."""
    if not os.path.exists(path):
        chk.fail('%s: missing image' % path)
        return None
    im = Image.open(path)
    want = {8: ('L',), 16: ('I;16', 'I;16B', 'I')}[bits]
    if im.mode not in want:
        chk.fail('%s: mode %s, expected a single-channel %d-bit image' % (path, im.mode, bits))
        return None
    if im.size != size:
        chk.fail('%s: size %dx%d differs from %dx%d in scene_camera.json' % ((path,) + im.size + size))
        return None
    a = np.array(im)
    return a.astype(np.uint16) if bits == 16 else a


# ------------------------------------------------------------------------------------------
# Geometry: exact point-to-triangle distance, triangle samples, silhouette fill.

def _dot(a, b):
    return np.einsum('ij,ij->i', a, b)


def segment_distance(p, a, b):
    ab = b - a
    t = np.clip(_dot(p - a, ab) / np.maximum(_dot(ab, ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(p - (a + t[:, None] * ab), axis=1)


def point_triangle_distance(p, a, b, c):
    """Row-wise exact distance: to the plane when the projection falls inside, else to the edges."""
    n = np.cross(b - a, c - a)
    nn = _dot(n, n)
    ok = nn > 1e-24
    nu = n / np.sqrt(np.where(ok, nn, 1.0))[:, None]
    h = _dot(p - a, nu)
    q = p - h[:, None] * nu
    inside = ok.copy()
    for u, v in ((a, b), (b, c), (c, a)):
        inside &= _dot(np.cross(v - u, q - u), n) >= 0.0
    edges = np.minimum(np.minimum(segment_distance(p, a, b), segment_distance(p, b, c)), segment_distance(p, c, a))
    return np.where(inside, np.abs(h), edges)


def triangle_samples(V, F, step):
    """Grid points apex + i/n1 e1 + j/n2 e2 (i/n1 + j/n2 <= 1) with the apex opposite the longest
    edge and n_k = ceil(|e_k| / step): every point of a triangle is within |e1|/n1 + |e2|/n2 <= 2 step
    of one of its samples. Returns (points, triangle index per point)."""
    pts, owner = [], []
    tri = V[F]
    lengths = np.linalg.norm(tri[:, [1, 2, 0]] - tri[:, [2, 0, 1]], axis=2)  # edge opposite vertex k
    apex = np.argmax(lengths, axis=1)
    grids = {}
    for t in range(len(F)):
        k = apex[t]
        p0, e1, e2 = tri[t, k], tri[t, (k + 1) % 3] - tri[t, k], tri[t, (k + 2) % 3] - tri[t, k]
        n1 = max(1, int(math.ceil(np.linalg.norm(e1) / step)))
        n2 = max(1, int(math.ceil(np.linalg.norm(e2) / step)))
        if (n1, n2) not in grids:
            i, j = np.meshgrid(np.arange(n1 + 1) / n1, np.arange(n2 + 1) / n2, indexing='ij')
            keep = i + j <= 1.0 + 1e-9
            grids[(n1, n2)] = (i[keep], j[keep])
        s, r = grids[(n1, n2)]
        pts.append(p0 + s[:, None] * e1 + r[:, None] * e2)
        owner.append(np.full(len(s), t))
    return np.concatenate(pts), np.concatenate(owner)


class SurfaceIndex:
    def __init__(self, V, F, step=SAMPLE_STEP_MM):
        self.V, self.F, self.step = V, F, step
        pts, self.owner = triangle_samples(V, F, step)
        self.tree = cKDTree(pts)

    def distance(self, p):
        """Exact distance of each point to the mesh: an upper bound from the nearest sample's
        triangle, then every triangle with a sample within that bound + 2 step."""
        if len(p) == 0:
            return np.zeros(0)
        _d, i = self.tree.query(p)
        tri = self.owner[i]
        A, B, C = (self.V[self.F[tri, k]] for k in range(3))
        best = point_triangle_distance(p, A, B, C)
        lists = self.tree.query_ball_point(p, best + 2 * self.step + 1e-9, return_sorted=False)
        counts = np.array([len(x) for x in lists])
        rows = np.repeat(np.arange(len(p)), counts)
        tri = self.owner[np.concatenate([np.asarray(x, np.int64) for x in lists])]
        d = point_triangle_distance(p[rows], *(self.V[self.F[tri, k]] for k in range(3)))
        np.minimum.at(best, rows, d)
        return best


def project(K, R, t, V):
    p = V @ R.T + t
    return np.stack([K[0, 0] * p[:, 0] / p[:, 2] + K[0, 2], K[1, 1] * p[:, 1] / p[:, 2] + K[1, 2]], 1), p[:, 2]


def fill_silhouette(uv, F, eps=1e-9):
    """Pixel centres inside any projected triangle. Returns (mask, x0, y0) on the silhouette's box."""
    x0, y0 = int(math.floor(uv[:, 0].min())), int(math.floor(uv[:, 1].min()))
    x1, y1 = int(math.ceil(uv[:, 0].max())), int(math.ceil(uv[:, 1].max()))
    mask = np.zeros((y1 - y0 + 1, x1 - x0 + 1), bool)
    A, B, C = uv[F[:, 0]], uv[F[:, 1]], uv[F[:, 2]]
    area = (B[:, 0] - A[:, 0]) * (C[:, 1] - A[:, 1]) - (B[:, 1] - A[:, 1]) * (C[:, 0] - A[:, 0])
    lo = np.ceil(np.minimum(np.minimum(A, B), C) - eps).astype(np.int64)
    hi = np.floor(np.maximum(np.maximum(A, B), C) + eps).astype(np.int64)
    nx, ny = np.maximum(hi[:, 0] - lo[:, 0] + 1, 0), np.maximum(hi[:, 1] - lo[:, 1] + 1, 0)
    live = np.nonzero((np.abs(area) > 1e-12) & (nx * ny > 0))[0]
    for chunk in np.array_split(live, max(1, int((nx[live] * ny[live]).sum() // 2_000_000) + 1)):
        cnt = nx[chunk] * ny[chunk]
        tri = np.repeat(chunk, cnt)
        local = np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        px = lo[tri, 0] + local % nx[tri]
        py = lo[tri, 1] + local // nx[tri]
        inside = np.ones(len(tri), bool)
        s = np.sign(area[tri])
        for P, Q in ((A, B), (B, C), (C, A)):
            e = (Q[tri, 0] - P[tri, 0]) * (py - P[tri, 1]) - (Q[tri, 1] - P[tri, 1]) * (px - P[tri, 0])
            inside &= s * e >= -eps * np.abs(area[tri])
        mask[py[inside] - y0, px[inside] - x0] = True
    return mask, x0, y0


def inner_boundary(mask):
    return mask & ~binary_erosion(mask, border_value=0)


def bbox(mask, x0=0, y0=0):
    ys, xs = np.nonzero(mask)
    if len(xs) == 0:
        return [-1, -1, -1, -1]
    return [int(xs.min()) + x0, int(ys.min()) + y0, int(xs.max() - xs.min() + 1), int(ys.max() - ys.min() + 1)]


# ------------------------------------------------------------------------------------------
# Per-instance checks.

def check_instance(chk, where, K, gt, info, mesh, index, mask, visib, depth, stats):
    R = np.array(gt['cam_R_m2c'], float).reshape(3, 3)
    t = np.array(gt['cam_t_m2c'], float)
    if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
        chk.fail('%s: cam_R_m2c is not a rotation' % where)
    H, W = depth.shape
    if np.any(visib & ~mask):
        chk.fail('%s: %d mask_visib pixels outside mask' % (where, int((visib & ~mask).sum())))
    check_surface(chk, where, K, R, t, index, visib, depth, stats)
    uv, z = project(K, R, t, mesh['vertices'])
    if z.min() <= 0:
        chk.fail('%s: model reaches behind the camera' % where)
        return None
    sil, x0, y0 = fill_silhouette(uv, mesh['faces'])
    canvas = np.zeros((H, W), bool)
    ys, xs = np.nonzero(sil)
    keep = (xs + x0 >= 0) & (xs + x0 < W) & (ys + y0 >= 0) & (ys + y0 < H)
    canvas[ys[keep] + y0, xs[keep] + x0] = True
    xor = canvas ^ mask
    dist = distance_transform_edt(~inner_boundary(canvas)) if canvas.any() else np.full((H, W), np.inf)
    worst = float(dist[xor].max()) if xor.any() else 0.0
    stats['sil_max'] = max(stats['sil_max'], worst)
    stats['xor_px'] += int(xor.sum())
    if worst > 1.0:
        chk.fail('%s: silhouette differs from mask/ by %.1f px (%d XOR pixels)' % (where, worst, int(xor.sum())))
    check_info(chk, where, info, sil, x0, y0, mask, visib, depth, keep.all())
    return canvas


def check_surface(chk, where, K, R, t, index, visib, depth, stats):
    vs, us = np.nonzero(visib)
    z = depth[vs, us].astype(float) * stats['depth_scale']
    if np.any(z <= 0):
        chk.fail('%s: %d mask_visib pixels have no depth' % (where, int((z <= 0).sum())))
    ok = z > 0
    us, vs, z = us[ok], vs[ok], z[ok]
    ray = np.stack([(us - K[0, 2]) / K[0, 0], (vs - K[1, 2]) / K[1, 1], np.ones_like(z)], 1)
    d = index.distance((ray * z[:, None] - t) @ R)  # R^T (p - t), row-wise
    tol = SURFACE_TOL_MM + DEPTH_ROUND_MM * np.linalg.norm(ray, axis=1)
    stats['dist'].append(d)
    bad = d > tol
    if bad.any():
        chk.fail('%s: %d of %d visible pixels farther than %.2f mm from the model (max %.3f mm)'
                 % (where, int(bad.sum()), len(d), float(tol.max()), float(d.max())))


def check_info(chk, where, info, sil, x0, y0, mask, visib, depth, sil_inside):
    def differ(key, got, want):
        if got != want:
            chk.fail('%s: %s is %s, the masks give %s' % (where, key, got, want))
    differ('px_count_visib', info['px_count_visib'], int(visib.sum()))
    differ('bbox_visib', list(info['bbox_visib']), bbox(visib))
    differ('px_count_valid', info['px_count_valid'], int((mask & (depth > 0)).sum()))
    n_all, n_sil = info['px_count_all'], int(sil.sum())
    if abs(n_all - n_sil) > max(3, 0.005 * n_sil):
        chk.fail('%s: px_count_all %d, projected silhouette %d' % (where, n_all, n_sil))
    if n_all < int(mask.sum()) or (sil_inside and n_all != int(mask.sum())):
        chk.fail('%s: px_count_all %d vs %d mask pixels' % (where, n_all, int(mask.sum())))
    box = bbox(sil, x0, y0)
    if any(abs(a - b) > 1 for a, b in zip(info['bbox_obj'], box)):
        chk.fail('%s: bbox_obj %s, projected silhouette %s' % (where, info['bbox_obj'], box))
    frac = info['px_count_visib'] / n_all if n_all else 0.0
    if abs(info['visib_fract'] - frac) > 1e-6:
        chk.fail('%s: visib_fract %g, expected %g' % (where, info['visib_fract'], frac))


def alignment_profiles(flashes, depth, scale):
    """Edge profiles at occluding contours, per axis (x, y) and per kind of contour.

    Contours: neighbour pairs (j, j + 1) whose depth steps by > 3 mm while both sides are smooth
    (< 1 mm steps next to them); the contour lies between the two pixel centres, at j + 0.5.
    Profile P(k), k = -3..3: the sum over contours of |I(j + k + 1) - I(j + k)| for the per-pixel
    maximum I of the flash images (shadows mostly gone). The near side of a contour biases its
    peak towards itself (surfaces darken as they turn away from the camera at their rim), so
    contours with the near side first and those with it second are summed apart.
    Returns [[(profile, count) near first, (profile, count) near second] for x, for y]."""
    img = np.max(np.stack(flashes), axis=0).astype(float)
    d = depth.astype(float) * scale
    out = []
    for I, D in ((img, d), (img.T, d.T)):
        g = np.abs(np.diff(I, axis=1))
        s = np.diff(D, axis=1)
        a = np.abs(s)
        valid = (D[:, :-1] > 0) & (D[:, 1:] > 0)
        step = np.zeros_like(valid)
        step[:, 3:-3] = (a[:, 3:-3] > 3.0) & (a[:, 2:-4] < 1.0) & (a[:, 4:-2] < 1.0) & valid[:, 3:-3]
        kinds = []
        for near_first in (True, False):
            rows, cols = np.nonzero(step & ((s > 0) == near_first))
            kinds.append((np.array([g[rows, cols + k].sum() for k in range(-3, 4)]), int(len(rows))))
        out.append(kinds)
    return out


def add_profiles(pooled, profiles):
    """alignment_profiles of several images summed (pooled None: the first)."""
    if pooled is None:
        return profiles
    return [[(p + q, m + n) for (p, m), (q, n) in zip(a, b)] for a, b in zip(pooled, profiles)]


def profile_peak(prof):
    """Sub-pixel peak of a 7-sample profile (k = -3..3), refined by a parabola."""
    k = int(np.clip(np.argmax(prof), 1, 5))
    den = prof[k - 1] - 2 * prof[k] + prof[k + 1]
    return k - 3 + (0.5 * (prof[k - 1] - prof[k + 1]) / den if den < 0 else 0.0)


def alignment_offsets(profiles, min_count=10):
    """Offset (px) per axis from alignment_profiles (or their sums over scenes): the mean of the two
    kinds' peaks, so that the rim bias cancels and a camera offset does not.
    Returns [(offset_x, contours_x), (offset_y, contours_y)]; contours counts the smaller kind
    (0, offset 0: too few to measure)."""
    out = []
    for kinds in profiles:
        n = min(c for _, c in kinds)
        out.append((float(np.mean([profile_peak(p) for p, _ in kinds])), n) if n >= min_count else (0.0, 0))
    return out


# ------------------------------------------------------------------------------------------

def check_image(chk, root, sdir, iid, cam, gts, infos, models, indexes, overlay):
    K = np.array(cam['cam_K'], float).reshape(3, 3)
    W, H = int(cam['width']), int(cam['height'])
    size, tag = (W, H), '%06d' % iid
    if K[2, 0] != 0 or K[2, 1] != 0 or K[2, 2] != 1 or not (-0.5 <= K[0, 2] <= W - 0.5 and -0.5 <= K[1, 2] <= H - 0.5):
        chk.fail('%s: cam_K is not a pinhole matrix with its principal point in the image' % tag)
    n_flash = len(cam['flash_positions_mm'])
    flashes = [load_png(os.path.join(sdir, 'flash', '%s_%d.png' % (tag, k)), size, 8, chk) for k in range(n_flash)]
    if os.path.exists(os.path.join(sdir, 'flash', '%s_%d.png' % (tag, n_flash))):
        chk.fail('%s: more flash images than %d flash positions' % (tag, n_flash))
    ambient = load_png(os.path.join(sdir, 'ambient', tag + '.png'), size, 8, chk)
    depth = load_png(os.path.join(sdir, 'depth', tag + '.png'), size, 16, chk)
    if depth is None:
        return None
    if len(gts) != len(infos):
        chk.fail('%s: %d scene_gt entries, %d scene_gt_info entries' % (tag, len(gts), len(infos)))
    stats = {'dist': [], 'sil_max': 0.0, 'xor_px': 0, 'depth_scale': float(cam['depth_scale']), 'n': 0}
    outlines = []
    for g, (gt, info) in enumerate(zip(gts, infos)):
        where = '%s instance %d (obj %d)' % (tag, g, gt['obj_id'])
        masks = [load_png(os.path.join(sdir, sub, '%s_%06d.png' % (tag, g)), size, 8, chk) for sub in ('mask', 'mask_visib')]
        if any(m is None for m in masks):
            continue
        for sub, m in zip(('mask', 'mask_visib'), masks):
            if np.any((m != 0) & (m != 255)):
                chk.fail('%s: %s has values other than 0 and 255' % (where, sub))
        oid = gt['obj_id']
        if oid not in models:
            chk.fail('%s: no model obj_%06d.ply' % (where, oid))
            continue
        canvas = check_instance(chk, where, K, gt, info, models[oid], indexes[oid], masks[0] > 0, masks[1] > 0, depth, stats)
        stats['n'] += 1
        if canvas is not None:
            outlines.append((g, oid, canvas))
    if all(f is not None for f in flashes) and flashes:
        stats['profiles'] = alignment_profiles(flashes, depth, stats['depth_scale'])
        stats['align'] = alignment_offsets(stats['profiles'])
        for name, (off, n) in zip('xy', stats['align']):
            if n >= ALIGN_MIN_CONTOURS and abs(off) > ALIGN_TOL_PX:
                chk.fail('%s: flash images are offset %.2f px in %s from the depth steps (%d edges)' % (tag, off, name, n))
    if overlay and ambient is not None:
        write_overlay(overlay, ambient, outlines)
    return stats


def world_pose(chk, tag, cam):
    """(R_w2c, t_w2c) of an image's scene_camera entry, or None (after a failure line) when malformed."""
    try:
        R = np.array(cam['cam_R_w2c'], float).reshape(3, 3)
        t = np.array(cam['cam_t_w2c'], float).reshape(3)
    except (KeyError, TypeError, ValueError):
        chk.fail('%s: cam_R_w2c needs 9 numbers and cam_t_w2c 3' % tag)
        return None
    if not (np.all(np.isfinite(R)) and np.all(np.isfinite(t))):
        chk.fail('%s: cam_R_w2c / cam_t_w2c are not finite' % tag)
        return None
    if np.abs(R @ R.T - np.eye(3)).max() > VIEW_R_TOL or np.linalg.det(R) < 0:
        chk.fail('%s: cam_R_w2c is not a rotation' % tag)
        return None
    return R, t


def check_views(chk, cams, gts):
    """The views rule (module docstring). Returns (max rotation entry error, max translation error mm)
    over the images after the first, or None when the scene has one image."""
    keys = sorted(cams, key=int)
    given = [k for k in keys if 'cam_R_w2c' in cams[k] or 'cam_t_w2c' in cams[k]]
    if len(keys) < 2 and not given:
        return None
    if not given:
        chk.fail('scene has %d images but no cam_R_w2c / cam_t_w2c: their cameras are not known' % len(keys))
        return None
    for k in keys:
        if k not in given:
            chk.fail('%06d: no cam_R_w2c / cam_t_w2c while image(s) %s give them' % (int(k), ', '.join(given)))
    poses = {k: world_pose(chk, '%06d' % int(k), cams[k]) for k in given}
    k0 = keys[0]
    if poses.get(k0) is None:
        return None
    R0, t0 = poses[k0]
    err_r, err_t = 0.0, 0.0
    for k in keys[1:]:
        if poses.get(k) is None:
            continue
        A = poses[k][0] @ R0.T
        b = poses[k][1] - A @ t0
        first, other = gts.get(k0, []), gts.get(k, [])
        if [e['obj_id'] for e in first] != [e['obj_id'] for e in other]:
            chk.fail('%06d: scene_gt lists other instances (obj_id %s) than image %s (%s)'
                     % (int(k), [e['obj_id'] for e in other], k0, [e['obj_id'] for e in first]))
            continue
        for g, (e0, e1) in enumerate(zip(first, other)):
            R = A @ np.array(e0['cam_R_m2c'], float).reshape(3, 3)
            t = A @ np.array(e0['cam_t_m2c'], float) + b
            dr = float(np.abs(np.array(e1['cam_R_m2c'], float).reshape(3, 3) - R).max())
            dt = float(np.abs(np.array(e1['cam_t_m2c'], float) - t).max())
            err_r, err_t = max(err_r, dr), max(err_t, dt)
            if dr > VIEW_R_TOL or dt > VIEW_T_TOL_MM:
                chk.fail('%06d instance %d (obj %d): pose differs from image %s\'s carried over by the cameras '
                         '(rotation %.2g, translation %.3g mm)' % (int(k), g, e1['obj_id'], k0, dr, dt))
    return err_r, err_t


def overlay_path(path, iid, first):
    """--overlay's file for the first image; PATH-IIIIII.ext for the others."""
    if path is None or iid == first:
        return path
    stem, ext = os.path.splitext(path)
    return '%s-%06d%s' % (stem, iid, ext)


def write_overlay(path, ambient, outlines):
    a = ambient.astype(float)
    a = np.clip(a * 255.0 / max(np.percentile(a, 99.5), 1.0), 0, 255).astype(np.uint8)
    rgb = np.repeat(a[:, :, None], 3, axis=2)
    colours = [(255, 60, 60), (60, 255, 60), (80, 160, 255), (255, 220, 40), (255, 60, 255), (40, 255, 255)]
    for g, _oid, canvas in outlines:
        rgb[inner_boundary(canvas)] = colours[g % len(colours)]
    scale = max(1, 640 // ambient.shape[1])
    im = Image.fromarray(rgb).resize((rgb.shape[1] * scale, rgb.shape[0] * scale), Image.NEAREST)
    draw = ImageDraw.Draw(im)
    for g, oid, canvas in outlines:
        ys, xs = np.nonzero(canvas)
        if len(xs):
            draw.text((xs.mean() * scale - 8, ys.mean() * scale - 5), '%d:%d' % (g, oid), fill=colours[g % len(colours)])
    im.save(path)


def split_alignment(dataset, split):
    """Every scene of the split (folders named by number: not those kept aside) pooled: exit 1 when
    an axis is off by more than ALIGN_SPLIT_TOL_PX."""
    chk = Checker()
    root = os.path.join(dataset, split)
    scenes = sorted(n for n in os.listdir(root) if n.isdigit())
    pooled = None
    for name in scenes:
        sdir = os.path.join(root, name)
        cams = load_json(os.path.join(sdir, 'scene_camera.json'), chk)
        for key, cam in sorted((cams or {}).items(), key=lambda kv: int(kv[0])):
            tag, size = '%06d' % int(key), (int(cam['width']), int(cam['height']))
            flashes = [load_png(os.path.join(sdir, 'flash', '%s_%d.png' % (tag, k)), size, 8, chk)
                       for k in range(len(cam['flash_positions_mm']))]
            depth = load_png(os.path.join(sdir, 'depth', tag + '.png'), size, 16, chk)
            if depth is None or any(f is None for f in flashes):
                continue
            pooled = add_profiles(pooled, alignment_profiles(flashes, depth, float(cam['depth_scale'])))
    if pooled is None:
        print('check_scene: split %s: no scene to pool' % split)
        return 1
    (ox, nx), (oy, ny) = alignment_offsets(pooled)
    for name, off, n in (('x', ox, nx), ('y', oy, ny)):
        if n >= ALIGN_SPLIT_MIN_CONTOURS and abs(off) > ALIGN_SPLIT_TOL_PX:
            chk.fail('split %s: flash images are offset %.3f px in %s from the depth steps over %d scenes'
                     % (split, off, name, len(scenes)))
    print('check_scene: split %s, %d scenes pooled: edge offset x %+.3f px (%d), y %+.3f px (%d); %s'
          % (split, len(scenes), ox, nx, oy, ny, 'FAIL' if chk.failures else 'PASS'))
    return 1 if chk.failures else 0


def main():
    p = argparse.ArgumentParser()
    p.add_argument('--dataset', required=True)
    p.add_argument('--split', default='test')
    p.add_argument('--scene', type=int)
    p.add_argument('--overlay')
    p.add_argument('--split-alignment', action='store_true', help='pooled edge alignment of every scene of the split')
    a = p.parse_args()
    if a.split_alignment:
        return split_alignment(a.dataset, a.split)
    if a.scene is None:
        p.error('--scene or --split-alignment is required')
    chk = Checker()
    sdir = os.path.join(a.dataset, a.split, '%06d' % a.scene)
    cams, gts, infos = (load_json(os.path.join(sdir, n), chk) for n in ('scene_camera.json', 'scene_gt.json', 'scene_gt_info.json'))
    if None in (cams, gts, infos):
        return 1
    ids = sorted({e['obj_id'] for v in gts.values() for e in v})
    models, indexes = {}, {}
    for oid in ids:
        path = os.path.join(a.dataset, 'models', 'obj_%06d.ply' % oid)
        if os.path.exists(path):
            models[oid] = plymesh.read_ply(path)
            indexes[oid] = SurfaceIndex(models[oid]['vertices'], models[oid]['faces'])
    total = {'n': 0, 'dist': [], 'sil': 0.0, 'xor': 0, 'align': []}
    keys = sorted(cams, key=int)
    for key in keys:
        s = check_image(chk, a.dataset, sdir, int(key), cams[key], gts.get(key, []), infos.get(key, []),
                        models, indexes, overlay_path(a.overlay, int(key), int(keys[0])))
        if s:
            total['n'] += s['n']
            total['dist'] += s['dist']
            total['sil'] = max(total['sil'], s['sil_max'])
            total['xor'] += s['xor_px']
            total['align'].append(s.get('align'))
        else:
            total['align'].append(None)
    views = check_views(chk, cams, gts)
    d = np.concatenate(total['dist']) if total['dist'] else np.zeros(1)
    al = total['align'][0] if total['align'] and total['align'][0] else [(0.0, 0), (0.0, 0)]
    more = ''  # a scene of several images: the others' edge offsets and the views rule's largest errors
    for key, other in zip(keys[1:], total['align'][1:]):
        other = other or [(0.0, 0), (0.0, 0)]
        more += '; image %s edge offset x %+.3f px (%d), y %+.3f px (%d)' % (key, other[0][0], other[0][1],
                                                                             other[1][0], other[1][1])
    if views is not None:
        more += '; %d views: poses carried over within %.1g (rotation), %.1g mm' % (len(keys), views[0], views[1])
    print('check_scene: scene %d: %d instances, %d visible pixels: surface distance max %.4f mm, p99 %.4f mm; '
          'silhouette max disagreement %.1f px (%d XOR px); edge offset x %+.3f px (%d), y %+.3f px (%d)%s; %s'
          % (a.scene, total['n'], d.size, d.max(), np.percentile(d, 99), total['sil'], total['xor'],
             al[0][0], al[0][1], al[1][0], al[1][1], more, 'FAIL (%d)' % len(chk.failures) if chk.failures else 'PASS'))
    return 1 if chk.failures else 0


if __name__ == '__main__':
    sys.exit(main())
