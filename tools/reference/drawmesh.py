"""Shapes and meshes for draw.py: analytic shapes (signed distance, uniform surface samples,
extent along a direction), Q2 hexahedral tensor meshes for boxes and curved quadratic
tetrahedra from gmsh (OCC kernel, second order, boundary mid-edge nodes on the exact
surface) converted to skfem's MeshTet2."""

import numpy as np
from dataclasses import replace

from skfem import ElementHex2, ElementTetP2, MeshHex, MeshTet1, MeshTet2

import generate as g


# ---------------------------------------------------------------------------
# Analytic shapes (the scene's [body] shape)
# ---------------------------------------------------------------------------
def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def _frame(axis):
    """Two unit vectors orthogonal to `axis` (and to each other)."""
    a = _unit(axis)
    t = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = _unit(t - (t @ a) * a)
    return e1, np.cross(a, e1)


def sdf(shape, X):
    """Signed distance (negative inside) of points X (n, 3) to the analytic shape."""
    X = np.atleast_2d(X)
    k = shape["kind"]
    if k == "sphere":
        return np.linalg.norm(X - shape["center"], axis=1) - shape["radius"]
    if k == "box":
        q = np.abs(X - shape["center"]) - np.asarray(shape["size"]) / 2
        out = np.linalg.norm(np.maximum(q, 0), axis=1)
        return out + np.minimum(q.max(axis=1), 0)
    if k == "torus":
        a = _unit(shape["axis"])
        d = X - shape["center"]
        h = d @ a
        rho = np.linalg.norm(d - h[:, None] * a, axis=1)
        return np.hypot(rho - shape["major"], h) - shape["minor"]
    if k == "capsule":
        A, B = np.asarray(shape["a"], float), np.asarray(shape["b"], float)
        ab = B - A
        t = np.clip((X - A) @ ab / (ab @ ab), 0, 1)
        return np.linalg.norm(X - (A + t[:, None] * ab), axis=1) - shape["radius"]
    raise ValueError(k)


def surface_points(shape, n, rng):
    """n points uniformly by area on the exact analytic surface."""
    k = shape["kind"]
    if k in ("sphere", "box"):
        return g.analytic_surface_points(shape, n, rng)
    if k == "torus":
        R, r = shape["major"], shape["minor"]
        a = _unit(shape["axis"])
        e1, e2 = _frame(a)
        out = []
        while sum(len(o) for o in out) < n:
            th, ph = rng.random((2, 2 * n)) * 2 * np.pi
            keep = rng.random(2 * n) < (R + r * np.cos(ph)) / (R + r)   # area weight
            th, ph = th[keep], ph[keep]
            radial = np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2
            out.append(shape["center"] + (R + r * np.cos(ph))[:, None] * radial
                       + (r * np.sin(ph))[:, None] * a)
        return np.concatenate(out)[:n]
    if k == "capsule":
        A, B = np.asarray(shape["a"], float), np.asarray(shape["b"], float)
        r = shape["radius"]
        L = np.linalg.norm(B - A)
        ax = (B - A) / L
        e1, e2 = _frame(ax)
        cyl = rng.random(n) < (2 * np.pi * r * L) / (2 * np.pi * r * L + 4 * np.pi * r * r)
        P = np.empty((n, 3))
        m = int(cyl.sum())
        th, t = rng.random(m) * 2 * np.pi, rng.random(m)
        P[cyl] = (A + t[:, None] * (B - A) + r * (np.cos(th)[:, None] * e1 + np.sin(th)[:, None] * e2))
        d = rng.normal(size=(n - m, 3))
        d /= np.linalg.norm(d, axis=1)[:, None]
        cen = np.where((d @ ax)[:, None] > 0, B, A)
        P[~cyl] = cen + r * d
        return P
    raise ValueError(k)


def extent(shape, d):
    """max over the shape of d . X (d a unit vector)."""
    d = np.asarray(d, float)
    k = shape["kind"]
    c = np.asarray(shape.get("center", [0, 0, 0]), float)
    if k == "sphere":
        return c @ d + shape["radius"]
    if k == "box":
        return c @ d + 0.5 * np.abs(d) @ np.asarray(shape["size"])
    if k == "torus":
        a = _unit(shape["axis"])
        da = d @ a
        return c @ d + shape["major"] * np.sqrt(max(0.0, 1 - da * da)) + shape["minor"]
    if k == "capsule":
        return max(np.dot(shape["a"], d), np.dot(shape["b"], d)) + shape["radius"]
    raise ValueError(k)


def bbox(shape):
    E = np.eye(3)
    return (np.array([-extent(shape, -E[i]) for i in range(3)]),
            np.array([extent(shape, E[i]) for i in range(3)]))


def volume_center(shape):
    if shape["kind"] == "capsule":
        return 0.5 * (np.asarray(shape["a"], float) + np.asarray(shape["b"], float))
    return np.asarray(shape["center"], float)


