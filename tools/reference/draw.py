#!/usr/bin/env python3
"""Random reference scenarios for the softbody fitter, drawn from a seed, computed with
scikit-fem (generate.py's physics, extended in drawphys.py and drawmesh.py).

Usage:
  draw.py --seed S [--set calibration|test] [--out DIR] [--quick]
  draw.py --set calibration --seeds 1-12 [--out DIR]
  draw.py --set test --count N [--out DIR]       fresh seeds (secrets.randbits(31)) + index.json

Writes DIR/<name>/ (name c%04d for calibration, t%010d for test; DIR defaults to
tests/reference_values/drawn/<set>): scene.toml, observations.csv, observations.cameras.json
(depth cameras only) and truth.json.  Everything a scenario is follows from its seed
(numpy.random.default_rng(seed)); see README.md beside this file, "Drawn scenarios".
"""

import os

for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse
import datetime
import json
import math
import platform
import secrets
import subprocess
import sys
import time

import numpy as np
import scipy
import skfem

import generate as g
import drawmesh as dm
import drawphys as ph
import drawconv as dc

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_ROOT = os.path.join(g.REPO, "tests", "reference_values", "drawn")
SIGMAS = (0.0025, 0.005, 0.01, 0.02)
GEOMETRIES = ("box", "bar", "plate", "sphere", "torus", "capsule")
CLAMPS = dict(box=("face",), bar=("face", "both"), plate=("face",), sphere=("patch",),
              torus=("patch",), capsule=("patch", "both"))
RESOLUTION = 20
MAX_POINTS = 6000                  # per scenario (file size)


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def random_unit(rng):
    return unit(rng.normal(size=3))


def loguniform(rng, a, b):
    return float(math.exp(rng.uniform(math.log(a), math.log(b))))


def translate(shape, t):
    s = dict(shape)
    for k in ("center", "a", "b"):
        if k in s:
            s[k] = list(np.asarray(s[k], float) + t)
    return s


def tilt(rng, max_deg, min_deg=0.0):
    """A unit vector within max_deg of +y (random azimuth)."""
    th = math.radians(rng.uniform(min_deg, max_deg))
    ph_ = rng.uniform(0, 2 * math.pi)
    return np.array([math.sin(th) * math.cos(ph_), math.cos(th), math.sin(th) * math.sin(ph_)])


def volume(shape):
    k = shape["kind"]
    if k == "box":
        return float(np.prod(shape["size"]))
    if k == "sphere":
        return 4 / 3 * math.pi * shape["radius"] ** 3
    if k == "torus":
        return 2 * math.pi ** 2 * shape["major"] * shape["minor"] ** 2
    L = np.linalg.norm(np.subtract(shape["b"], shape["a"]))
    return math.pi * shape["radius"] ** 2 * L + 4 / 3 * math.pi * shape["radius"] ** 3


