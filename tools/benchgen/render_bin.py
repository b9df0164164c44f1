"""Independent evaluation-scene renderer: one bin of parts in BOP layout, rendered by Blender Cycles.

Run: blender -b --factory-startup -noaudio --python tools/benchgen/render_bin.py -- --models DIR
     --obj-ids 3,17 --camera CAM.json --out ROOT --split test --scene-id N --seed S
     [--samples 24] [--parts MIN,MAX] [--max-seconds 90] [--noise-probe]
Shares no code with vision/render. Writes ROOT/<split>/<NNNNNN>/ (image 0) as docs/datasets.md
describes, built in a temp folder and renamed into place, so an existing scene folder is complete.

Frames: Blender world = the camera's frame (camera at the origin, identity rotation, looking
along -Z, +Y up); OpenCV camera coords (x, y, z) = world (x, -y, -z). Unit: 1 Blender unit = 1 mm
everywhere, also for physics (gravity 9810 mm/s^2). Randomness: numpy PCG64 seeded by
(--seed, --scene-id); Cycles seeds derived from the same pair.
"""

import argparse, json, math, os, shutil, sys, time
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plymesh  # noqa: E402

import bpy  # noqa: E402
from mathutils.bvhtree import BVHTree  # noqa: E402

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


def parse_args(argv):
    p = argparse.ArgumentParser(prog='render_bin.py')
    for name in ('--models', '--obj-ids', '--camera', '--out'):
        p.add_argument(name, required=True)
    p.add_argument('--split', default='test')
    p.add_argument('--scene-id', type=int, required=True)
    p.add_argument('--seed', type=int, required=True)
    p.add_argument('--samples', type=int, default=24)
    p.add_argument('--parts', default='8,25')
    p.add_argument('--max-seconds', type=float, default=90.0, help='warn when a scene takes longer')
    p.add_argument('--noise-probe', action='store_true', help='2 more renders: Cycles noise of flash 0 in DN')
    a = p.parse_args(argv)
    a.obj_ids = [int(x) for x in a.obj_ids.split(',') if x]
    a.parts = tuple(int(x) for x in a.parts.split(','))
    if not 1 <= len(a.obj_ids) <= 3 or len(a.parts) != 2 or not 1 <= a.parts[0] <= a.parts[1]:
        p.error('--obj-ids needs 1-3 ids, --parts MIN,MAX with 1 <= MIN <= MAX')
    return a


def load_camera(path):
    """Camera file keys (OpenCV camera frame, mm): fx fy cx cy width height flash_positions_mm floor_distance_mm."""
    with open(path) as f:
        c = json.load(f)
    if abs(c['fx'] - c['fy']) > 1e-9 * c['fx']:
        raise SystemExit('camera %s: fx != fy (%g, %g): Blender has square pixels only' % (path, c['fx'], c['fy']))
    if len(c['flash_positions_mm']) != N_FLASH:
        raise SystemExit('camera %s: need %d flash positions' % (path, N_FLASH))
    c['width'], c['height'] = int(c['width']), int(c['height'])
    return c


def load_models(folder, ids):
    """Per obj_id: PLY mesh (model frame, mm) plus volume (mm^3) and convex hull vertices."""
    from scipy.spatial import ConvexHull
    with open(os.path.join(folder, 'models_info.json')) as f:
        info = json.load(f)
    models = {}
    for oid in ids:
        if str(oid) not in info:
            raise SystemExit('models_info.json has no object %d' % oid)
        m = plymesh.read_ply(os.path.join(folder, 'obj_%06d.ply' % oid))
        v, tri = m['vertices'], m['faces']
        a, b, c = v[tri[:, 0]], v[tri[:, 1]], v[tri[:, 2]]
        m['volume'] = abs(np.einsum('ij,ij->i', a, np.cross(b, c)).sum()) / 6.0
        hull = ConvexHull(v)
        m['hull'] = v[hull.vertices]
        m['radius'] = float(np.linalg.norm(m['hull'] - m['hull'].mean(0), axis=1).max())
        m['margin'], m['phys_hull'], m['phys_faces'] = shrunk_hull(v, hull)
        models[oid] = m
    return models


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


def cycles_seed(args, k):
    return (args.seed * 1000003 + args.scene_id * 7919 + k * 104729) % (2 ** 31 - 1)


# ------------------------------------------------------------------------------------------
# Scene layout (numpy only) and geometry in the world frame, mm.

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


