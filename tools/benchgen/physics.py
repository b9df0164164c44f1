"""Physics: convex-hull proxies of the parts dropped into a passive bin (Blender rigid bodies),
stepped until they stop; parts that end outside the bin are removed and the rest settled again."""

import numpy as np
import bpy  # noqa: E402
from benchgen_common import log  # noqa: E402
from bin_layout import bin_boxes, bin_rotation, bin_to_world, box_tris, inside_bin, matrix4, orthonormal, quat_matrix, table_mesh  # noqa: E402
from blender_scene import mesh_object  # noqa: E402


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