def thinnest(shape):
    k = shape["kind"]
    if k == "sphere":
        return 2 * shape["radius"]
    if k == "box":
        return float(min(shape["size"]))
    if k == "torus":
        return 2 * shape["minor"]
    return 2 * shape["radius"]


def size(shape):
    lo, hi = bbox(shape)
    return float(np.linalg.norm(hi - lo))


# ---------------------------------------------------------------------------
# Meshes
# ---------------------------------------------------------------------------
def box_mesh(shape, cells, grade_axes, q=1.5):
    """Q2 hexahedra on a box; grade_axes[i] in (None, "lo", "hi", "both") grades the cells
    along axis i towards those faces (power grading x -> x^q, generate.graded)."""
    c = np.asarray(shape["center"], float)
    s = np.asarray(shape["size"], float)
    lo = c - s / 2
    axes = [lo[i] + s[i] * g.graded(cells[i], q, grade_axes[i]) for i in range(3)]
    return MeshHex.init_tensor(*axes), ElementHex2()


# gmsh's 10-node tetrahedron: nodes 4..9 sit on the edges (0,1), (1,2), (0,2), (0,3), (2,3), (1,3)
# elements per 2 pi of curvature radius (the torus' tube needs more for 1e-4)
CURVATURE_POINTS = dict(torus=15)
GMSH_TET10_EDGES = [(0, 1), (1, 2), (0, 2), (0, 3), (2, 3), (1, 3)]


CLAMP_EDGE_REFINE = 0.0       # element size at the clamp edge / h (0: no grading; 0.35 was tried
                              # on c0012: no gain in the estimated error for twice the dofs)


def inside_box(s, lo, hi):
    """Whether the OCC surface s lies in the box: its centre of mass (surfaces lie wholly
    inside or outside after the fragmentation; a convex box holds the centroid of what it
    holds; OCC bounding boxes of curved patches are loose)."""
    import gmsh
    c = np.asarray(gmsh.model.occ.getCenterOfMass(2, s))
    return bool(np.all(c >= np.asarray(lo) - 1e-9) and np.all(c <= np.asarray(hi) + 1e-9))


