"""The Blender scene: mesh objects, the camera matching K, Cycles settings, materials, lights."""

import math
import numpy as np
import bpy  # noqa: E402
from benchgen_common import CYCLES, FLIP  # noqa: E402
from bin_layout import matrix4  # noqa: E402


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


def camera_error(cam, obj, to_world=None):
    """Max |Blender projection - K projection| in px over a grid of points in front of the camera.
    to_world: (R, t) from the camera's Blender frame to the world, when the camera is not at the
    world origin (None: it is)."""
    from bpy_extras.object_utils import world_to_camera_view
    import mathutils
    bpy.context.view_layer.update()
    W, H = cam['width'], cam['height']
    err = 0.0
    for u in np.linspace(-0.2 * W, 1.2 * W, 5):
        for v in np.linspace(-0.2 * H, 1.2 * H, 5):
            for z in (100.0, 300.0):
                p = np.array([(u - cam['cx']) / cam['fx'] * z, -(v - cam['cy']) / cam['fy'] * z, -z])
                if to_world is not None:
                    p = to_world[0] @ p + to_world[1]
                q = world_to_camera_view(bpy.context.scene, obj, mathutils.Vector(p.tolist()))
                err = max(err, abs(q.x * W - 0.5 - u), abs((1.0 - q.y) * H - 0.5 - v))
    if err > 1e-3:
        raise SystemExit('Blender camera does not reproduce K: %.4f px' % err)
    return err


def move_camera(cam, lights, R_wc, t_wc):
    """The camera and its LED ring (flash_positions_mm, camera frame) to the pose (R_wc, t_wc):
    camera's Blender frame -> world. The room light stays. Returns camera_error at the new pose."""
    obj = bpy.context.scene.camera
    obj.matrix_world = matrix4(R_wc, t_wc)
    for (led, _power), p in zip(lights['all'], cam['flash_positions_mm']):
        led.location = (R_wc @ (FLIP @ np.asarray(p, float)) + t_wc).tolist()
    return camera_error(cam, obj, (R_wc, t_wc))


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