# ------------------------------------------------------------------------------------------
# Blender scene: objects, camera, Cycles, materials, lights.

def reset_blender():
    for coll in (bpy.data.objects, bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras):
        for item in list(coll):
            coll.remove(item)


def mesh_object(name, verts, faces, normals=None):
    me = bpy.data.meshes.new(name)
    m = len(faces)
    me.vertices.add(len(verts))
    me.vertices.foreach_set('co', np.asarray(verts, np.float32).ravel())
    me.loops.add(3 * m)
    me.loops.foreach_set('vertex_index', np.asarray(faces, np.int32).ravel())
    me.polygons.add(m)
    me.polygons.foreach_set('loop_start', np.arange(0, 3 * m, 3, dtype=np.int32))
    me.polygons.foreach_set('loop_total', np.full(m, 3, np.int32))
    me.update(calc_edges=True)
    if normals is not None:  # PLY vertex normals as custom split normals: smooth where the file is
        n = normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        me.polygons.foreach_set('use_smooth', np.ones(m, bool))
        me.use_auto_smooth = True
        me.normals_split_custom_set_from_vertices(n.tolist())
    obj = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(obj)
    return obj


def setup_render(cam, samples):
    """Camera with projection = K (pixel centres at integer OpenCV coords); Cycles; returns check error px."""
    scene = bpy.context.scene
    W, H = cam['width'], cam['height']
    r = scene.render
    r.engine, r.resolution_x, r.resolution_y, r.resolution_percentage = 'CYCLES', W, H, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_persistent_data = True  # 9 renders of one scene reuse its BVH
    r.image_settings.file_format, r.image_settings.color_mode = 'OPEN_EXR', 'RGB'
    r.image_settings.color_depth, r.image_settings.exr_codec = '32', 'NONE'
    scene.view_settings.view_transform, scene.view_settings.look = 'Standard', 'None'
    scene.view_settings.exposure, scene.view_settings.gamma = 0.0, 1.0
    c = scene.cycles
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = 'CPU', samples, False, False
    for key, value in CYCLES.items():
        setattr(c, key, value)
    c.transmission_bounces = c.volume_bounces = c.transparent_max_bounces = 0
    c.caustics_reflective = c.caustics_refractive = False
    c.light_sampling_threshold = 0.0  # keep every light: no probabilistic light culling
    c.use_animated_seed = False
    world = bpy.data.worlds.new('black')
    world.use_nodes = True
    world.node_tree.nodes['Background'].inputs['Strength'].default_value = 0.0
    scene.world = world
    cd = bpy.data.cameras.new('cam')
    cd.sensor_fit, cd.sensor_width = 'HORIZONTAL', 36.0  # shift unit = the sensor width = W pixels
    cd.lens = cam['fx'] * 36.0 / W
    cd.shift_x = (W / 2.0 - cam['cx'] - 0.5) / W
    cd.shift_y = (cam['cy'] + 0.5 - H / 2.0) / W
    cd.clip_start, cd.clip_end = 1.0, 20000.0
    obj = bpy.data.objects.new('cam', cd)
    scene.collection.objects.link(obj)
    scene.camera = obj
    return camera_error(cam, obj)


def camera_error(cam, obj):
    """Max |Blender projection - K projection| in px over a grid of points in front of the camera."""
    from bpy_extras.object_utils import world_to_camera_view
    import mathutils
    bpy.context.view_layer.update()
    W, H = cam['width'], cam['height']
    err = 0.0
    for u in np.linspace(-0.2 * W, 1.2 * W, 5):
        for v in np.linspace(-0.2 * H, 1.2 * H, 5):
            for z in (100.0, 300.0):
                p = np.array([(u - cam['cx']) / cam['fx'] * z, -(v - cam['cy']) / cam['fy'] * z, -z])
                q = world_to_camera_view(bpy.context.scene, obj, mathutils.Vector(p.tolist()))
                err = max(err, abs(q.x * W - 0.5 - u), abs((1.0 - q.y) * H - 0.5 - v))
    if err > 1e-3:
        raise SystemExit('Blender camera does not reproduce K: %.4f px' % err)
    return err


