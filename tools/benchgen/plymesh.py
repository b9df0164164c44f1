"""Minimal PLY reader shared by render_bin.py (inside Blender) and check_scene.py.

Contract: read_ply(path) -> dict with
  'vertices'  float64 (N, 3), the file's own frame and unit (BOP models: mm),
  'normals'   float64 (N, 3) or None when the file has no nx ny nz,
  'faces'     int64 (M, 3), polygons fan-triangulated in file order.
Handles ASCII and binary (little or big endian) files with any extra elements or
properties; only numpy is required so it runs in Blender's Python as well.
"""

import numpy as np

_SCALARS = {
    'char': 'i1', 'int8': 'i1', 'uchar': 'u1', 'uint8': 'u1',
    'short': 'i2', 'int16': 'i2', 'ushort': 'u2', 'uint16': 'u2',
    'int': 'i4', 'int32': 'i4', 'uint': 'u4', 'uint32': 'u4',
    'float': 'f4', 'float32': 'f4', 'double': 'f8', 'float64': 'f8',
}


def _parse_header(f):
    """Return (format, elements); elements = [(name, count, [(prop, type, list_count_type)])]."""
    if f.readline().strip() != b'ply':
        raise ValueError('not a PLY file')
    fmt, elements = None, []
    while True:
        line = f.readline()
        if not line:
            raise ValueError('PLY header has no end_header')
        words = line.decode('ascii', 'replace').split()
        if not words or words[0] in ('comment', 'obj_info'):
            continue
        if words[0] == 'end_header':
            return fmt, elements
        if words[0] == 'format':
            fmt = words[1]
        elif words[0] == 'element':
            elements.append((words[1], int(words[2]), []))
        elif words[0] == 'property':
            if words[1] == 'list':
                elements[-1][2].append((words[4], words[3], words[2]))
            else:
                elements[-1][2].append((words[2], words[1], None))


def _read_ascii(f, elements):
    tokens = f.read().split()
    pos, out = 0, {}
    for name, count, props in elements:
        has_list = any(p[2] for p in props)
        if not has_list:
            n = len(props)
            block = np.array(tokens[pos:pos + n * count], dtype=np.float64).reshape(count, n)
            pos += n * count
            out[name] = {p[0]: block[:, i] for i, p in enumerate(props)}
            continue
        rows = {p[0]: [] for p in props}
        for _ in range(count):
            for pname, _t, ltype in props:
                if ltype:
                    k = int(tokens[pos])
                    rows[pname].append([int(float(x)) for x in tokens[pos + 1:pos + 1 + k]])
                    pos += 1 + k
                else:
                    rows[pname].append(float(tokens[pos]))
                    pos += 1
        out[name] = rows
    return out


def _read_binary(data, elements, endian):
    pos, out = 0, {}
    for name, count, props in elements:
        if not any(p[2] for p in props):
            dt = np.dtype([(p[0], endian + _SCALARS[p[1]]) for p in props])
            arr = np.frombuffer(data, dtype=dt, count=count, offset=pos)
            pos += dt.itemsize * count
            out[name] = {p[0]: arr[p[0]].astype(np.float64) for p in props}
            continue
        fast = _binary_triangles(data, pos, count, props, endian)
        if fast is not None:
            out[name], pos = fast
            continue
        rows = {p[0]: [] for p in props}
        for _ in range(count):
            for pname, ptype, ltype in props:
                if ltype:
                    lt = np.dtype(endian + _SCALARS[ltype])
                    k = int(np.frombuffer(data, lt, 1, pos)[0])
                    pos += lt.itemsize
                    it = np.dtype(endian + _SCALARS[ptype])
                    rows[pname].append(np.frombuffer(data, it, k, pos).tolist())
                    pos += it.itemsize * k
                else:
                    st = np.dtype(endian + _SCALARS[ptype])
                    rows[pname].append(float(np.frombuffer(data, st, 1, pos)[0]))
                    pos += st.itemsize
        out[name] = rows
    return out


def _binary_triangles(data, pos, count, props, endian):
    """Fast path: a face element holding only one list property whose lists all have 3 entries."""
    if len(props) != 1 or count == 0:
        return None
    pname, ptype, ltype = props[0]
    dt = np.dtype([('n', endian + _SCALARS[ltype]), ('v', endian + _SCALARS[ptype], (3,))])
    if pos + dt.itemsize * count > len(data):
        return None
    arr = np.frombuffer(data, dtype=dt, count=count, offset=pos)
    if not np.all(arr['n'] == 3):
        return None
    return {pname: arr['v'].astype(np.int64)}, pos + dt.itemsize * count


def _triangulate(polys):
    if isinstance(polys, np.ndarray):
        return polys.astype(np.int64).reshape(-1, 3)
    tris = []
    for p in polys:
        for i in range(1, len(p) - 1):
            tris.append((p[0], p[i], p[i + 1]))
    return np.array(tris, dtype=np.int64).reshape(-1, 3)


def read_ply(path):
    with open(path, 'rb') as f:
        fmt, elements = _parse_header(f)
        if fmt == 'ascii':
            data = _read_ascii(f, elements)
        elif fmt in ('binary_little_endian', 'binary_big_endian'):
            data = _read_binary(f.read(), elements, '<' if fmt == 'binary_little_endian' else '>')
        else:
            raise ValueError('%s: unknown PLY format %r' % (path, fmt))
    vert = data.get('vertex')
    if vert is None or 'face' not in data:
        raise ValueError('%s: PLY needs vertex and face elements' % path)
    v = np.stack([np.asarray(vert[k], np.float64) for k in ('x', 'y', 'z')], axis=1)
    normals = None
    if all(k in vert for k in ('nx', 'ny', 'nz')):
        normals = np.stack([np.asarray(vert[k], np.float64) for k in ('nx', 'ny', 'nz')], axis=1)
    face = data['face']
    key = 'vertex_indices' if 'vertex_indices' in face else 'vertex_index'
    if key not in face:
        raise ValueError('%s: face element has no vertex_indices' % path)
    faces = _triangulate(face[key])
    if faces.size and (faces.min() < 0 or faces.max() >= len(v)):
        raise ValueError('%s: face index out of range' % path)
    return {'vertices': v, 'normals': normals, 'faces': faces}
