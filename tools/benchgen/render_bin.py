"""Independent evaluation-scene renderer: one bin of parts in BOP layout, rendered by Blender Cycles.

Run: blender -b --factory-startup -noaudio --python tools/benchgen/render_bin.py -- --models DIR
     --obj-ids 3,17 --camera CAM.json --out ROOT --split test --scene-id N --seed S
     [--samples 24] [--parts MIN,MAX] [--max-seconds 90] [--noise-probe] [--second-view-deg D]
Shares no code with vision/render. Writes ROOT/<split>/<NNNNNN>/ (image 0) as docs/datasets.md
describes, built in a temp folder and renamed into place, so an existing scene folder is complete.

--second-view-deg D (default 0: image 0 only, the files of a run without the option): image 1 of
the same settled scene, seen by camera 0 turned by D degrees about the axis parallel to its x axis
through (0, 0, floor) (OpenCV camera-0 frame; benchgen_common.second_view_pose): p1 = R p0 + t,
R = Rx(D), t = c - R c. D > 0 moves the camera towards the top edge of image 0. The LED ring moves
with the camera, the room light stays; image 1 has its own 8 flashes + ambient with image 0's
gain (fixed exposure), its own ray-cast ground truth, and both images get cam_R_w2c / cam_t_w2c
(world = camera 0's OpenCV frame). Image 0 is the same as without the option.

Frames: Blender world = camera 0's frame (camera at the origin, identity rotation, looking
along -Z, +Y up); OpenCV camera coords (x, y, z) = world (x, -y, -z). Unit: 1 Blender unit = 1 mm
everywhere, also for physics (gravity 9810 mm/s^2). Randomness: numpy PCG64 seeded by
(--seed, --scene-id); Cycles seeds derived from the same pair.
"""

import argparse, json, math, os, shutil, sys, time
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import plymesh  # noqa: E402

import bpy  # noqa: E402
from benchgen_common import CYCLES, FLIP, N_FLASH, cycles_seed, log, second_view_pose, shrunk_hull  # noqa: E402
from bin_layout import bin_mesh, draw_layout, draw_types, fit_bin_to_parts, table_mesh  # noqa: E402
from blender_scene import add_lights, build_render_scene, move_camera, reset_blender, setup_render  # noqa: E402
from physics import settle, spawn_poses  # noqa: E402
from raycast_truth import ground_truth  # noqa: E402

# --second-view-deg's limit: at 60 degrees camera 1 is still floor * cos 60 (~150 mm) above the bin
# floor, over its walls (at most ~90 mm); much more and it looks along the floor.
MAX_SECOND_VIEW_DEG = 60.0
SECOND_VIEW_SEED = 200  # Cycles seeds of image 1: cycles_seed(args, 200 + k) (image 0: k, probe: 100, 101)


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
    p.add_argument('--second-view-deg', type=float, default=0.0,
                   help='image 1: camera 0 turned by D degrees about its x axis through (0, 0, floor), its optical '
                        "axis' point at the bin floor's depth; D > 0 moves it towards image 0's top edge "
                        '(default 0: no second image; |D| <= %g)' % MAX_SECOND_VIEW_DEG)
    a = p.parse_args(argv)
    if not abs(a.second_view_deg) <= MAX_SECOND_VIEW_DEG:
        p.error('--second-view-deg must lie within +-%g degrees' % MAX_SECOND_VIEW_DEG)
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


def render_all(args, lights, tmp, view=0):
    """Linear luminance of LED k alone (k = 0..7), then of the room light alone.

    A flash image is LED k's render plus the room light's: exact by the linearity of light
    transport, and Cycles then spends no samples of a flash render on the dim room light.
    view 1 (the second view): other Cycles seeds, other temp files."""
    first, name = (0, 'r%d.exr') if view == 0 else (SECOND_VIEW_SEED, 'v%d_r%%d.exr' % view)
    out = [render_lit(args, lights, k, cycles_seed(args, first + k), os.path.join(tmp, name % k), view)
           for k in range(N_FLASH + 1)]
    return [im for im, _s in out], [s for _im, s in out]


def render_lit(args, lights, k, seed, path, view=0):
    """Render with only light k on (k = N_FLASH: the room light); returns (luminance, seconds)."""
    for j, (obj, power) in enumerate(lights['all']):
        obj.data.energy = power if j == k else 0.0
        obj.hide_render = j != k
    bpy.context.scene.cycles.seed = seed
    t0 = time.time()
    im = render_linear(path)
    log('render %s%s: %.1f s' % ('image %d ' % view if view else '', 'LED %d' % k if k < N_FLASH else 'room light',
                                 time.time() - t0))
    return im, time.time() - t0


