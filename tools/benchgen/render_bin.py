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
from benchgen_common import CYCLES, FLIP, N_FLASH, cycles_seed, log, shrunk_hull  # noqa: E402
from bin_layout import bin_mesh, draw_layout, draw_types, fit_bin_to_parts, table_mesh  # noqa: E402
from blender_scene import add_lights, build_render_scene, reset_blender, setup_render  # noqa: E402
from physics import settle, spawn_poses  # noqa: E402
from raycast_truth import ground_truth  # noqa: E402


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
    lay['bin_area_scale'] = fit_bin_to_parts(lay, models, types)
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
