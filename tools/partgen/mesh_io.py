"""Triangle-mesh input, checks, crease-angle normals and PLY output for partgen.

Contract: meshes are (V, F) with V a float64 (n, 3) array in millimetres and F an
int64 (m, 3) array of counter-clockwise (seen from outside) vertex indices.
Nothing here depends on the part family.
"""

import numpy as np

CREASE_ANGLE_DEG = 30.0


def read_off(path):
    """Reads an OFF file as written by OpenSCAD (indexed, triangulated or polygonal).

    Polygons with more than three corners are fanned into triangles. Returns (V, F).
    """
    with open(path, "r", encoding="ascii") as f:
        tokens = f.read().split()
    if not tokens or tokens[0] != "OFF":
        raise ValueError(f"{path}: not an OFF file")
    nv, nf = int(tokens[1]), int(tokens[2])
    pos = 4
    V = np.array(tokens[pos:pos + 3 * nv], dtype=np.float64).reshape(nv, 3)
    pos += 3 * nv
    tris = []
    for _ in range(nf):
        k = int(tokens[pos])
        idx = [int(t) for t in tokens[pos + 1:pos + 1 + k]]
        pos += 1 + k
        for j in range(1, k - 1):
            tris.append((idx[0], idx[j], idx[j + 1]))
    return V, np.array(tris, dtype=np.int64).reshape(-1, 3)


def weld(V, F, rel_eps=2e-6):
    """Merges vertices closer than rel_eps * largest extent (mm) and drops faces that
    then repeat a vertex, and pairs of opposite faces on the same three vertices.

    OpenSCAD prints 6 significant digits, so vertices that CGAL keeps apart by less
    than that print (almost) alike; merging them makes the connectivity follow the
    printed geometry instead of leaving needle triangles.
    """
    from scipy.spatial import cKDTree
    eps = max(1e-7, rel_eps * float(np.max(np.ptp(V, axis=0))))
    # Lexicographic vertex order first: OpenSCAD's output order varies from run to
    # run (same triangles, other order), the result must not.
    order = np.lexsort((V[:, 2], V[:, 1], V[:, 0]))
    rank = np.empty(len(V), dtype=np.int64)
    rank[order] = np.arange(len(V))
    V, F = V[order], rank[F]
    parent = np.arange(len(V))
    for i, j in sorted(cKDTree(V).query_pairs(eps)):
        ri, rj = i, j
        while parent[ri] != ri:
            ri = parent[ri]
        while parent[rj] != rj:
            rj = parent[rj]
        if ri != rj:
            parent[max(ri, rj)] = min(ri, rj)
    for i in range(len(V)):
        r = i
        while parent[r] != r:
            r = parent[r]
        parent[i] = r
    used, inverse = np.unique(parent, return_inverse=True)
    V2 = V[used]
    F2 = inverse[F]
    keep = (F2[:, 0] != F2[:, 1]) & (F2[:, 1] != F2[:, 2]) & (F2[:, 2] != F2[:, 0])
    F2 = F2[keep]
    # Opposite faces on one vertex triple (a fin left by a merge) cancel out.
    key = np.sort(F2, axis=1)
    _, first, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    if np.any(counts > 1):
        dup = set(map(tuple, key[first[counts > 1]].tolist()))
        F2 = F2[[tuple(k) not in dup for k in key.tolist()]]
    # Vertices no face uses any more are dropped.
    used_v, inv = np.unique(F2, return_inverse=True)
    return V2[used_v], canonical_faces(inv.reshape(-1, 3))


def canonical_faces(F):
    """Faces in a canonical order: each rotated to start at its smallest index (the
    winding kept), then sorted. Makes the output independent of the input's order."""
    F = np.asarray(F, dtype=np.int64)
    k = np.argmin(F, axis=1)
    idx = (k[:, None] + np.arange(3)[None, :]) % 3
    R = np.take_along_axis(F, idx, axis=1)
    return R[np.lexsort((R[:, 2], R[:, 1], R[:, 0]))]


def face_normals_areas(V, F):
    """Unit face normals (zero for degenerate faces) and face areas (mm^2)."""
    cr = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    dbl = np.linalg.norm(cr, axis=1)
    n = np.zeros_like(cr)
    ok = dbl > 0
    n[ok] = cr[ok] / dbl[ok, None]
    return n, 0.5 * dbl