def sensor(rng, images, floor_px, lay):
    """One gain per scene (flash-lit floor median -> lay['floor_dn']), read + shot noise, 8-bit.
    images: 8 LED-alone renders, then the room light's; flash k = LED k + room light."""
    gain = sensor_gain(images, floor_px, lay)
    return sensor_apply(rng, images, gain, lay), gain


def sensor_gain(images, floor_px, lay):
    """The scene's gain: the mean over the flashes of the flash-lit floor's median -> lay['floor_dn']."""
    room = images[N_FLASH]
    flashes = [im + room for im in images[:N_FLASH]]
    enough = floor_px.sum() >= 200
    med = [float(np.median(im[floor_px]) if enough else np.percentile(im, 90)) for im in flashes]
    return lay['floor_dn'] / max(np.mean(med), 1e-12)


def sensor_apply(rng, images, gain, lay):
    """The 8 flash images and the ambient one in DN: gain, read + shot noise, rounded to 8 bit."""
    room = images[N_FLASH]
    flashes = [im + room for im in images[:N_FLASH]]
    out = []
    for im in flashes + [room]:
        dn = gain * im
        sigma = np.sqrt(lay['read_noise_dn'] ** 2 + np.maximum(dn, 0.0) / lay['e_per_dn'])
        out.append(np.clip(np.rint(dn + sigma * rng.standard_normal(dn.shape)), 0, 255).astype(np.uint8))
    return out


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


def write_scene(tmp, cam, lay, types, views):
    """views: per image id, {'poses' (world = Blender camera 0), 'gt', 'depth', 'images', and for
    two views 'w2c' = (R, t): OpenCV camera 0 -> OpenCV camera of the image}."""
    cams, gts, infos = {}, {}, {}
    for iid, v in enumerate(views):
        cams[str(iid)], gts[str(iid)], infos[str(iid)] = write_image(tmp, iid, cam, lay, types, v)
    dump(cams, os.path.join(tmp, 'scene_camera.json'))
    dump(gts, os.path.join(tmp, 'scene_gt.json'))
    dump(infos, os.path.join(tmp, 'scene_gt_info.json'))


def write_image(tmp, iid, cam, lay, types, view):
    """One image's PNGs; returns its scene_camera, scene_gt and scene_gt_info entries."""
    tag = '%06d' % iid
    gt, depth, images = view['gt'], view['depth'], view['images']
    for sub in ('flash', 'ambient', 'depth', 'mask', 'mask_visib'):
        os.makedirs(os.path.join(tmp, sub), exist_ok=True)
    for k in range(N_FLASH):
        save_png(images[k], os.path.join(tmp, 'flash', '%s_%d.png' % (tag, k)))
    save_png(images[N_FLASH], os.path.join(tmp, 'ambient', tag + '.png'))
    save_png(np.clip(np.rint(depth / 0.1), 0, 65535).astype(np.uint16), os.path.join(tmp, 'depth', tag + '.png'))
    for g, inst in enumerate(gt):
        save_png(inst['mask'].astype(np.uint8) * 255, os.path.join(tmp, 'mask', '%s_%06d.png' % (tag, g)))
        save_png(inst['visib'].astype(np.uint8) * 255, os.path.join(tmp, 'mask_visib', '%s_%06d.png' % (tag, g)))
    K = [cam['fx'], 0.0, cam['cx'], 0.0, cam['fy'], cam['cy'], 0.0, 0.0, 1.0]
    # working_distance_mm: along the optical axis to the pivot (0, 0, floor), the same in both views.
    entry = {'cam_K': K, 'depth_scale': 0.1, 'width': cam['width'], 'height': cam['height'],
             'flash_positions_mm': cam['flash_positions_mm'], 'working_distance_mm': lay['floor_mm']}
    R_w2c, t_w2c = view.get('w2c', (np.eye(3), np.zeros(3)))
    if 'w2c' in view:
        entry |= {'cam_R_w2c': R_w2c.ravel().tolist(), 'cam_t_w2c': t_w2c.tolist()}
    entries = []
    for oid, (R, t) in zip(types, view['poses']):
        Rc, tc = FLIP @ R, FLIP @ t  # model -> world -> OpenCV camera 0
        if iid:
            Rc, tc = R_w2c @ Rc, R_w2c @ tc + t_w2c  # -> OpenCV camera of this image
        entries.append({'obj_id': int(oid), 'cam_R_m2c': Rc.ravel().tolist(), 'cam_t_m2c': tc.tolist()})
    return entry, entries, [inst['info'] for inst in gt]


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
    second = record.get('second_view')
    return ('benchgen: scene %d: %d parts (%d dropped), gain %.4g, settle %.1f s, GT %.1f s, render %.1f s, total %.1f s%s%s'
            % (args.scene_id, len(record['instances']), record['physics']['dropped'], record['gain_dn_per_radiance'],
               record['settle_seconds'], record['gt_seconds'], sum(record['render_seconds']), total,
               '' if noise is None else ', Cycles noise on the floor %.2f DN (robust %.2f)'
               % (noise['std_dn'], noise['robust_std_dn']),
               '' if second is None else '; image 1 at %g deg: GT %.1f s, render %.1f s'
               % (args.second_view_deg, second['gt_seconds'], sum(second['render_seconds']))))


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
    views = [{'poses': poses, 'gt': gt, 'depth': depth, 'images': frames8}]
    amb = float(np.median(images[N_FLASH][floor_px]) * gain) if floor_px.any() else None
    log('sensor: gain %.4g DN per radiance unit, room light on the floor %s DN' % (gain, amb))
    record = {'seed': args.seed, 'scene_id': args.scene_id, 'obj_ids': args.obj_ids, 'samples': args.samples,
              'floor_distance_mm': lay['floor_mm'], 'bin_inner_mm': lay['inner'], 'wall_height_mm': lay['wall_h'],
              'bin_albedo': lay['bin_albedo'], 'table_albedo': lay['table_albedo'], 'layout': lay,
              'instances': mats, 'physics': phys, 'camera_check_px': cam_err, 'cycles': CYCLES,
              'led_power': lights['led_power'], 'room_power': lights['room_power'], 'gain_dn_per_radiance': gain,
              'floor_px': int(floor_px.sum()), 'ambient_floor_dn': amb, 'cycles_floor_noise_dn': noise,
              'render_seconds': secs, 'settle_seconds': t_settle, 'gt_seconds': t_gt}
    if args.second_view_deg:  # absent from a one-view scene's record: 0
        record['second_view_deg'] = args.second_view_deg
        view, record['second_view'] = second_view(args, cam, lay, lights, tmp, rng, gain, parts, bin_vf, table_vf)
        views[0]['w2c'] = (np.eye(3), np.zeros(3))
        views.append(view | {'poses': poses})
    write_scene(tmp, cam, lay, types, views)
    return record


