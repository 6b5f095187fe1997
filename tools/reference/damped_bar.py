#!/usr/bin/env python3
"""Reference data for the damped-bar nu-bias measurement (issue 49, docs/simulation.md).

The hidden.py bar (Q2 16x4x4 graded, consistent mass, Newmark average acceleration, dt 0.03,
20 frames) with Rayleigh damping C = a1 M + a2 K, several (a1, a2, substeps) variants.
Observations: 120 points per frame uniformly by deformed area (hidden.sample_points, same
locations in every variant and noise level: one seed), noise-free and sigma 0.0025 / 0.005,
noise floor as generate.noise_floor (fine surface, s = 8).

Usage: /tmp/skfem-venv/bin/python tools/reference/damped_bar.py OUTDIR   (about 40 s)

Then, for each variant and noise level, `softbody fit SCENE --observations OUTDIR/d2/samples-0.csv
--params young,poisson --optimizer gauss-newton --no-refine-check` with SCENE the bar of
tests/reference_values/independent/hidden/scenes/complete-damping.toml at the variant's a1, a2
(docs/simulation.md, "Why a damped clamped bar's fit moves nu").
"""
import os
for _v in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ[_v] = "1"
import json
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import generate as g  # noqa: E402
import hidden as hd   # noqa: E402

VARIANTS = {
    # name: (a1, a2, reference substeps per frame)
    "d2": (0.8, 0.02, 8),      # the reported case
    "d2s16": (0.8, 0.02, 16),  # same, reference substep halved (time resolution check)
    "d2s1": (0.8, 0.02, 1),    # same, reference at one step per frame (our default dt)
    "d1": (0.8, 0.0, 8),       # mass damping only
    "d1s1": (0.8, 0.0, 1),
    "d0": (0.0, 0.0, 8),       # undamped
    "d0s1": (0.0, 0.0, 1),
}
SIGMAS = (0.0, 0.0025, 0.005)
SEED = 20261207


def main(out):
    os.makedirs(out, exist_ok=True)
    t0 = time.time()
    body = g.Body(hd.BASE, "reference")
    print(f"body: {body.N} dofs in {time.time() - t0:.1f}s", flush=True)
    surf = g.Surface(body, 4)
    info = {}
    frames_of = {}
    for name, (a1, a2, sub) in VARIANTS.items():
        t1 = time.time()
        hd.BASE["damping_stiffness"] = a2
        hd.BASE["substeps"] = sub
        C = hd.sp.csr_matrix((body.N, body.N))
        frames = hd.simulate(body, C, np.zeros(body.N), a1)
        frames_of[name] = frames
        np.save(os.path.join(out, f"{name}-frames.npy"), frames)
        d = os.path.join(out, name)
        os.makedirs(d, exist_ok=True)
        rng = np.random.default_rng(SEED)
        clean = [hd.sample_points(body, surf, frames[f], rng, False)
                 for f in range(1, hd.BASE["steps"] + 1)]
        fr = np.concatenate([np.full(len(p), f) for f, p in zip(range(1, 21), clean)])
        clean = np.concatenate(clean)
        files = {}
        for li, sigma in enumerate(SIGMAS):
            nrng = np.random.default_rng([SEED, li])
            pts = clean + sigma * nrng.normal(size=clean.shape)
            path = os.path.join(d, f"samples-{sigma:g}.csv")
            hd.write_csv(path, fr, pts)
            floor, _ = g.noise_floor(body, frames, fr, pts, 8)
            files[f"{sigma:g}"] = dict(csv=path, sigma=sigma, noise_floor=floor)
        tip = frames[:, np.argmax(body.doflocs[:, 0])]
        info[name] = dict(a1=a1, a2=a2, substeps=sub, files=files,
                          max_displacement=float(np.linalg.norm(frames, axis=2).max()),
                          tip_y=[float(x) for x in tip[:, 1]])
        print(f"{name}: a1 {a1} a2 {a2} substeps {sub}: {time.time() - t1:.1f}s, "
              f"max |u| {info[name]['max_displacement']:.4f}, floors "
              + ", ".join(f"{k}:{v['noise_floor']:.6f}" for k, v in files.items()), flush=True)
    # time-resolution of the reference and of a one-step-per-frame integration (nodal rms)
    cmp = {}
    for a, b in [("d2", "d2s16"), ("d2s1", "d2s16"), ("d1s1", "d1"), ("d0s1", "d0"), ("d2", "d1"),
                 ("d1", "d0")]:
        diff = frames_of[a] - frames_of[b]
        cmp[f"{a}-{b}"] = dict(nodal_rms=float(np.sqrt(np.mean(np.sum(diff ** 2, axis=2)))),
                               nodal_max=float(np.linalg.norm(diff, axis=2).max()))
        print(f"{a} vs {b}: nodal rms {cmp[f'{a}-{b}']['nodal_rms']:.3e} "
              f"max {cmp[f'{a}-{b}']['nodal_max']:.3e}", flush=True)
    json.dump(dict(variants=info, compare=cmp), open(os.path.join(out, "truth.json"), "w"), indent=1)
    print(f"done in {time.time() - t0:.1f}s")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "/tmp/damped-bar")