def _edge_keys(F):
    """Directed edges (i -> j) of every face, as an (3m, 2) array, face-major order."""
    return np.stack([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]], axis=1).reshape(-1, 2)


def fix_slivers(V, F, rel_eps=1e-9, max_rounds=50):
    """Removes zero-area (collinear) triangles by flipping the edge they share with
    the neighbour across their longest edge, so the mesh stays closed.

    Such slivers appear when OpenSCAD's 6-digit output puts a vertex on an edge.
    A sliver (a, b, c) with c on edge ab and neighbour (b, a, d) becomes (b, c, d),
    (c, a, d): the neighbour is split at c and the sliver disappears. Returns (F, number of slivers removed).
    """
    F = F.copy()
    removed = 0
    scale = float(np.max(np.ptp(V, axis=0))) ** 2
    for _ in range(max_rounds):
        _, area = face_normals_areas(V, F)
        bad = np.nonzero(area <= rel_eps * scale)[0]
        if len(bad) == 0:
            break
        edge_face = {}
        for fi, tri in enumerate(F):
            for k in range(3):
                edge_face[(int(tri[k]), int(tri[(k + 1) % 3]))] = fi
        dead = set()
        changed = False
        for fi in bad:
            if fi in dead:
                continue
            tri = [int(x) for x in F[fi]]
            lens = [np.linalg.norm(V[tri[(k + 1) % 3]] - V[tri[k]]) for k in range(3)]
            k = int(np.argmax(lens))
            a, b, c = tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]
            g = edge_face.get((b, a))
            if g is None or g in dead or g == fi:
                continue
            d = [int(x) for x in F[g] if x not in (a, b)]
            if len(d) != 1:
                continue
            F[fi] = (b, c, d[0])
            F[g] = (c, a, d[0])
            dead.update((fi, g))
            changed = True
        if not changed:
            break
        F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
        removed += len(dead) // 2
    return F, removed