def gmsh_mesh(shape, h, boxes=(), curvature_scale=1.0):
    """Curved quadratic tetrahedra for a sphere, torus or capsule: gmsh (OCC), mesh size h,
    second order with the boundary mid-edge nodes on the exact surface, as skfem MeshTet2
    (corner nodes -> MeshTet1 -> MeshTet2.from_mesh, every edge dof moved to gmsh's mid-edge
    node of the same vertex pair).  With clamp `boxes` ((lo, hi) pairs) the body is fragmented
    with the boxes first (the parts of the boxes outside the body removed), so that the mesh
    conforms to the box boundary: the part of the surface inside a box is its own surface
    entity.  Returns (mesh, element, info); info["clamp_area"] is the OCC area of the boundary
    surfaces inside the boxes.  curvature_scale divides the elements per 2 pi of curvature
    radius (coarser levels of the same mesh family)."""
    import gmsh
    gmsh.initialize(["-v", "0"] if False else [])
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.option.setNumber("General.NumThreads", 1)
        gmsh.option.setNumber("Mesh.MaxNumThreads3D", 1)
        gmsh.option.setNumber("Mesh.RandomSeed", 1)
        gmsh.model.add("body")
        occ = gmsh.model.occ
        k = shape["kind"]
        if k == "sphere":
            vols = [(3, occ.addSphere(*shape["center"], shape["radius"]))]
        elif k == "torus":
            vols = [(3, occ.addTorus(*shape["center"], shape["major"], shape["minor"],
                                     zAxis=list(_unit(shape["axis"]))))]
        elif k == "capsule":
            A, B, r = np.asarray(shape["a"], float), np.asarray(shape["b"], float), shape["radius"]
            cyl = occ.addCylinder(*A, *(B - A), r)
            s1 = occ.addSphere(*A, r)
            s2 = occ.addSphere(*B, r)
            vols, _ = occ.fuse([(3, cyl)], [(3, s1), (3, s2)])
        else:
            raise ValueError(k)
        if len(boxes):
            tools = [(3, occ.addBox(*lo, *(np.asarray(hi) - np.asarray(lo)))) for lo, hi in boxes]
            out, omap = occ.fragment(vols, tools)
            keep = {tuple(x) for m in omap[:len(vols)] for x in m}
            occ.remove([x for x in out if tuple(x) not in keep], recursive=True)
        occ.synchronize()
        # the clamp surfaces and the curves where they meet the free surface
        clamp_surf, free_curves = [], set()
        for _, s in gmsh.model.getEntities(2):
            up, down = gmsh.model.getAdjacencies(2, s)
            if len(up) != 1:
                continue                                    # an interface inside the body
            if any(inside_box(s, lo, hi) for lo, hi in boxes):
                clamp_surf.append(s)
            else:
                free_curves |= set(int(c) for c in down)
        edge = sorted(set(int(c) for s in clamp_surf for c in gmsh.model.getAdjacencies(2, s)[1])
                      & free_curves)
        if edge and CLAMP_EDGE_REFINE:        # graded towards the clamp edge (its singularity)
            fd = gmsh.model.mesh.field.add("Distance")
            gmsh.model.mesh.field.setNumbers(fd, "CurvesList", edge)
            gmsh.model.mesh.field.setNumber(fd, "Sampling", 200)
            ft = gmsh.model.mesh.field.add("Threshold")
            gmsh.model.mesh.field.setNumber(ft, "InField", fd)
            gmsh.model.mesh.field.setNumber(ft, "SizeMin", CLAMP_EDGE_REFINE * h)
            gmsh.model.mesh.field.setNumber(ft, "SizeMax", h)
            gmsh.model.mesh.field.setNumber(ft, "DistMin", 0.0)
            gmsh.model.mesh.field.setNumber(ft, "DistMax", 3 * h)
            gmsh.model.mesh.field.setAsBackgroundMesh(ft)
        # sizes from h, the curvature and the field only (a family that scales with h)
        gmsh.option.setNumber("Mesh.MeshSizeExtendFromBoundary", 0)
        gmsh.option.setNumber("Mesh.MeshSizeFromPoints", 0)
        gmsh.option.setNumber("Mesh.MinimumCirclePoints", 3)
        gmsh.option.setNumber("Mesh.MeshSizeMax", h)
        gmsh.option.setNumber("Mesh.MeshSizeMin", 0.5 * h)
        gmsh.option.setNumber("Mesh.MeshSizeFromCurvature",
                              max(4, round(CURVATURE_POINTS.get(k, 12) / curvature_scale)))
        gmsh.option.setNumber("Mesh.ElementOrder", 1)
        gmsh.option.setNumber("Mesh.Algorithm3D", 1)
        gmsh.model.mesh.generate(3)
        gmsh.model.mesh.setOrder(2)
        clamp_area, clamp_facets = 0.0, 0
        for s in clamp_surf:      # the nodes of a clamp surface lie in its box (conforming)
            P = gmsh.model.mesh.getNodes(2, s, includeBoundary=True)[1].reshape(-1, 3)
            assert any(np.all((P >= np.asarray(lo) - 1e-6) & (P <= np.asarray(hi) + 1e-6))
                       for lo, hi in boxes)
            clamp_area += occ.getMass(2, s)
            clamp_facets += sum(len(t) for t in gmsh.model.mesh.getElements(2, s)[1])
        tags, coords, _ = gmsh.model.mesh.getNodes()
        X = coords.reshape(-1, 3)
        index = -np.ones(int(tags.max()) + 1, int)
        index[tags.astype(int)] = np.arange(len(tags))
        etypes, _, enodes = gmsh.model.mesh.getElements(3)
        assert list(etypes) == [11], etypes            # 10-node tetrahedra only
        T = index[np.concatenate([np.asarray(e, int) for e in enodes]).reshape(-1, 10)]
    finally:
        gmsh.finalize()
    corners = np.unique(T[:, :4])
    renum = -np.ones(len(X), int)
    renum[corners] = np.arange(len(corners))
    p = X[corners].T.copy()
    t = renum[T[:, :4]].T.copy()
    # mid-edge nodes by vertex pair
    mid = {}
    for e, (a, b) in enumerate(GMSH_TET10_EDGES):
        va, vb, vm = t[a], t[b], T[:, 4 + e]
        for x, y, m in zip(np.minimum(va, vb), np.maximum(va, vb), vm):
            mid[(int(x), int(y))] = int(m)
    m1 = MeshTet1(p, t)
    M = MeshTet2.from_mesh(m1)
    nv = m1.p.shape[1]
    edges = M.edges
    assert np.array_equal(m1.p, p)
    D = M.doflocs.copy()
    assert np.allclose(D[:, nv:], 0.5 * (p[:, edges[0]] + p[:, edges[1]]))
    idx = np.array([mid[(int(min(a, b)), int(max(a, b)))] for a, b in edges.T])
    newmid = X[idx].T
    L = np.linalg.norm(p[:, edges[0]] - p[:, edges[1]], axis=0)
    # a mid-edge node is near its edge's midpoint (checks the node order assumption)
    assert np.all(np.linalg.norm(newmid - D[:, nv:], axis=0) < 0.25 * L)
    D[:, nv:] = newmid
    return replace(M, doflocs=D), ElementTetP2(), dict(clamp_area=clamp_area, clamp_facets=clamp_facets)


def surface_error(body, shape, s=8):
    """Largest |analytic signed distance| over the quadratic boundary surface (facet
    subdivision vertices, s x s per facet)."""
    surf = g.Surface(body, s)
    return float(np.abs(sdf(shape, surf.X0)).max())