def second_view(args, cam, lay, lights, tmp, rng, gain, parts, bin_vf, table_vf):
    """Image 1: the camera and its LEDs turned (second_view_pose), GT ray-cast in its frame,
    rendered and put through the sensor with image 0's gain. Returns (view, its record)."""
    R, t = second_view_pose(args.second_view_deg, lay['floor_mm'])  # OpenCV camera 0 -> camera 1
    M, m = FLIP @ R @ FLIP, FLIP @ t  # the same in Blender frames: world (camera 0) -> camera 1
    t0 = time.time()
    to1 = lambda v: v @ M.T + m  # noqa: E731
    depth, owner, gt = ground_truth(cam, [(to1(v), f) for v, f in parts], (to1(bin_vf[0]), bin_vf[1]),
                                    (to1(table_vf[0]), table_vf[1]))
    t_gt = time.time() - t0
    log('GT image 1: %d instances, %.1f s' % (len(gt), t_gt))
    cam_err = move_camera(cam, lights, M.T, -M.T @ m)  # camera 1's Blender frame -> world
    images, secs = render_all(args, lights, tmp, view=1)
    frames8 = sensor_apply(rng, images, gain, lay)  # fixed exposure: image 0's gain
    # The bin floor seen directly: its points lie on the plane z = floor of camera 0's OpenCV frame.
    H, W = depth.shape
    vs, us = np.mgrid[0:H, 0:W]
    p1 = np.stack([(us - cam['cx']) / cam['fx'] * depth, (vs - cam['cy']) / cam['fy'] * depth, depth], -1)
    z0 = ((p1 - t) @ R)[..., 2]  # R^T (p1 - t), row-wise
    floor_px = (owner == -2) & (depth > 0) & (np.abs(z0 - lay['floor_mm']) < 0.01)
    flash_dn = float(np.median(np.mean(frames8[:N_FLASH], axis=0)[floor_px])) if floor_px.any() else None
    amb = float(np.median(images[N_FLASH][floor_px]) * gain) if floor_px.any() else None
    log('image 1: %.4g deg, floor %d px at %s DN in the flashes, room light %s DN'
        % (args.second_view_deg, floor_px.sum(), flash_dn, amb))
    centre = -R.T @ t
    record = {'cam_R_w2c': R.ravel().tolist(), 'cam_t_w2c': t.tolist(), 'camera_centre_mm': centre.tolist(),
              'camera_check_px': cam_err, 'floor_px': int(floor_px.sum()), 'flash_floor_dn': flash_dn,
              'ambient_floor_dn': amb, 'render_seconds': secs, 'gt_seconds': t_gt}
    return {'gt': gt, 'depth': depth, 'images': frames8, 'w2c': (R, t)}, record


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