def signed_volume(V, F):
    """Enclosed volume in mm^3; positive when the faces wind outward."""
    a, b, c = V[F[:, 0]], V[F[:, 1]], V[F[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def connected_components(nv, F):
    """Number of face-connected components (via shared vertices)."""
    parent = np.arange(nv)

    def find(x):
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    for tri in F:
        ra, rb, rc = find(tri[0]), find(tri[1]), find(tri[2])
        parent[rb] = ra
        parent[find(rc)] = ra
    used = np.unique(F)
    return len({find(int(v)) for v in used})


def check_mesh(V, F):
    """Validity report: closed 2-manifold edges, consistent orientation, outward
    winding, no degenerate faces, and the component count. 'ok' sums them up."""
    edges = _edge_keys(F)
    uniq, counts = np.unique(edges, axis=0, return_counts=True)
    dup_directed = int(np.sum(counts > 1))
    fwd = {tuple(e) for e in uniq.tolist()}
    unmatched = sum(1 for (i, j) in fwd if (j, i) not in fwd)
    _, area = face_normals_areas(V, F)
    scale = float(np.max(np.ptp(V, axis=0))) ** 2
    degenerate = int(np.sum(area <= 1e-9 * scale))
    vol = signed_volume(V, F)
    comps = connected_components(len(V), F)
    report = {
        "vertices": int(len(V)),
        "triangles": int(len(F)),
        "watertight": dup_directed == 0 and unmatched == 0,
        "open_or_nonmanifold_edges": int(dup_directed + unmatched),
        "degenerate_triangles": degenerate,
        "volume_mm3": round(vol, 3),
        "outward": vol > 0,
        "components": comps,
    }
    report["ok"] = bool(report["watertight"] and degenerate == 0 and vol > 0 and comps == 1)
    return report


def crease_split(V, F, crease_deg=CREASE_ANGLE_DEG):
    """Splits vertices along sharp edges and computes smooth vertex normals.

    An edge is smooth when its two faces' normals differ by less than crease_deg;
    the corners of a vertex that are joined through smooth edges share one output
    vertex, whose normal is the angle-weighted mean of those faces' normals. So
    flat faces get their own normal and faceted cylinders shade smooth.
    Returns (positions (k, 3), normals (k, 3), faces (m, 3)).
    """
    m = len(F)
    fn, _ = face_normals_areas(V, F)
    corner_vertex = F.reshape(-1)                     # corner id = 3 * face + k
    parent = np.arange(3 * m)

    def find(x):
        root = x
        while parent[root] != root:
            root = parent[root]
        while parent[x] != root:
            parent[x], x = root, parent[x]
        return root

    cos_lim = np.cos(np.radians(crease_deg))
    edge_to_corner = {}
    for fi in range(m):
        for k in range(3):
            i, j = int(F[fi, k]), int(F[fi, (k + 1) % 3])
            edge_to_corner[(i, j)] = (3 * fi + k, 3 * fi + (k + 1) % 3)
    for (i, j), (ci, cj) in edge_to_corner.items():
        if i > j:
            continue
        other = edge_to_corner.get((j, i))
        if other is None:
            continue
        fi, fj = ci // 3, other[0] // 3
        if float(np.dot(fn[fi], fn[fj])) < cos_lim:
            continue
        # Face fi has corners (i, j) = (ci, cj); face fj has (j, i) = other.
        for a, b in ((ci, other[1]), (cj, other[0])):
            ra, rb = find(a), find(b)
            if ra != rb:
                parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([find(c) for c in range(3 * m)])
    # Corner angles as weights.
    P = V[F]
    angles = np.zeros((m, 3))
    for k in range(3):
        e1 = P[:, (k + 1) % 3] - P[:, k]
        e2 = P[:, (k + 2) % 3] - P[:, k]
        cosang = np.einsum("ij,ij->i", e1, e2) / np.maximum(
            np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1), 1e-300)
        angles[:, k] = np.arccos(np.clip(cosang, -1.0, 1.0))
    uniq_roots, new_index = np.unique(roots, return_inverse=True)
    k_out = len(uniq_roots)
    normals = np.zeros((k_out, 3))
    np.add.at(normals, new_index, (fn[:, None, :] * angles[:, :, None]).reshape(-1, 3))
    ln = np.linalg.norm(normals, axis=1)
    normals /= np.maximum(ln, 1e-300)[:, None]
    positions = V[corner_vertex[uniq_roots]]
    faces = new_index.reshape(m, 3)
    return positions, normals, faces


def write_ply(path, positions, normals, faces, comment):
    """Binary little-endian PLY: float x y z nx ny nz per vertex, uchar/int faces."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"comment {comment}\n"
        f"element vertex {len(positions)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        f"element face {len(faces)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    vert = np.hstack([positions, normals]).astype("<f4")
    face = np.zeros(len(faces), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    face["n"] = 3
    face["i"] = faces
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(vert.tobytes())
        f.write(face.tobytes())


def read_ply(path):
    """Reads a PLY written by write_ply. Returns (positions, normals, faces, comment)."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode("ascii").splitlines()
    nv = nf = 0
    comment = ""
    for line in header:
        parts = line.split()
        if parts[:2] == ["element", "vertex"]:
            nv = int(parts[2])
        elif parts[:2] == ["element", "face"]:
            nf = int(parts[2])
        elif parts[:1] == ["comment"]:
            comment = line[len("comment "):]
    vert = np.frombuffer(data, dtype="<f4", count=6 * nv, offset=end).reshape(nv, 6)
    face = np.frombuffer(data, dtype=[("n", "u1"), ("i", "<i4", (3,))], count=nf,
                         offset=end + 24 * nv)
    return vert[:, :3].astype(np.float64), vert[:, 3:].astype(np.float64), \
        face["i"].astype(np.int64), comment


def ply_comment(path):
    """The first comment line of a PLY header, or None when the file is unreadable."""
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError:
        return None
    for line in head.split(b"\n"):
        if line.startswith(b"comment "):
            return line[len(b"comment "):].decode("ascii", "replace")
        if line == b"end_header":
            break
    return None


def diameter(V):
    """Largest distance between two vertices (mm), via the convex hull."""
    from scipy.spatial import ConvexHull
    try:
        H = V[ConvexHull(V).vertices]
    except Exception:  # flat or tiny input: fall back to all vertices
        H = V
    best = 0.0
    for s in range(0, len(H), 512):
        d = np.linalg.norm(H[s:s + 512, None, :] - H[None, :, :], axis=2)
        best = max(best, float(d.max()))
    return best
