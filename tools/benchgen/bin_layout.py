"""Scene layout drawn from the scene's random generator, and the bin and table geometry, in the
world frame (= the Blender camera frame, mm). numpy only."""

import math
import numpy as np


def draw_layout(rng, cam, args):
    """Everything drawn per scene except the parts: bin, lights, sensor."""
    D = float(cam['floor_distance_mm']) + rng.uniform(-10.0, 10.0)
    fov = np.array([cam['width'] * D / cam['fx'], cam['height'] * D / cam['fy']])  # view at the floor, mm
    return {'floor_mm': D, 'inner': (fov * rng.uniform(0.80, 0.95, 2)).tolist(),
            'wall_h': rng.uniform(30.0, 70.0), 'wall_t': rng.uniform(3.0, 8.0), 'floor_t': rng.uniform(3.0, 6.0),
            'offset': rng.uniform(-5.0, 5.0, 2).tolist(), 'yaw_deg': rng.uniform(-4.0, 4.0),
            'bin_albedo': rng.uniform(0.25, 0.75), 'table_albedo': rng.uniform(0.15, 0.6),
            'floor_dn': rng.uniform(150.0, 200.0), 'read_noise_dn': rng.uniform(1.5, 2.5),
            'e_per_dn': rng.uniform(20.0, 60.0), 'led_radius_mm': rng.uniform(0.75, 2.0),
            'ambient_ratio': rng.uniform(0.08, 0.25), 'room_light_xy': rng.uniform(-400.0, 400.0, 2).tolist()}


def draw_types(rng, args):
    """Instance types: every given type at least once (when the count allows), the rest random."""
    n = int(rng.integers(args.parts[0], args.parts[1] + 1))
    ids = args.obj_ids
    base = list(ids[:min(n, len(ids))])
    rest = rng.choice(ids, size=n - len(base), p=rng.dirichlet(np.ones(len(ids)))).tolist()
    return [int(x) for x in rng.permutation(base + rest)]


# A bin holds its parts in about one layer, each part covering about half the square of its
# diameter, and its walls stand at least this share of the largest part's diameter: a bin drawn
# for the view alone held 1 of 21 cups of 112 mm (the rest slid over its 36 mm walls).
BIN_LAYERS = 1.0
FOOTPRINT_SHARE = 0.5
WALL_SHARE = 0.75


def fit_bin_to_parts(lay, models, types):
    """Grows the drawn bin (in place) to hold `types`: its floor to BIN_LAYERS layers of the parts'
    footprints (the bin may then reach past the view, as a large part's bin does), its walls to
    WALL_SHARE of the largest diameter. Returns the area scale applied (1: the drawn bin held them)."""
    d = [2.0 * models[o]['radius'] for o in types]
    need = sum(FOOTPRINT_SHARE * x * x for x in d) / BIN_LAYERS
    area = lay['inner'][0] * lay['inner'][1]
    scale = max(1.0, need / area)
    lay['inner'] = [x * math.sqrt(scale) for x in lay['inner']]
    lay['wall_h'] = max(lay['wall_h'], WALL_SHARE * max(d))
    return scale


def quat_matrix(q):
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def orthonormal(R, t):
    u, _s, vt = np.linalg.svd(R)
    Rn = u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt
    return Rn, np.asarray(t, np.float64).copy()


def matrix4(R, t):
    import mathutils
    M = np.eye(4)
    M[:3, :3], M[:3, 3] = R, t
    return mathutils.Matrix(M.tolist())


def bin_rotation(lay):
    a = math.radians(lay['yaw_deg'])
    return np.array([[math.cos(a), -math.sin(a), 0.0], [math.sin(a), math.cos(a), 0.0], [0.0, 0.0, 1.0]])


def bin_to_world(lay, pts):
    """Bin frame: origin at the inner floor centre, z up, x/y along the walls."""
    o = np.array([lay['offset'][0], lay['offset'][1], -lay['floor_mm']])
    return pts @ bin_rotation(lay).T + o


def inside_bin(lay, pts_world):
    """pts (3, N) world; inside when within the inner walls (+0.5 mm) and not below the floor."""
    o = np.array([lay['offset'][0], lay['offset'][1], -lay['floor_mm']])
    p = bin_rotation(lay).T @ (pts_world - o[:, None])
    hx, hy = lay['inner'][0] / 2 + 0.5, lay['inner'][1] / 2 + 0.5
    return bool(np.all(np.abs(p[0]) <= hx) and np.all(np.abs(p[1]) <= hy) and np.all(p[2] >= -0.5))


def box_tris(lo, hi):
    """Closed box, outward triangles: (8, 3) corners, (12, 3) faces."""
    v = np.array([[x, y, z] for z in (lo[2], hi[2]) for y in (lo[1], hi[1]) for x in (lo[0], hi[0])], float)
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    return v, np.array([t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))], np.int64)


def merge(meshes):
    offsets = np.cumsum([0] + [len(v) for v, _f in meshes])
    return np.concatenate([v for v, _f in meshes]), np.concatenate([f + o for (_v, f), o in zip(meshes, offsets)])


def bin_boxes(lay):
    """The bin as 5 boxes (lo, hi) in the bin frame (origin at the inner floor centre, z up):
    floor slab with its top at z = 0, then the walls standing on it."""
    ix, iy = lay['inner'][0] / 2, lay['inner'][1] / 2
    t, h, ft = lay['wall_t'], lay['wall_h'], lay['floor_t']
    return [((-ix - t, -iy - t, -ft), (ix + t, iy + t, 0.0)),
            ((ix, -iy - t, 0.0), (ix + t, iy + t, h)), ((-ix - t, -iy - t, 0.0), (-ix, iy + t, h)),
            ((-ix, iy, 0.0), (ix, iy + t, h)), ((-ix, -iy - t, 0.0), (ix, -iy, h))]


def bin_mesh(lay):
    """Open box (floor + 4 walls) as one mesh in the world frame."""
    v, f = merge([box_tris(lo, hi) for lo, hi in bin_boxes(lay)])
    return bin_to_world(lay, v), f


def table_mesh(lay):
    """Table: a 3 m square slab whose top touches the bin's underside."""
    top = -lay['floor_mm'] - lay['floor_t']
    return box_tris((-1500.0, -1500.0, top - 10.0), (1500.0, 1500.0, top))