def principled(name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    return mat, mat.node_tree, mat.node_tree.nodes['Principled BSDF']


def set_bsdf(b, **kw):
    for k, v in kw.items():
        b.inputs[k.replace('_', ' ').title()].default_value = v
    return {k: (list(v) if isinstance(v, tuple) else v) for k, v in kw.items()}


def metal_material(rng, name):
    mat, nt, b = principled(name)
    g = rng.uniform(0.55, 0.95)
    col = tuple(np.clip(g + rng.uniform(-0.04, 0.04, 3), 0, 1).tolist()) + (1.0,)
    p = set_bsdf(b, base_color=col, metallic=1.0, roughness=rng.uniform(0.12, 0.45),
                 anisotropic=rng.uniform(0.4, 0.9), anisotropic_rotation=rng.uniform(0.0, 1.0))
    tan = nt.nodes.new('ShaderNodeTangent')
    tan.direction_type, tan.axis = 'RADIAL', str(rng.choice(['X', 'Y', 'Z']))
    nt.links.new(tan.outputs['Tangent'], b.inputs['Tangent'])
    return mat, p | {'brush_axis': tan.axis}


def plastic_material(rng, name):
    import colorsys
    mat, _nt, b = principled(name)
    col = colorsys.hsv_to_rgb(rng.uniform(0, 1), rng.uniform(0.2, 0.9), rng.uniform(0.25, 0.9)) + (1.0,)
    return mat, set_bsdf(b, base_color=col, metallic=0.0, specular=0.5, roughness=rng.uniform(0.15, 0.7))


def painted_material(rng, name):
    """Procedural paint (object coords, mm) into the base colour: intensity edges that are no depth edges."""
    import colorsys
    mat, nt, b = principled(name)
    pattern = str(rng.choice(['noise', 'checker', 'wave']))
    size = rng.uniform(2.0, 8.0)  # mm: checker square, wave period, noise feature size
    cols = [colorsys.hsv_to_rgb(rng.uniform(0, 1), rng.uniform(0.1, 0.9), v) + (1.0,)
            for v in (rng.uniform(0.05, 0.35), rng.uniform(0.5, 0.95))]
    tex = nt.nodes.new({'noise': 'ShaderNodeTexNoise', 'checker': 'ShaderNodeTexChecker',
                        'wave': 'ShaderNodeTexWave'}[pattern])
    mapping, coords = nt.nodes.new('ShaderNodeMapping'), nt.nodes.new('ShaderNodeTexCoord')
    rot = rng.uniform(0, 2 * math.pi, 3)
    mapping.inputs['Rotation'].default_value = rot.tolist()
    mapping.inputs['Scale'].default_value = [{'noise': 1.0, 'checker': 1.0, 'wave': 0.314}[pattern] / size] * 3
    tex.inputs['Scale'].default_value = 1.0
    if pattern == 'wave':
        tex.bands_direction = 'X'
    if pattern == 'noise':
        tex.inputs['Detail'].default_value = rng.uniform(1.0, 4.0)
    ramp = nt.nodes.new('ShaderNodeValToRGB')
    ramp.color_ramp.interpolation = 'LINEAR' if pattern == 'wave' else 'CONSTANT'
    ramp.color_ramp.elements[0].color, ramp.color_ramp.elements[1].color = cols
    ramp.color_ramp.elements[1].position = 0.5
    nt.links.new(coords.outputs['Object'], mapping.inputs['Vector'])
    nt.links.new(mapping.outputs['Vector'], tex.inputs['Vector'])
    nt.links.new(tex.outputs['Fac'], ramp.inputs['Fac'])
    nt.links.new(ramp.outputs['Color'], b.inputs['Base Color'])
    p = set_bsdf(b, metallic=0.0, specular=0.5, roughness=rng.uniform(0.3, 0.8))
    return mat, p | {'pattern': pattern, 'size_mm': size, 'colors': [list(c) for c in cols], 'rotation': rot.tolist()}


def build_render_scene(rng, lay, models, types, poses, bin_vf, table_vf):
    """Bin, table and parts with their materials; returns the per-instance material record."""
    for name, (v, f), albedo in (('bin', bin_vf, lay['bin_albedo']), ('table', table_vf, lay['table_albedo'])):
        mat, _nt, b = principled(name)
        set_bsdf(b, base_color=(albedo, albedo, albedo, 1.0), specular=0.3, roughness=0.7)
        mesh_object(name, v, f).data.materials.append(mat)
    start = int(rng.integers(3))
    kinds = list(rng.permutation([('metal', 'plastic', 'painted')[(i + start) % 3] for i in range(len(types))]))
    makers = {'metal': metal_material, 'plastic': plastic_material, 'painted': painted_material}
    record = []
    for g, (oid, (R, t), kind) in enumerate(zip(types, poses, kinds)):
        m = models[oid]
        obj = mesh_object('part_%d' % g, m['vertices'], m['faces'], m['normals'])
        obj.matrix_world = matrix4(R, t)
        mat, params = makers[kind](rng, 'mat_%d' % g)
        obj.data.materials.append(mat)
        record.append({'instance': g, 'obj_id': oid, 'kind': kind, 'params': params})
    return record


def add_lights(lay, cam):
    """8 LED point lights at the flash positions and a dim square room light 1.5 m above the floor.

    Power units: Cycles point light irradiance = P / (4 pi d^2), so P = 4 pi^2 D^2 puts the floor
    irradiance at pi (radiance = albedo). The room light's power per floor irradiance, 8.3e-8, was
    measured for this 1.5 m square at 1.5 m; ambient_ratio sets it relative to a flash.
    """
    scene, leds = bpy.context.scene, []
    power = 4.0 * math.pi ** 2 * lay['floor_mm'] ** 2
    for k, p in enumerate(cam['flash_positions_mm']):
        ld = bpy.data.lights.new('led_%d' % k, 'POINT')
        ld.shadow_soft_size = lay['led_radius_mm']
        obj = bpy.data.objects.new('led_%d' % k, ld)
        obj.location = (FLIP @ np.asarray(p, float)).tolist()
        scene.collection.objects.link(obj)
        leds.append((obj, power))
    ad = bpy.data.lights.new('room', 'AREA')
    ad.shape, ad.size = 'SQUARE', 1500.0
    ad.energy = lay['ambient_ratio'] * math.pi / 8.3e-8
    obj = bpy.data.objects.new('room', ad)
    obj.location = (lay['room_light_xy'][0], lay['room_light_xy'][1], 1500.0 - lay['floor_mm'])
    scene.collection.objects.link(obj)
    return {'all': leds + [(obj, ad.energy)], 'led_power': power, 'room_power': ad.energy}


# ------------------------------------------------------------------------------------------
# Physics: convex-hull proxies dropped into a passive bin, stepped until they stop.

def spawn_poses(rng, lay, models, types, tries=24):
    """Random orientations; each part's box (bin frame) above the walls and above the boxes placed
    before it that it overlaps, at the lowest of `tries` random x/y spots: a compact, overlap-free drop."""
    placed, poses = [], []
    half = np.array(lay['inner']) / 2.0
    Rbin = bin_rotation(lay)
    for oid in types:
        q = rng.normal(size=4)
        R = quat_matrix(q / np.linalg.norm(q))
        h = models[oid]['hull'] @ R.T
        lo, hi = h.min(0), h.max(0)
        best = None
        for xy in rng.uniform(-1.0, 1.0, (tries, 2)):
            c = np.where(hi[:2] - lo[:2] < 2 * half, xy * (half - (hi[:2] - lo[:2]) / 2) - (lo[:2] + hi[:2]) / 2, 0.0)
            z = lay['wall_h'] + 2.0 - lo[2]
            for plo, phi in placed:
                if np.all(c + lo[:2] < phi[:2] + 1.0) and np.all(c + hi[:2] > plo[:2] - 1.0):
                    z = max(z, phi[2] + 1.0 - lo[2])
            if best is None or z < best[2]:
                best = np.array([c[0], c[1], z])
        placed.append((best + lo, best + hi))
        poses.append((Rbin @ R, bin_to_world(lay, best[None, :])[0]))
    return poses


def make_physics(lay, models, types, poses):
    """Rigid-body world at true scale (mm, 9810 mm/s^2, 480 Hz steps): passive BOX shapes for the
    bin's five slabs and the table (far steadier contacts than a triangle mesh), the parts active."""
    scene = bpy.context.scene
    bpy.ops.rigidbody.world_add()
    scene.rigidbody_world.substeps_per_frame, scene.rigidbody_world.solver_iterations = 20, 20
    scene.gravity, scene.render.fps = (0.0, 0.0, -9810.0), 24
    slabs = [(bin_rotation(lay), bin_to_world(lay, ((np.add(lo, hi)) / 2)[None, :])[0], np.subtract(hi, lo) / 2)
             for lo, hi in bin_boxes(lay)]
    tv, _tf = table_mesh(lay)
    slabs.append((np.eye(3), (tv.min(0) + tv.max(0)) / 2, (tv.max(0) - tv.min(0)) / 2))
    statics = []
    for j, (R, mid, half) in enumerate(slabs):  # BOX shapes are centred on the object origin
        statics.append(mesh_object('phys_static_%d' % j, *box_tris(-half, half)))
        statics[-1].matrix_world = matrix4(R, mid)
    bodies = []
    for i, (oid, (R, t)) in enumerate(zip(types, poses)):
        bodies.append(mesh_object('phys_%d' % i, models[oid]['phys_hull'], models[oid]['phys_faces']))
        bodies[-1].matrix_world = matrix4(R, t)
    for obj in statics + bodies:
        bpy.context.view_layer.objects.active = obj
        bpy.ops.rigidbody.object_add(type='PASSIVE' if obj in statics else 'ACTIVE')
        rb = obj.rigid_body
        rb.friction, rb.restitution, rb.use_margin, rb.collision_margin = 0.5, 0.05, True, 1.0
        rb.collision_shape = 'BOX' if obj in statics else 'CONVEX_HULL'  # a box keeps its margin inside
    for obj, oid in zip(bodies, types):
        rb = obj.rigid_body
        rb.collision_margin = models[oid]['margin']
        rb.mass = models[oid]['volume'] * 2.0e-6  # kg, 2 g/cm^3: only mass ratios matter
        rb.linear_damping, rb.angular_damping = 0.2, 0.6  # stops rolling cylinders sooner
        # Bullet sleeping (below 30 mm/s and 1 rad/s for 2 s) ends stacking jitter and friction creep;
        # at 480 Hz gravity alone adds 20 mm/s per step, so lower thresholds never let a part sleep.
        rb.use_deactivation = True
        rb.deactivate_linear_velocity, rb.deactivate_angular_velocity = 30.0, 1.0
    return bodies


def read_poses(bodies):
    deps = bpy.context.evaluated_depsgraph_get()
    out = []
    for obj in bodies:
        mw = np.array(obj.evaluated_get(deps).matrix_world, dtype=np.float64)
        out.append(orthonormal(mw[:3, :3], mw[:3, 3]))
    return out


def step_until_still(lay, bodies, hulls, first, cap, tol_mm=0.01, still_frames=3):
    """Step frames first..cap (24 per s) until every part inside the bin sleeps: no hull vertex
    moved > tol_mm per frame for still_frames frames."""
    scene = bpy.context.scene
    scene.rigidbody_world.point_cache.frame_start = first
    scene.rigidbody_world.point_cache.frame_end = cap
    scene.frame_start, scene.frame_end = first, cap
    prev, calm, frame = None, 0, first
    for frame in range(first, cap + 1):
        scene.frame_set(frame)
        pts = [R @ h.T + t[:, None] for (R, t), h in zip(read_poses(bodies), hulls)]
        if prev is not None:  # parts outside the bin will be removed: their motion does not count
            moves = [np.abs(a - b).max() for a, b in zip(pts, prev) if inside_bin(lay, a)]
            move = max(moves) if moves else 0.0
            calm = calm + 1 if move < tol_mm else 0
            if calm >= still_frames:
                return frame, True
        prev = pts
    return frame, False


def restart_from(bodies, poses):
    """Freeze current poses as a new start state (after parts were removed) and clear the cache."""
    for obj, (R, t) in zip(bodies, poses):
        obj.matrix_world = matrix4(R, t)
    bpy.context.scene.frame_set(1)
    bpy.ops.ptcache.free_bake_all()
    for obj, (R, t) in zip(bodies, poses):
        obj.matrix_world = matrix4(R, t)


def settle(lay, models, types, poses):
    bodies = make_physics(lay, models, types, poses)
    hulls = [models[o]['hull'] for o in types]
    frames, still = step_until_still(lay, bodies, hulls, 1, 200)
    final = read_poses(bodies)
    keep = [inside_bin(lay, R @ h.T + t[:, None]) for (R, t), h in zip(final, hulls)]
    log('settle: %d frames, %s, %d of %d parts inside the bin' % (frames, 'still' if still else 'MOVING at cap',
                                                                    sum(keep), len(keep)))
    report = {'frames': frames, 'still': still, 'dropped': len(types), 'removed_outside': len(keep) - sum(keep)}
    if not all(keep):
        for obj, k in zip(bodies, keep):
            if not k:
                bpy.data.objects.remove(obj)
        bodies = [b for b, k in zip(bodies, keep) if k]
        hulls = [h for h, k in zip(hulls, keep) if k]
        final = [p for p, k in zip(final, keep) if k]
        types = [o for o, k in zip(types, keep) if k]
        restart_from(bodies, final)
        f2, still2 = step_until_still(lay, bodies, hulls, 1, 120)
        again = read_poses(bodies)
        moved = max([np.abs((R2 - R) @ h.T + (t2 - t)[:, None]).max()
                     for (R, t), (R2, t2), h in zip(final, again, hulls)] + [0.0])
        final = again
        report.update({'resettle_frames': f2, 'resettle_still': still2, 'resettle_max_move_mm': float(moved)})
        log('settle: re-settled %d parts in %d frames (%s), moved up to %.2f mm'
            % (len(bodies), f2, 'still' if still2 else 'MOVING', moved))
    bpy.ops.rigidbody.world_remove()
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    return types, final, report


# ------------------------------------------------------------------------------------------
# Ground truth by ray casting through pixel centres (world = Blender camera frame).

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


# ------------------------------------------------------------------------------------------
# Rendering and sensor model.

def render_linear(path):
    """Render the scene to a float EXR and return its linear luminance (H, W), top row first."""
    r = bpy.context.scene.render
    r.filepath = path
    bpy.ops.render.render(write_still=True)
    img = bpy.data.images.load(path)
    W, H = r.resolution_x, r.resolution_y
    px = np.empty(W * H * 4, np.float32)
    img.pixels.foreach_get(px)
    bpy.data.images.remove(img)
    os.remove(path)
    rgb = px.reshape(H, W, 4)[::-1, :, :3].astype(np.float64)
    return rgb @ np.array([0.2126, 0.7152, 0.0722])  # Rec.709 luminance of linear RGB


def render_all(args, lights, tmp):
    """Linear luminance of LED k alone (k = 0..7), then of the room light alone.

    A flash image is LED k's render plus the room light's: exact by the linearity of light
    transport, and Cycles then spends no samples of a flash render on the dim room light."""
    out = [render_lit(args, lights, k, cycles_seed(args, k), os.path.join(tmp, 'r%d.exr' % k))
           for k in range(N_FLASH + 1)]
    return [im for im, _s in out], [s for _im, s in out]


def render_lit(args, lights, k, seed, path):
    """Render with only light k on (k = N_FLASH: the room light); returns (luminance, seconds)."""
    for j, (obj, power) in enumerate(lights['all']):
        obj.data.energy = power if j == k else 0.0
        obj.hide_render = j != k
    bpy.context.scene.cycles.seed = seed
    t0 = time.time()
    im = render_linear(path)
    log('render %s: %.1f s' % ('LED %d' % k if k < N_FLASH else 'room light', time.time() - t0))
    return im, time.time() - t0


def sensor(rng, images, floor_px, lay):
    """One gain per scene (flash-lit floor median -> lay['floor_dn']), read + shot noise, 8-bit.
    images: 8 LED-alone renders, then the room light's; flash k = LED k + room light."""
    room = images[N_FLASH]
    flashes = [im + room for im in images[:N_FLASH]]
    enough = floor_px.sum() >= 200
    med = [float(np.median(im[floor_px]) if enough else np.percentile(im, 90)) for im in flashes]
    gain = lay['floor_dn'] / max(np.mean(med), 1e-12)
    out = []
    for im in flashes + [room]:
        dn = gain * im
        sigma = np.sqrt(lay['read_noise_dn'] ** 2 + np.maximum(dn, 0.0) / lay['e_per_dn'])
        out.append(np.clip(np.rint(dn + sigma * rng.standard_normal(dn.shape)), 0, 255).astype(np.uint8))
    return out, gain


def noise_probe(args, lights, tmp, images, gain, floor_px):
    """Cycles noise of flash 0 (DN, after the gain, before sensor noise) on the floor, at least 3 px
    from anything else: LED 0 and the room light rendered again with other seeds.
    Returns (std, robust std = 1.4826 MAD) of the per-pixel difference / sqrt(2)."""
    from scipy.ndimage import binary_erosion
    core = binary_erosion(floor_px, iterations=3)
    led = render_lit(args, lights, 0, cycles_seed(args, 100), os.path.join(tmp, 'p0.exr'))[0]
    room = render_lit(args, lights, N_FLASH, cycles_seed(args, 101), os.path.join(tmp, 'p1.exr'))[0]
    d = gain * ((led + room) - (images[0] + images[N_FLASH]))[core] / math.sqrt(2.0)
    if d.size == 0:
        return None
    return {'std_dn': float(d.std()), 'robust_std_dn': float(1.4826 * np.median(np.abs(d - np.median(d)))),
            'pixels': int(d.size)}


# ------------------------------------------------------------------------------------------
# Output.

def save_png(arr, path):
    from PIL import Image
    Image.fromarray(arr).save(path)


def write_scene(tmp, cam, lay, poses, types, gt, depth, images):
    for sub in ('flash', 'ambient', 'depth', 'mask', 'mask_visib'):
        os.makedirs(os.path.join(tmp, sub), exist_ok=True)
    for k in range(N_FLASH):
        save_png(images[k], os.path.join(tmp, 'flash', '000000_%d.png' % k))
    save_png(images[N_FLASH], os.path.join(tmp, 'ambient', '000000.png'))
    save_png(np.clip(np.rint(depth / 0.1), 0, 65535).astype(np.uint16), os.path.join(tmp, 'depth', '000000.png'))
    for g, inst in enumerate(gt):
        save_png(inst['mask'].astype(np.uint8) * 255, os.path.join(tmp, 'mask', '000000_%06d.png' % g))
        save_png(inst['visib'].astype(np.uint8) * 255, os.path.join(tmp, 'mask_visib', '000000_%06d.png' % g))
    K = [cam['fx'], 0.0, cam['cx'], 0.0, cam['fy'], cam['cy'], 0.0, 0.0, 1.0]
    dump({'0': {'cam_K': K, 'depth_scale': 0.1, 'width': cam['width'], 'height': cam['height'],
                'flash_positions_mm': cam['flash_positions_mm'], 'working_distance_mm': lay['floor_mm']}},
         os.path.join(tmp, 'scene_camera.json'))
    entries = []
    for oid, (R, t) in zip(types, poses):
        Rc, tc = FLIP @ R, FLIP @ t  # model -> world -> OpenCV camera
        entries.append({'obj_id': int(oid), 'cam_R_m2c': Rc.ravel().tolist(), 'cam_t_m2c': tc.tolist()})
    dump({'0': entries}, os.path.join(tmp, 'scene_gt.json'))
    dump({'0': [inst['info'] for inst in gt]}, os.path.join(tmp, 'scene_gt_info.json'))


def dump(obj, path):
    with open(path, 'w') as f:
        json.dump(obj, f, indent=2)
        f.write('\n')


def write_root_files(args, cam):
    """ROOT/camera.json and ROOT/models (a copy of --models) when missing, so BopDataset can open ROOT."""
    path = os.path.join(args.out, 'camera.json')
    if not os.path.exists(path):
        dump({k: cam[k] for k in ('fx', 'fy', 'cx', 'cy', 'width', 'height')} | {'depth_scale': 0.1}, path + '.tmp')
        os.replace(path + '.tmp', path)
    models = os.path.join(args.out, 'models')
    if not os.path.exists(models) and os.path.realpath(args.models) != os.path.realpath(models):
        tmp = models + '.tmp-%d' % os.getpid()
        shutil.copytree(args.models, tmp)
        os.rename(tmp, models)


def main(argv):
    """Render one scene into a temp folder, then rename it into place; returns the summary line."""
    t_start = time.time()
    args = parse_args(argv)
    cam, models = load_camera(args.camera), load_models(args.models, args.obj_ids)
    split_dir = os.path.join(args.out, args.split)
    final_dir = os.path.join(split_dir, '%06d' % args.scene_id)
    if os.path.isdir(final_dir):
        log('scene %s exists: nothing to do' % final_dir)
        return 'benchgen: scene %d exists, skipped' % args.scene_id
    os.makedirs(split_dir, exist_ok=True)
    for old in os.listdir(split_dir):  # leftovers of interrupted runs of this scene
        if old.startswith('.tmp-%06d-' % args.scene_id):
            shutil.rmtree(os.path.join(split_dir, old), ignore_errors=True)
    tmp = os.path.join(split_dir, '.tmp-%06d-%d' % (args.scene_id, os.getpid()))
    os.makedirs(tmp)
    try:
        record = make_scene(args, cam, models, tmp)
        record['total_seconds'] = time.time() - t_start
        dump(record, os.path.join(tmp, 'scene_render.json'))
        write_root_files(args, cam)
        os.rename(tmp, final_dir)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    total = record['total_seconds']
    if total > args.max_seconds:
        log('WARNING: scene took %.1f s, over --max-seconds %.0f' % (total, args.max_seconds))
    noise = record['cycles_floor_noise_dn']
    return ('benchgen: scene %d: %d parts (%d dropped), gain %.4g, settle %.1f s, GT %.1f s, render %.1f s, total %.1f s%s'
            % (args.scene_id, len(record['instances']), record['physics']['dropped'], record['gain_dn_per_radiance'],
               record['settle_seconds'], record['gt_seconds'], sum(record['render_seconds']), total,
               '' if noise is None else ', Cycles noise on the floor %.2f DN (robust %.2f)'
               % (noise['std_dn'], noise['robust_std_dn'])))


def make_scene(args, cam, models, tmp):
    """Draw, settle, ray-cast GT, render, write the scene files into tmp; returns scene_render.json."""
    rng = np.random.default_rng([args.seed, args.scene_id])
    lay = draw_layout(rng, cam, args)
    types = draw_types(rng, args)
    reset_blender()
    t0 = time.time()
    types, poses, phys = settle(lay, models, types, spawn_poses(rng, lay, models, types))
    t_settle, t0 = time.time() - t0, time.time()
    bin_vf, table_vf = bin_mesh(lay), table_mesh(lay)
    parts = [((R @ models[o]['vertices'].T).T + t, models[o]['faces']) for (R, t), o in zip(poses, types)]
    depth, owner, gt = ground_truth(cam, parts, bin_vf, table_vf)
    t_gt = time.time() - t0
    log('GT: %d instances, %.1f s' % (len(gt), t_gt))
    cam_err = setup_render(cam, args.samples)
    mats = build_render_scene(rng, lay, models, types, poses, bin_vf, table_vf)
    lights = add_lights(lay, cam)
    bpy.context.scene.frame_set(1)
    images, secs = render_all(args, lights, tmp)
    floor_px = (owner == -2) & (np.abs(depth - lay['floor_mm']) < 0.01)  # bin floor seen directly
    frames8, gain = sensor(rng, images, floor_px, lay)
    noise = noise_probe(args, lights, tmp, images, gain, floor_px) if args.noise_probe else None
    write_scene(tmp, cam, lay, poses, types, gt, depth, frames8)
    amb = float(np.median(images[N_FLASH][floor_px]) * gain) if floor_px.any() else None
    log('sensor: gain %.4g DN per radiance unit, room light on the floor %s DN' % (gain, amb))
    return {'seed': args.seed, 'scene_id': args.scene_id, 'obj_ids': args.obj_ids, 'samples': args.samples,
            'floor_distance_mm': lay['floor_mm'], 'bin_inner_mm': lay['inner'], 'wall_height_mm': lay['wall_h'],
            'bin_albedo': lay['bin_albedo'], 'table_albedo': lay['table_albedo'], 'layout': lay,
            'instances': mats, 'physics': phys, 'camera_check_px': cam_err, 'cycles': CYCLES,
            'led_power': lights['led_power'], 'room_power': lights['room_power'], 'gain_dn_per_radiance': gain,
            'floor_px': int(floor_px.sum()), 'ambient_floor_dn': amb, 'cycles_floor_noise_dn': noise,
            'render_seconds': secs, 'settle_seconds': t_settle, 'gt_seconds': t_gt}


def run():
    """Exit status 0 with the summary on stdout, or 1 with the reason on stderr."""
    argv = sys.argv[sys.argv.index('--') + 1:] if '--' in sys.argv else []
    real_stdout = os.dup(1)
    os.dup2(2, 1)  # Blender's own render chatter goes to stderr; stdout keeps the summary line
    summary, code = None, 0
    try:
        summary = main(argv)
    except SystemExit as e:
        code = 0 if e.code in (0, None) else 1
        if code:
            log('error: %s' % e.code)
    except Exception:
        import traceback
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    os.dup2(real_stdout, 1)
    if summary:
        print(summary, flush=True)
    sys.exit(code)


if __name__ == '__main__':
    run()