# ---------------------------------------------------------------------------
# Drawing a scenario (no simulation but the static solve that scales E)
# ---------------------------------------------------------------------------
def draw(seed, which, dry=False):
    """The scenario of a seed; dry: without the static solve that scales E and dt (clamped)."""
    rng = np.random.default_rng(seed)
    name = f"c{seed:04d}" if which == "calibration" else f"t{seed:010d}"
    geometry = GEOMETRIES[rng.integers(len(GEOMETRIES))]
    clamp = "none" if rng.random() < 0.5 else CLAMPS[geometry][rng.integers(len(CLAMPS[geometry]))]
    if clamp == "none":
        motion = "drop" if rng.random() < 0.5 else "throw"
    else:
        motion = "swing" if rng.random() < 0.6 else "push"
    sc = dict(seed=int(seed), set=which, name=name, geometry=geometry, clamp=clamp, motion=motion,
              family="hex" if geometry in ("box", "bar", "plate") else "tet",
              clamp_boxes=[], clamp_faces=[], wind=None, drag=None, svk=False, initial=None,
              ground=None, draws={})
    # -- geometry ------------------------------------------------------------------------
    long_axis = 0
    if geometry == "box":
        shape = dict(kind="box", center=[0.0, 0.0, 0.0], size=list(rng.uniform(0.35, 0.7, 3)))
        cells = [9, 9, 9]
        long_axis = int(rng.integers(3))
    elif geometry == "bar":
        a = rng.uniform(0.2, 0.26)
        b = max(0.2, a * rng.uniform(0.85, 1.15))
        L = a * rng.uniform(4.0, 6.0)
        long_axis = int(rng.choice([0, 2]))
        s = [a, b, a]
        s[long_axis] = L
        s[2 - long_axis] = b if long_axis == 0 else a
        s[1] = b if long_axis == 2 else a
        shape = dict(kind="box", center=[0.0, 0.0, 0.0], size=s)
        cells = [6, 6, 6]
        cells[long_axis] = 20
    elif geometry == "plate":
        L = rng.uniform(1.2, 1.5)
        thin = 1 if rng.random() < 0.6 else 2
        s = [L, 0.8 * L, 0.8 * L]
        s[thin] = rng.uniform(0.12, 0.15) * L
        shape = dict(kind="box", center=[0.0, 0.0, 0.0], size=s)
        cells = [16, 12, 12]
        cells[thin] = 3
    elif geometry == "sphere":
        shape = dict(kind="sphere", center=[0.0, 0.0, 0.0], radius=rng.uniform(0.3, 0.5))
    elif geometry == "torus":
        r = rng.uniform(0.11, 0.17)
        shape = dict(kind="torus", center=[0.0, 0.0, 0.0], axis=list(random_unit(rng)),
                     major=r * rng.uniform(2.5, 3.5), minor=r)
    else:
        r = rng.uniform(0.12, 0.2)
        L = rng.uniform(0.4, 0.8)
        ax = np.array([1.0, 0.0, 0.0]) if clamp == "both" else random_unit(rng)
        shape = dict(kind="capsule", a=list(-0.5 * L * ax), b=list(0.5 * L * ax), radius=r)
    # -- motion, placement, ground -------------------------------------------------------
    gravity = np.array([0.0, -10.0, 0.0])
    if motion == "swing" and rng.random() < 0.3:
        gravity = -10.0 * tilt(rng, 30.0, 5.0)
    if motion == "push":
        sc["wind"] = list(rng.uniform(1.0, 5.0) * random_unit(rng))
        if rng.random() < 0.5:
            gravity = None
    ground_on = motion == "drop" or (motion == "throw" and rng.random() < 0.7)
    if clamp == "none":
        n = tilt(rng, 15.0, 5.0) if rng.random() < 0.35 else np.array([0.0, 1.0, 0.0])
        h0 = rng.uniform(0.02, 0.06)
        if not ground_on:
            h0 = 0.5
        shape = translate(shape, (h0 + dm.extent(shape, -n)) * n)
        if ground_on:
            sc["ground"] = dict(normal=list(n), height=0.0)
    else:
        shape = translate(shape, np.array([0.0, 1.0, 0.0]))
    sc["shape"] = shape
    sc["gravity"] = list(gravity) if gravity is not None else [0.0, 0.0, 0.0]
    sc["gravity_on"] = gravity is not None
    # -- clamp boxes ---------------------------------------------------------------------
    lo, hi = dm.bbox(shape)
    if clamp in ("face", "both") and sc["family"] == "hex":
        c, s = np.asarray(shape["center"]), np.asarray(shape["size"])
        ax = long_axis if geometry != "box" or rng.random() < 0.5 else 1
        sides = ["min", "max"] if clamp == "both" else [["min", "max"][rng.integers(2)]]
        for side in sides:
            face = c[ax] - s[ax] / 2 if side == "min" else c[ax] + s[ax] / 2
            blo, bhi = c - s / 2 - 0.05, c + s / 2 + 0.05
            blo[ax], bhi[ax] = face - 0.005, face + 0.005
            sc["clamp_boxes"].append((list(blo), list(bhi)))
            sc["clamp_faces"].append((int(ax), float(face)))
        grade = ["both"] * 3
        grade[ax] = "both" if clamp == "both" else ("lo" if sides[0] == "min" else "hi")
    elif clamp in ("patch", "both"):
        if clamp == "both":
            dirs = [np.array([1.0, 0, 0]), np.array([-1.0, 0, 0])]
        else:
            dirs = [[np.array([1.0, 0, 0]), np.array([-1.0, 0, 0]), np.array([0, 0, 1.0]),
                     np.array([0, 0, -1.0]), np.array([0, 1.0, 0])][rng.integers(5)]]
        for d in dirs:
            depth = rng.uniform(0.1, 0.15)
            ax = int(np.argmax(np.abs(d)))
            blo, bhi = lo - 0.05, hi + 0.05
            ext = dm.extent(shape, d)
            if d[ax] > 0:
                blo[ax], bhi[ax] = ext - depth, ext + 0.05
            else:
                blo[ax], bhi[ax] = -ext - 0.05, -ext + depth
            sc["clamp_boxes"].append((list(np.round(blo, 6)), list(np.round(bhi, 6))))
        grade = None
    else:
        grade = [None] * 3
    # -- meshes --------------------------------------------------------------------------
    if sc["family"] == "hex":         # never a single cell through a thickness below the reference
        sc["mesh"] = dict(reference=dict(cells=cells, grade=grade),
                          coarse=dict(cells=[max(2, c // 2) for c in cells], grade=grade),
                          coarser=dict(cells=[max(2, c // 4) for c in cells], grade=grade))
    else:
        t = dm.thinnest(shape)
        h = dict(sphere=0.11 * t, torus=0.27 * t, capsule=0.22 * t)[geometry]
        # curvature points / sqrt(h ratio): a torus' tube with fewer points gives elements
        # skfem's isoparametric facet mapping cannot invert
        sc["mesh"] = dict(reference=dict(h=h), coarse=dict(h=1.5 * h, curvature_scale=1.5 ** 0.5),
                          coarser=dict(h=1.5 ** 2 * h, curvature_scale=1.5))
    # -- effects and material ------------------------------------------------------------
    E_drawn = loguniform(rng, 300.0, 5000.0)
    nu = rng.uniform(0.15, 0.45)
    rho = 1.0 if rng.random() < 0.5 else rng.uniform(0.5, 2.0)
    a1 = 0.0 if rng.random() < 0.25 else loguniform(rng, 0.1, 2.0)
    a2 = 0.0 if rng.random() < 0.5 else loguniform(rng, 2e-4, 3e-3)
    if rng.random() < 0.35:
        sc["drag"] = loguniform(rng, 0.05, 0.5)
    if clamp == "none" and not ground_on and sc["drag"] is None:
        # a free flight deforms the body only through a surface effect: drag or wind
        # (its own stream, so that the other scenarios keep their draws)
        r4 = np.random.default_rng([seed, 4])
        if r4.random() < 0.5:
            sc["drag"] = loguniform(r4, 0.05, 0.5)
        else:
            sc["wind"] = list(r4.uniform(1.0, 5.0) * random_unit(r4))
    sc["svk"] = bool(sc["ground"] is None and rng.random() < 0.25)
    sub_svk = 6                        # St Venant-Kirchhoff: Newton per substep, the cost
    sigma = SIGMAS[rng.integers(len(SIGMAS))]
    observation = "points" if rng.random() < 0.6 else "cameras"
    ncam = int(rng.choice([1, 2, 3, 4], p=[0.3, 0.3, 0.2, 0.2])) if observation == "cameras" else 0
    steps = int(rng.integers(20, 41))
    substeps = int(rng.choice([16, 24, 32]) if clamp != "none" else rng.choice([12, 16]))
    points = int(rng.integers(100, 201))
    sc.update(truth=dict(young=E_drawn, poisson=float(nu), density=float(rho),
                         damping_mass=a1, damping_stiffness=a2),
              sigma=sigma, observation=observation, cameras=ncam, steps=steps,
              substeps=sub_svk if sc["svk"] else substeps,
              points=min(points, MAX_POINTS // steps))
    sc["draws"].update(young_drawn=E_drawn, points_drawn=points)
    r_frames = rng.uniform(8.0, 14.0)
    extra_time = rng.uniform(0.15, 0.35)
    cam_draws = rng.random((4, 4))
    throw_draws = rng.random(8)
    # -- time and amplitude ----------------------------------------------------------------
    size = float(np.max(hi - lo))
    if clamp != "none":
        if not dry:
            scale_clamped(sc, size, r_frames)
    else:
        n = np.asarray(sc["ground"]["normal"]) if sc["ground"] else np.array([0.0, 1.0, 0.0])
        if motion == "throw":
            az = 2 * math.pi * throw_draws[0]
            vh = 0.2 + 0.8 * throw_draws[1]
            vy = (-0.5 + throw_draws[2]) if ground_on else throw_draws[2]
            v0 = np.array([vh * math.cos(az), vy, vh * math.sin(az)])
            T = 0.3 + 0.2 * throw_draws[3] if not ground_on else None
        else:
            v0, T = None, None
        hgt = -dm.extent(shape, -n) if ground_on else None      # lowest point above the plane
        vn = 0.0 if v0 is None else float(v0 @ n)
        if ground_on:
            gn = 10.0 * n[1]
            t_land = (vn + math.sqrt(vn * vn + 2 * gn * hgt)) / gn
            T = t_land + extra_time
        else:
            t_land = T
        sc["dt"] = float(np.round(T / steps, 5))
        if v0 is not None:
            wmax = (1.5 if sc["svk"] else 0.3) / T
            w = random_unit(np.random.default_rng([seed, 3])) * wmax * (0.3 + 0.7 * throw_draws[4])
            sc["initial"] = dict(velocity=list(v0), angular_velocity=list(w),
                                 center=list(dm.volume_center(shape)))
        if ground_on:
            tilt_span = size * math.sqrt(max(0.0, 1 - n[1] ** 2))
            rot = 0.0 if sc["initial"] is None else np.linalg.norm(sc["initial"]["angular_velocity"]) * t_land
            sc["ground"].update(cap=float(0.03 + tilt_span + size * rot),
                                penalty=contact_stiffness(sc, n))
        sc["draws"].update(t_land=float(t_land))
    if clamp == "none":
        E = sc["truth"]["young"]
        sc["truth"]["young"] = float(np.round(E, 3 - int(math.floor(math.log10(E)))))
        if sc["ground"] is not None:
            sc["ground"]["penalty"] = contact_stiffness(sc, n)
    sc["cam_draws"] = cam_draws
    return sc


def scale_clamped(sc, size, r_frames):
    """E within the drawn value's neighbourhood such that the swing's peak (twice the static
    deflection under the load) is 3%..15% of the body's size and at least 5 sigma; the frame
    interval a fraction 1/r of the first period (Rayleigh quotient of the static deflection)."""
    E0 = 1000.0
    probe = dict(sc, truth=dict(sc["truth"], young=E0), drag=None)
    body = ph.DBody(probe, "coarse")
    I = body.free
    K = body.K[I][:, I]
    u = g.Factor(K).solve(body.F[I])
    M = body.M[I][:, I]
    peak0 = 2 * float(np.linalg.norm(g.u_full(body, u).reshape(-1, 3), axis=1).max())
    omega0 = math.sqrt((u @ (K @ u)) / (u @ (M @ u)))
    lo_amp = max(0.03 * size, 5 * sc["sigma"])
    hi_amp = 0.15 * size
    E_hi = E0 * peak0 / lo_amp                     # stiffer than this: peak below lo_amp
    E_lo = E0 * peak0 / hi_amp
    E = float(min(max(sc["truth"]["young"], E_lo), E_hi))
    sc["truth"]["young"] = float(np.round(E, 3 - int(math.floor(math.log10(E)))))
    omega = omega0 * math.sqrt(sc["truth"]["young"] / E0)
    T1 = 2 * math.pi / omega
    sc["dt"] = float(np.round(T1 / r_frames, 5))
    sc["draws"].update(first_period_estimate=T1, frames_per_period=r_frames,
                       peak_estimate=peak0 * E0 / sc["truth"]["young"],
                       young_range_for_amplitude=[E_lo, E_hi])


def contact_stiffness(sc, n):
    """k so that the resting pressure (flat face: rho g H; curved or tilted: Hertz' peak
    pressure of the body's weight) presses 1e-5 deep (the landing more), within [1e5, 2e7]."""
    t, shape = sc["truth"], sc["shape"]
    W = t["density"] * 10.0 * volume(shape)
    if shape["kind"] == "box" and n[1] > 0.9999:
        p = t["density"] * 10.0 * shape["size"][1]
    else:
        R = dict(sphere=shape.get("radius"), torus=shape.get("minor"),
                 capsule=shape.get("radius")).get(shape["kind"], 0.03)
        Es = t["young"] / (1 - t["poisson"] ** 2)
        p = (6 * W * Es ** 2 / (math.pi ** 3 * R ** 2)) ** (1 / 3)
    k = float(np.clip(p / 1e-5, 1e5, 2e7))
    return float(np.round(k, -int(math.floor(math.log10(k))) + 1))


# ---------------------------------------------------------------------------
# Observations
# ---------------------------------------------------------------------------
def place_cameras(sc, body, frames):
    """Cameras looking at the middle of the motion from random directions 15..60 degrees
    above the horizon, far enough that the body's whole path fits the picture."""
    surf = g.Surface(body, 2)
    P = np.concatenate([surf.vertices(U) for U in frames[1:]])
    target = 0.5 * (P.min(axis=0) + P.max(axis=0))
    radius = float(np.linalg.norm(P - target, axis=1).max())
    cams = []
    for k in range(sc["cameras"]):
        d = sc["cam_draws"][k]
        az, el = 2 * math.pi * d[0], math.radians(15 + 45 * d[1])
        fov = 0.6 + 0.3 * d[2]
        W, H = [(40, 30), (48, 36), (64, 48)][int(3 * d[3])]
        dist = 1.1 * radius / math.tan(fov / 2)
        direction = np.array([math.cos(el) * math.cos(az), math.sin(el), math.cos(el) * math.sin(az)])
        cams.append(dict(id=k, eye=[round(float(x), 6) for x in target + dist * direction],
                         target=[round(float(x), 6) for x in target], up=[0.0, 1.0, 0.0],
                         fov_y=round(fov, 6), width=W, height=H))
    return cams


def observe_cameras(sc, body, frames, cams, rng):
    """Depth images of the deformed surface (4 x 4 flat sub-triangles per quadratic facet,
    nearest hit), Gaussian depth noise, unprojected; at most sc['points'] pixels per frame
    (all cameras together) are kept, a uniform random subset.  Also returns each kept point's
    distance along its viewing ray to the true surface (the depth noise times the ray's length
    per unit depth): the residual softbody measures for a point whose camera it knows."""
    surf = g.Surface(body, 4)
    fr, pts, cid, along = [], [], [], []
    hits = []
    for f in range(1, sc["steps"] + 1):
        T = surf.triangles(frames[f])
        P, C, R = [], [], []
        for cam in cams:
            Z = ph.depth_image(T, cam)
            jj, ii = np.nonzero(np.isfinite(Z))
            noise = sc["sigma"] * rng.normal(size=len(ii))
            z = Z[jj, ii] + noise
            P.append(ph.unproject(cam, ii, jj, z))
            C.append(np.full(len(ii), cam["id"]))
            R.append(noise * np.linalg.norm(ph.rays(cam, ii.astype(float), jj.astype(float)), axis=1))
        P, C, R = np.concatenate(P), np.concatenate(C), np.concatenate(R)
        hits.append(len(P))
        if len(P) > sc["points"]:
            keep = np.sort(rng.choice(len(P), size=sc["points"], replace=False))
            P, C, R = P[keep], C[keep], R[keep]
        fr.append(np.full(len(P), f))
        pts.append(P)
        cid.append(C)
        along.append(R)
    return (np.concatenate(fr), np.concatenate(pts), np.concatenate(cid), hits,
            np.concatenate(along))


def write_csv(path, fr, pts, cid=None):
    with open(path, "w") as fh:
        fh.write("frame,x,y,z" + (",camera" if cid is not None else "") + "\n")
        for k, (f, p) in enumerate(zip(fr, pts)):
            tail = f",{cid[k]}" if cid is not None else ""
            fh.write(f"{f},{p[0]:.6g},{p[1]:.6g},{p[2]:.6g}{tail}\n")


# ---------------------------------------------------------------------------
# Scene file
# ---------------------------------------------------------------------------
def fmt(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def effects_of(sc):
    e = []
    if sc["gravity_on"]:
        e.append("gravity")
    t = sc["truth"]
    if t["damping_mass"] or t["damping_stiffness"]:
        e.append("damping")
    if sc["ground"] is not None:
        e.append("ground")
    if sc["svk"]:
        e.append("corotation")
    if sc["initial"] is not None:
        e.append("initial_velocity")
    if sc["drag"] is not None:
        e.append("drag")
    if sc["wind"] is not None:
        e.append("wind")
    return e


def describe(sc):
    parts = [f"a {sc['geometry']}", f"clamp {sc['clamp']}", f"motion {sc['motion']}",
             "effects " + ", ".join(effects_of(sc)),
             f"observed by {sc['cameras']} depth camera(s)" if sc["observation"] == "cameras"
             else f"observed by {sc['points']} surface points per frame", f"noise sigma {sc['sigma']:g}"]
    return "; ".join(parts)


def scene_toml(sc):
    s, t = sc["shape"], sc["truth"]
    k = s["kind"]
    if k == "box":
        shape = f'{{ kind = "box", center = {fmt(s["center"])}, size = {fmt(s["size"])} }}'
    elif k == "sphere":
        shape = f'{{ kind = "sphere", center = {fmt(s["center"])}, radius = {float(s["radius"])!r} }}'
    elif k == "torus":
        shape = (f'{{ kind = "torus", center = {fmt(s["center"])}, axis = {fmt(s["axis"])}, '
                 f'major = {float(s["major"])!r}, minor = {float(s["minor"])!r} }}')
    else:
        shape = f'{{ kind = "capsule", a = {fmt(s["a"])}, b = {fmt(s["b"])}, radius = {float(s["radius"])!r} }}'
    L = [f"# Drawn reference scenario '{sc['name']}' (tools/reference/draw.py, scikit-fem), "
         f"seed {sc['seed']}, set {sc['set']}.",
         "# " + describe(sc) + ".",
         "# True parameters and the true model; observations.csv holds noisy observations of the",
         "# reference solution, truth.json the discretisation, convergence and noise floor.",
         "[body]", f"shape = {shape}", f"resolution = {RESOLUTION}", "",
         "[material]", f"young = {t['young']!r}", f"poisson = {t['poisson']!r}",
         f"density = {t['density']!r}", ""]
    if t["damping_mass"] or t["damping_stiffness"]:
        L += ["[damping]", f"mass = {t['damping_mass']!r}", f"stiffness = {t['damping_stiffness']!r}", ""]
    if sc["gravity_on"]:
        L += ["[gravity]", f"acceleration = {fmt(sc['gravity'])}", ""]
    if sc["ground"] is not None:
        gr = sc["ground"]
        L += ["# the reference: frictionless penalty pressure k * penetration per unit area",
              "[ground]", f"normal = {fmt(gr['normal'])}", f"height = {gr['height']!r}",
              'scheme = "penalty"', f"stiffness = {gr['penalty']!r}", "softness = 1000000.0", ""]
    for lo, hi in sc["clamp_boxes"]:
        L += ["# the reference fixes every boundary node inside this box",
              "[[dirichlet]]", f"min = {fmt(np.round(lo, 6))}", f"max = {fmt(np.round(hi, 6))}", ""]
    if sc["initial"] is not None:
        L += ["# rigid motion about the centre of mass", "[initial]",
              f"velocity = {fmt(sc['initial']['velocity'])}",
              f"angular_velocity = {fmt(sc['initial']['angular_velocity'])}", ""]
    if sc["drag"] is not None:
        L += ["# traction -c v on the surface", "[drag]", f"coefficient = {sc['drag']!r}", ""]
    if sc["wind"] is not None:
        L += ["# a uniform traction per unit area on the whole surface", "[wind]",
              f"traction = {fmt(sc['wind'])}", ""]
    L += ["[time]", f"dt = {sc['dt']!r}", f"steps = {sc['steps']}", "theta = 0.5", "",
          "[model]", "effects = [" + ", ".join(f'"{e}"' for e in effects_of(sc)) + "]", "",
          "[fit]", 'parameters = ["young", "poisson"]', ""]
    return "\n".join(L)


# ---------------------------------------------------------------------------
# One scenario
# ---------------------------------------------------------------------------
def dry_line(sc):
    gr = sc["ground"]
    gv = np.asarray(sc["gravity"])
    gtilt = math.degrees(math.acos(min(1.0, -gv[1] / np.linalg.norm(gv)))) if sc["gravity_on"] else None
    return (f"{sc['name']} seed {sc['seed']}: {sc['geometry']} {sc['clamp']} {sc['motion']} "
            f"[{', '.join(effects_of(sc))}] "
            f"size {np.round(dm.bbox(sc['shape'])[1] - dm.bbox(sc['shape'])[0], 3).tolist()}"
            + (f" ground tilt {math.degrees(math.acos(gr['normal'][1])):.1f} deg" if gr else "")
            + (f" gravity tilt {gtilt:.1f} deg" if gtilt else "")
            + f" substeps {sc['substeps']} sigma {sc['sigma']} {sc['observation']}")


def run_scenario(seed, which, out, quick=False, log=print):
    t_start = time.time()
    sc = draw(seed, which)
    log(f"== {sc['name']} (seed {seed}): {describe(sc)}")
    ref = ph.DBody(sc, "reference")
    log(f"    reference mesh: {ref.N} dofs, {ref.mesh.t.shape[1]} cells, {len(ref.fixed) // 3} clamped nodes")
    checks = {}
    if sc["family"] == "tet":
        err = dm.surface_error(ref, sc["shape"])
        checks["surface_vs_analytic_max"] = err
        log(f"    quadratic surface vs analytic: max {err:.2e}")
        assert err < 2.5e-4, err
    if sc["svk"]:
        checks["svk"] = ph.check_svk(ref, ph.svk_force(ref))
    frames, info = ph.run(ref, sc, sc["substeps"], log)
    if sc["initial"] is not None:
        com, mass = ph.center_of_mass(ref)
        checks["center_of_mass_error"] = float(np.linalg.norm(com - sc["initial"]["center"]))
        checks["mass"] = mass
        checks["mass_expected"] = sc["truth"]["density"] * volume(sc["shape"])
    convergence = None
    if not quick:
        convergence = dc.convergence_study(sc, ref, frames, volume(sc["shape"]), log)
    rng = np.random.default_rng([seed, 2])
    d = os.path.join(out, sc["name"])
    os.makedirs(d, exist_ok=True)
    cams, cid, hits, ray_floor = None, None, None, None
    if sc["observation"] == "cameras":
        cams = place_cameras(sc, ref, frames)
        fr, pts, cid, hits, along = observe_cameras(sc, ref, frames, cams, rng)
        ray_floor = float(np.sqrt(np.mean(along ** 2)))
        with open(os.path.join(d, "observations.cameras.json"), "w") as fh:
            fh.write(g.compact_json(dict(cameras=cams)) + "\n")
    else:
        case = dict(steps=sc["steps"], obs_every=1, points=sc["points"], sigma=sc["sigma"])
        fr, pts = g.observe(ref, frames, case, rng)
    write_csv(os.path.join(d, "observations.csv"), fr, pts, cid)
    with open(os.path.join(d, "scene.toml"), "w") as fh:
        fh.write(scene_toml(sc))
    nf, _ = g.noise_floor(ref, frames, fr, pts, 8)
    nr = dc.nonrigid(ref, frames)
    log(f"    largest non-rigid displacement {nr:.2e}")
    kin = g.kinematics(ref, frames)
    log(f"    noise floor {nf:.5f} (sigma {sc['sigma']}), max displacement {kin['max_displacement']:.3f}")
    t = sc["truth"]
    truth = dict(
        seed=sc["seed"], set=which, name=sc["name"],
        generator=dict(script="tools/reference/draw.py", python=platform.python_version(),
                       scikit_fem=skfem.__version__, numpy=np.__version__, scipy=scipy.__version__,
                       solver="CHOLMOD (cvxopt)" if g.HAVE_CHOLMOD else "SuperLU", quick=quick),
        description=describe(sc),
        scenario=dict(geometry=sc["geometry"], shape=sc["shape"], clamp=sc["clamp"],
                      clamp_boxes=sc["clamp_boxes"], motion=sc["motion"], effects=effects_of(sc),
                      ground=None if sc["ground"] is None else dict(
                          normal=sc["ground"]["normal"], height=sc["ground"]["height"],
                          k=sc["ground"]["penalty"],
                          law="frictionless penalty pressure k * penetration per unit reference area"),
                      observation=sc["observation"], cameras=sc["cameras"], sigma=sc["sigma"],
                      points_per_frame=sc["points"]),
        truth=dict(young=t["young"], poisson=t["poisson"], density=t["density"],
                   damping_mass=t["damping_mass"], damping_stiffness=t["damping_stiffness"],
                   gravity=sc["gravity"] if sc["gravity_on"] else None,
                   drag=sc["drag"], wind=sc["wind"], st_venant_kirchhoff=sc["svk"],
                   initial=sc["initial"]),
        draws=sc["draws"],
        discretisation=dict(family="Q2 hexahedra" if sc["family"] == "hex"
                            else "curved P2 tetrahedra (gmsh, isoparametric)",
                            mesh=sc["mesh"]["reference"], dofs=int(ref.N), cells=int(ref.mesh.t.shape[1]),
                            clamped_nodes=int(len(ref.fixed) // 3), substeps=sc["substeps"],
                            dt=sc["dt"], steps=sc["steps"], **ref.h),
        run=info, checks=checks, convergence=convergence, noise_floor=nf,
        noise_floor_camera_rays=ray_floor,
        points=int(len(pts)), max_displacement=kin["max_displacement"], kinematics=kin,
        max_nonrigid_displacement=nr,
        max_displacement_per_frame=g.max_displacement_per_frame(frames),
        camera_hits_per_frame=hits,
        seconds=round(time.time() - t_start, 1))
    with open(os.path.join(d, "truth.json"), "w") as fh:
        fh.write(g.compact_json(truth) + "\n")
    log(f"    wrote {d} in {truth['seconds']:.0f}s")
    return truth


def parse_seeds(text):
    out = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-")
            out += list(range(int(a), int(b) + 1))
        else:
            out.append(int(part))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int)
    ap.add_argument("--seeds", help="e.g. 1-12 or 1,4,7")
    ap.add_argument("--count", type=int, help="draw this many fresh seeds (test set)")
    ap.add_argument("--set", choices=("calibration", "test"), default="calibration")
    ap.add_argument("--out")
    ap.add_argument("--quick", action="store_true", help="skip the convergence runs")
    ap.add_argument("--dry-run", action="store_true", help="only print what each seed draws")
    args = ap.parse_args()
    out = args.out or os.path.join(DEFAULT_ROOT, args.set)
    log = lambda *a: print(*a, flush=True)  # noqa: E731
    if args.count:
        seeds = [secrets.randbits(31) for _ in range(args.count)]
    elif args.seeds:
        seeds = parse_seeds(args.seeds)
    elif args.seed is not None:
        seeds = [args.seed]
    else:
        ap.error("give --seed, --seeds or --count")
    if args.dry_run:
        for s in seeds:
            log(dry_line(draw(s, args.set, dry=True)))
        return 0
    results = []
    for s in seeds:
        try:
            tr = run_scenario(s, args.set, out, args.quick, log)
        except Exception as e:  # noqa: BLE001  a reference that cannot be computed is recorded, not hidden
            log(f"    FAILED seed {s}: {type(e).__name__}: {e}")
            results.append(dict(seed=s, name=None, failed=f"{type(e).__name__}: {e}"))
            continue
        results.append(dict(seed=s, name=tr["name"], converged=(tr["convergence"] or {}).get("converged"),
                            seconds=tr["seconds"]))
    if args.count:
        try:
            commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=g.REPO, capture_output=True,
                                    text=True).stdout.strip()
        except OSError:
            commit = None
        index = dict(set=args.set, seeds=[r["seed"] for r in results], names=[r["name"] for r in results],
                     scenarios=results, commit=commit, command=" ".join(sys.argv),
                     date=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"))
        with open(os.path.join(out, "index.json"), "w") as fh:
            fh.write(json.dumps(index, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
