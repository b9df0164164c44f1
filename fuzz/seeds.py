#!/usr/bin/env python3
"""Writes the seed inputs of every harness into fuzz/corpus/<name>/seed-*: small valid files of
each format and near-valid ones (one field wrong), made here from the formats' definitions.
Inputs a fuzz run found (crash-*, added by hand as regressions) are left alone.
Run: python3 fuzz/seeds.py (idempotent)."""

import json
import math
import os
import struct
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)


def write(name, seed, data):
    d = os.path.join(HERE, "corpus", name)
    os.makedirs(d, exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(d, "seed-" + seed), "wb") as f:
        f.write(data)


# --- a box, the shape every mesh seed and the template database use --------------------------
BOX_V = [((-20 if i & 1 == 0 else 20), (-15 if i & 2 == 0 else 15), (-10 if i & 4 == 0 else 10)) for i in range(8)]
BOX_F = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
         (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]


def normal(t):
    a, b, c = (BOX_V[i] for i in t)
    u = [b[k] - a[k] for k in range(3)]
    v = [c[k] - a[k] for k in range(3)]
    n = [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    length = math.sqrt(sum(x * x for x in n))
    return [x / length for x in n]


# --- modbus_request_guard: MBAP frames --------------------------------------------------------
def mbap(tid, unit, pdu, protocol=0, length=None):
    return struct.pack(">HHHB", tid, protocol, len(pdu) + 1 if length is None else length, unit) + pdu


def modbus():
    n = "modbus_request_guard"
    write(n, "fc03-read-block", mbap(1, 1, struct.pack(">BHH", 0x03, 0, 64)))
    write(n, "fc04-read-pose", mbap(2, 1, struct.pack(">BHH", 0x04, 36, 14)))
    write(n, "fc06-write-command", mbap(3, 1, struct.pack(">BHH", 0x06, 0, 1)))
    write(n, "fc16-trigger", mbap(4, 1, struct.pack(">BHHB4H", 0x10, 0, 4, 8, 1, 7, 2, 0)))
    write(n, "fc16-robot-pose", mbap(5, 1, struct.pack(">BHHB14H", 0x10, 36, 14, 28, *range(14))))
    write(n, "fc23-read-write", mbap(6, 1, struct.pack(">BHHHHB2H", 0x17, 8, 10, 2, 2, 4, 5, 6)))
    write(n, "two-frames", mbap(7, 1, struct.pack(">BHH", 0x03, 0, 8)) + mbap(8, 1, struct.pack(">BHH", 0x06, 1, 3)))
    write(n, "fc01-coils", mbap(9, 1, struct.pack(">BHH", 0x01, 0, 8)))
    write(n, "fc16-count-mismatch", mbap(10, 1, struct.pack(">BHHB2H", 0x10, 0, 3, 4, 1, 2)))
    write(n, "fc23-write-outside", mbap(11, 1, struct.pack(">BHHHHB2H", 0x17, 0, 1, 10, 2, 4, 5, 6)))
    write(n, "bad-protocol", mbap(12, 1, struct.pack(">BHH", 0x03, 0, 1), protocol=1))
    write(n, "length-past-frame", mbap(13, 1, struct.pack(">BHH", 0x03, 0, 1), length=200))
    write(n, "short-header", b"\x00\x01\x00\x00\x00")
    write(n, "fc03-read-map-v4", mbap(14, 1, struct.pack(">BHH", 0x03, 0, 80)))
    write(n, "fc03-read-past-map", mbap(15, 1, struct.pack(">BHH", 0x03, 79, 2)))
    write(n, "fc16-look", mbap(16, 1, struct.pack(">BHHB4H", 0x10, 0, 4, 8, 5, 8, 2, 0)))
    write(n, "fc03-read-map-v5", mbap(17, 1, struct.pack(">BHH", 0x03, 0, 96)))
    write(n, "fc03-read-past-map-v5", mbap(18, 1, struct.pack(">BHH", 0x03, 95, 2)))
    write(n, "fc16-check-grip", mbap(19, 1, struct.pack(">BHHB6H", 0x10, 0, 6, 12, 6, 9, 2, 0, 1, 8)))


# --- camera_config: OpenCV FileStorage YAML / JSON / XML --------------------------------------
def camera():
    n = "camera_config"
    with open(os.path.join(ROOT, "config", "camera-sim.yaml")) as f:
        sim = f.read()
    write(n, "sim.yaml", sim)
    positions = []
    for i in range(8):
        a = math.radians(45 * i)
        positions += [round(40 * math.cos(a), 3), round(40 * math.sin(a), 3), 0.0]
    measured = sim[:sim.index("flashes:")] + (
        "flashes:\n   positions_mm: !!opencv-matrix\n      rows: 8\n      cols: 3\n      dt: d\n"
        "      data: [ " + ", ".join(repr(x) for x in positions) + " ]\n")
    write(n, "measured.yaml", measured)
    write(n, "hand-eye.yaml", sim + (
        "hand_eye:\n   mode: eye_in_hand\n   camera_pose: !!opencv-matrix\n      rows: 4\n      cols: 4\n"
        "      dt: d\n      data: [ 0., -1., 0., 42., 1., 0., 0., -27.5, 0., 0., 1., 95., 0., 0., 0., 1. ]\n"
        "   reprojection_rms_px: 0.21\n   residual_rms_mm: 0.4\n   views: 15\n"))
    write(n, "distortion-column.yaml", sim.replace("rows: 1\n   cols: 5", "rows: 5\n   cols: 1"))
    write(n, "count-6.yaml", sim.replace("count: 8", "count: 6"))
    write(n, "rows-huge.yaml", sim.replace("rows: 3", "rows: 2000000000", 1))
    write(n, "data-short.yaml", sim.replace("data: [ 0., 0., 0., 0., 0. ]", "data: [ 0., 0. ]"))
    # JSON is YAML to the reader (this one lacks keys); XML is refused.
    write(n, "json-missing-keys.json", '{"image_width": 640, "image_height": 480}')
    write(n, "not-yaml.xml", '<?xml version="1.0"?>\n<opencv_storage><image_width>640</image_width></opencv_storage>\n')


# --- mesh_stl, mesh_obj, mesh_ply -------------------------------------------------------------
def meshes():
    out = ["solid box"]
    for t in BOX_F:
        out.append(" facet normal %g %g %g\n  outer loop" % tuple(normal(t)))
        out += ["   vertex %g %g %g" % BOX_V[i] for i in t]
        out.append("  endloop\n endfacet")
    out.append("endsolid box\n")
    write("mesh_stl", "ascii-box.stl", "\n".join(out))
    binary = bytearray(b"binary box".ljust(80, b" ")) + struct.pack("<I", len(BOX_F))
    for t in BOX_F:
        binary += struct.pack("<3f", *normal(t))
        for i in t:
            binary += struct.pack("<3f", *BOX_V[i])
        binary += b"\0\0"
    write("mesh_stl", "binary-box.stl", bytes(binary))
    write("mesh_stl", "binary-count-too-big.stl", bytes(binary[:80]) + struct.pack("<I", 1000) + bytes(binary[84:]))
    write("mesh_stl", "ascii-two-solids.stl", "\n".join(out) + "\n".join(out).replace("solid box", "solid lid"))

    obj = ["# box"] + ["v %g %g %g" % v for v in BOX_V] + ["f %d %d %d" % tuple(i + 1 for i in t) for t in BOX_F]
    write("mesh_obj", "box.obj", "\n".join(obj) + "\n")
    normals = ["vn 0 0 -1", "vn 0 0 1", "vn 0 -1 0", "vn 0 1 0", "vn -1 0 0", "vn 1 0 0"]
    quads = ["f 1//1 3//1 4//1 2//1", "f 5//2 6//2 8//2 7//2", "f 1//3 2//3 6//3 5//3",
             "f 3//4 7//4 8//4 4//4", "f 1//5 5//5 7//5 3//5", "f 2//6 4//6 8//6 6//6"]
    write("mesh_obj", "quads-normals-groups.obj",
          "\n".join(["o box", "g bottom"] + ["v %g %g %g" % v for v in BOX_V] + normals + quads[:3] +
                    ["g top", "s 1", "usemtl none"] + quads[3:]) + "\n")
    write("mesh_obj", "negative-indices.obj",
          "\n".join(["v %g %g %g" % v for v in BOX_V] + ["f %d %d %d" % tuple(i - 8 for i in t) for t in BOX_F]) + "\n")
    write("mesh_obj", "index-out-of-range.obj", "\n".join(obj + ["f 1 2 9"]) + "\n")

    def ply(fmt, extra=""):
        head = ("ply\nformat %s 1.0\ncomment box\nelement vertex 8\nproperty float x\nproperty float y\n"
                "property float z\n%selement face 12\nproperty list uchar int vertex_indices\nend_header\n" % (fmt, extra))
        return head.encode()
    write("mesh_ply", "ascii-box.ply", ply("ascii") + "".join("%g %g %g\n" % v for v in BOX_V).encode() +
          "".join("3 %d %d %d\n" % t for t in BOX_F).encode())
    for fmt, e in (("binary_little_endian", "<"), ("binary_big_endian", ">")):
        body = b"".join(struct.pack(e + "3f", *v) for v in BOX_V)
        body += b"".join(struct.pack(e + "B3i", 3, *t) for t in BOX_F)
        write("mesh_ply", fmt + "-box.ply", ply(fmt) + body)
    colours = "property uchar red\nproperty uchar green\nproperty uchar blue\n"
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    head = ("ply\nformat ascii 1.0\nelement vertex 8\nproperty double x\nproperty double y\nproperty double z\n" +
            colours + "element face 6\nproperty list uint uint vertex_index\nelement edge 1\n"
            "property int vertex1\nproperty int vertex2\nend_header\n")
    write("mesh_ply", "ascii-quads-colours.ply", head + "".join("%g %g %g 200 100 50\n" % v for v in BOX_V) +
          "".join("4 %d %d %d %d\n" % q for q in quads) + "0 1\n")
    write("mesh_ply", "count-too-big.ply", ply("binary_little_endian").replace(b"vertex 8", b"vertex 2000000000") +
          b"\0" * 300)


# --- template_database: a .tdb of the box with two views (version 6; 5 for the refusal) --------
def tdb(version):
    p = bytearray()
    u8 = lambda v: p.extend(struct.pack("<B", v))
    i32 = lambda v: p.extend(struct.pack("<i", v))
    u32 = lambda v: p.extend(struct.pack("<I", v))
    f32 = lambda *v: p.extend(struct.pack("<%df" % len(v), *v))
    f64 = lambda *v: p.extend(struct.pack("<%dd" % len(v), *v))
    s = lambda t: (u32(len(t)), p.extend(t.encode()))
    s("box"); i32(7)
    u8(1); i32(2)                                   # symmetry z:2
    i32(640); i32(480); f64(1100, 0, 319.5, 0, 1100, 239.5, 0, 0, 1)
    u32(5); f64(0, 0, 0, 0, 0)
    u32(8)
    for i in range(8):
        a = math.radians(45 * i)
        f64(40 * math.cos(a), 40 * math.sin(a), 0)
    f64(300)                                        # working distance
    f64(300); f64(0, 0, 0); f64(53.85); i32(300); i32(120); u8(1)
    s("box")
    u32(len(BOX_V))
    for v in BOX_V:
        f32(*v)
    u32(len(BOX_F))
    for t in BOX_F:
        p.extend(struct.pack("<3I", *t))
    u32(2)
    for view in range(2):
        i32(view); f64(0, 0, 1)
        f64(1, 0, 0, 0, 1, 0, 0, 0, 1) if view == 0 else f64(-1, 0, 0, 0, -1, 0, 0, 0, 1)
        f64(0, 0, 300)
        i32(120); i32(80); i32(60); f32(40, 30)     # lines: q, size, origin
        u32(2)
        f32(-36, -27, 36, -27); i32(0); i32(72)
        f32(36, -27, 36, 27); i32(30); i32(54)
        u32(3)
        for k in range(3):
            f32(-36 + k, -27, 0.0, -20 + k, -15, 10)
        f32(-36, -27, 72, 54)
    if version >= 4:
        u32(72); f32(*[0.25] * 72)
        u32(0)
    if version >= 5:
        u8(1); i32(2)                               # views folded by z:2
    if version >= 6:                                # the part's turns
        f64(0, 0, 0); f64(1, 0, 0, 0, 1, 0, 0, 0, 1)  # centroid, principal axes
        u32(1)                                      # symmetries: the half turn about z
        u8(0); f64(-1, 0, 0, 0, -1, 0, 0, 0, 1); f64(0, 0, 0); f64(0, 0, 1); i32(2); f64(1)
        u32(1)                                      # alternatives: turned over about x
        u8(2); f64(1, 0, 0, 0, -1, 0, 0, 0, -1); f64(0, 0, 0); f64(1, 0, 0); i32(2); f64(0.5)
    header = b"MFCD-TDB" + struct.pack("<IIQII", version, 32, len(p), zlib.crc32(bytes(p)), 0)
    return header + bytes(p)


def templates():
    n = "template_database"
    for v in (5, 6):
        write(n, "box-v%d.tdb" % v, tdb(v))
    good = tdb(6)
    write(n, "version-7.tdb", good[:8] + struct.pack("<I", 7) + good[12:])
    write(n, "truncated-header.tdb", good[:20])
    bad = bytearray(good)
    struct.pack_into("<I", bad, 32, 0x7fffffff)      # part name length past the payload
    write(n, "name-length-huge.tdb", bytes(bad))


# --- bop_dataset: first byte picks the file (see fuzz/bop_dataset.cpp) ------------------------
def bop():
    n = "bop_dataset"
    info = {"1": {"diameter": 50.0, "min_x": -20.0, "min_y": -15.0, "min_z": -10.0, "size_x": 40.0, "size_y": 30.0,
                  "size_z": 20.0, "symmetries_discrete": [[-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}}
    flashes = [[round(40 * math.cos(math.radians(45 * i)), 3), round(40 * math.sin(math.radians(45 * i)), 3), 0]
               for i in range(8)]
    K = [1100.0, 0.0, 319.5, 0.0, 1100.0, 239.5, 0.0, 0.0, 1.0]
    cams = {"0": {"cam_K": K, "depth_scale": 0.1, "width": 640, "height": 480, "flash_positions_mm": flashes,
                  "working_distance_mm": 300.0},
            "3": {"cam_K": K}}
    gt = {"0": [{"obj_id": 1, "cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [0, 0, 300]},
                {"obj_id": 2, "cam_R_m2c": [0, -1, 0, 1, 0, 0, 0, 0, 1], "cam_t_m2c": [10, -5, 310]}], "3": []}
    gt_info = {"0": [{"bbox_obj": [10, 20, 30, 40], "bbox_visib": [12, 22, 20, 30], "px_count_all": 1200,
                      "px_count_valid": 1200, "px_count_visib": 600, "visib_fract": 0.5}], "3": []}
    camera = {"cx": 319.5, "cy": 239.5, "fx": 1100.0, "fy": 1100.0, "width": 640, "height": 480, "depth_scale": 0.1}
    files = [info, camera, cams, gt, gt_info]
    names = ["models-info", "camera", "scene-camera", "scene-gt", "scene-gt-info"]
    for i, (name, j) in enumerate(zip(names, files)):
        write(n, name, bytes([i]) + json.dumps(j).encode())
    write(n, "scene-camera-no-camera-json", bytes([2 + 5]) + json.dumps(cams).encode())
    write(n, "scene-camera-default-flashes", bytes([2 + 10]) + json.dumps({"0": {"cam_K": K}}).encode())
    write(n, "scene-camera-bad-K", bytes([2]) + json.dumps({"0": {"cam_K": K[:8]}}).encode())
    write(n, "models-info-bad-id", bytes([0]) + json.dumps({"one": info["1"]}).encode())
    write(n, "scene-gt-not-array", bytes([3]) + json.dumps({"0": {"obj_id": 1}}).encode())


# --- daemon_config: the project's own configurations and small variants ----------------------
def daemon():
    n = "daemon_config"
    for name in ("sim.yaml", "cell.yaml"):
        with open(os.path.join(ROOT, "config", name)) as f:
            write(n, name, f.read())
    minimal = "camera:\n  model: camera-sim.yaml\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n"
    write(n, "minimal.yaml", minimal)
    write(n, "from-camera-file.yaml",
          "camera:\n  model: camera-he.yaml\nrecipes:\n  - {id: 1, part: tnut, obj_id: 4, templates: templates/tnut.tdb}\n"
          "hand_eye:\n  setup: eye_to_hand\n  from_camera_file: true\n"
          "  part_T_grasp: {x_mm: 0, y_mm: 0, z_mm: 5, rx_deg: 0, ry_deg: 0, rz_deg: 0}\n")
    write(n, "unknown-key.yaml", minimal + "daemon:\n  cycle_budget: 100\n")
    write(n, "anchors.yaml", "pose: &p {x_mm: 1, y_mm: 2, z_mm: 3}\n" + minimal +
          "hand_eye:\n  setup: eye_to_hand\n  base_T_camera: *p\n")
    write(n, "not-a-mapping.yaml", "- camera\n- recipes\n")
    write(n, "aravis-camera-strobe.yaml",
          "camera:\n  model: camera-sim.yaml\n  type: aravis\n  device: Fake-GV01\n  exposure_us: 2000\n"
          "  gain: 1.5\n  packet_size: 8192\nlights:\n  type: camera\n  active_low: true\n  strobe_line: Line1\n"
          "  select_lines: [Line2, Line3, Line4]\nrecipes:\n  - {id: 0, part: any, obj_id: 0}\n")


# --- modbus_session: byte 0 picks the chunk sizes, the rest is the TCP stream -----------------
def session():
    n = "modbus_session"
    read_all = mbap(1, 1, bytes([0x03, 0, 0, 0, 64]))
    trigger = mbap(2, 1, bytes([0x10, 0, 0, 0, 4, 8, 0, 1, 0, 7, 0, 0, 0, 0]))
    pose = mbap(3, 1, bytes([0x10, 0, 36, 0, 14, 28]) + bytes(24) + bytes([0, 1, 0, 9]))
    write(n, "read-all", bytes([0x00]) + read_all)
    write(n, "poll-then-trigger", bytes([0x5A]) + read_all + trigger + read_all)
    write(n, "robot-pose", bytes([0xFF]) + pose)
    write(n, "pipelined", bytes([0x13]) + read_all * 6)
    write(n, "cut-off", bytes([0x01]) + read_all[:9])
    write(n, "bad-protocol", bytes([0x07]) + mbap(4, 1, bytes([0x03, 0, 0, 0, 1]), protocol=1) + read_all)
    read_map_v4 = mbap(5, 1, bytes([0x03, 0, 0, 0, 80]))
    look = mbap(6, 1, bytes([0x10, 0, 0, 0, 4, 8, 0, 5, 0, 8, 0, 0, 0, 0]))
    write(n, "trigger-then-look", bytes([0x33]) + trigger + read_map_v4 + look + read_map_v4)
    read_map_v5 = mbap(7, 1, bytes([0x03, 0, 0, 0, 96]))
    check_grip = mbap(8, 1, bytes([0x10, 0, 0, 0, 4, 8, 0, 6, 0, 9, 0, 0, 0, 0]))
    write(n, "trigger-then-check-grip", bytes([0x2C]) + trigger + read_map_v5 + check_grip + read_map_v5)


# --- control_line: one JSON request per line ---------------------------------------------------
def control():
    n = "control_line"
    write(n, "status", '{"cmd":"status"}\n')
    write(n, "trigger", '{"cmd":"trigger","recipe":3}\n{"cmd":"trigger","recipe":70000}\n{"cmd":"trigger","recipe":"x"}\n')
    write(n, "calibrate", '{"cmd":"calibrate","action":"capture","pose":[1,2,3,4,5,6],"confirm":true}\n'
          '{"cmd":"calibrate","action":5}\n{"cmd":"calibrate","pose":["a",2,3,4,5,6]}\n')
    write(n, "unknown-and-garbage", '{"cmd":"nope"}\n[1,2]\nnot json\n\n{"cmd":7}\n')
    write(n, "invalid-utf8", b'\xff\n{"cmd":"calibrate","action":"caf\xe9"}\n')


if __name__ == "__main__":
    modbus()
    camera()
    meshes()
    templates()
    bop()
    daemon()
    session()
    control()
