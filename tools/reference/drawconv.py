"""Convergence estimates and diagnostics for draw.py: the reference's own discretisation
error by Richardson extrapolation over three mesh levels and three substep counts, and the
non-rigid part of the motion."""

import math

import numpy as np

import generate as g
import drawmesh as dm
import drawphys as ph


def nonrigid(body, frames):
    """Largest distance of a node from the best rigid motion of all nodes (Kabsch), over
    the frames: the deformation an observation could see."""
    X = body.doflocs
    c = X.mean(axis=0)
    out = 0.0
    for U in frames:
        Y = X + U
        d = Y.mean(axis=0)
        Us, _, Vt = np.linalg.svd((X - c).T @ (Y - d))
        R = (Us @ np.diag([1, 1, np.sign(np.linalg.det(Us @ Vt))]) @ Vt).T
        out = max(out, float(np.linalg.norm((X - c) @ R.T + d - Y, axis=1).max()))
    return out



def observed_order(d1, d2, r21, r32, lo=0.25, hi=8.0):
    """p with d2 / d1 = r21^p (r32^p - 1) / (r21^p - 1): the differences d1 = |u_1 - u_0|,
    d2 = |u_2 - u_1| of three levels with error C h^p, h_1 = r21 h_0, h_2 = r32 h_1 (Celik et
    al. 2008's procedure, differences taken as norms); -inf / inf when d2/d1 is below / above
    what p in [lo, hi] gives (not in the asymptotic range)."""
    if not d1 > 0:
        return math.inf
    if not d2 > 0:
        return -math.inf
    f = lambda p: math.log(r21 ** p * (r32 ** p - 1) / (r21 ** p - 1)) - math.log(d2 / d1)  # noqa: E731
    if f(lo) > 0:
        return -math.inf
    if f(hi) < 0:
        return math.inf
    a, b = lo, hi
    for _ in range(100):
        m = 0.5 * (a + b)
        a, b = (m, b) if f(m) < 0 else (a, m)
    return 0.5 * (a + b)


def estimate(d1, d2, r21, r32, p_default, p_range):
    """The finest level's own error d1 / (r21^p - 1): p observed from three levels and clipped
    to p_range (a ratio d2/d1 that no p fits counts as the nearer end: too small, i.e. no
    convergence seen, gives the lower end), or p_default without a third level."""
    if d2 is None:
        p_obs, p, src = None, p_default, "assumed (no third level)"
    else:
        p_obs = observed_order(d1, d2, r21, r32)
        p = min(max(p_obs, p_range[0]), p_range[1])
        src = "observed, clipped to [%g, %g]" % p_range if math.isfinite(p_obs) else \
            "d2/d1 fits no order: the %s end" % ("lower" if p_obs < 0 else "upper")
        p_obs = p_obs if math.isfinite(p_obs) else None
    return dict(p_observed=p_obs, p_used=p, p_source=src,
                reference_error_estimate=float(d1 / (r21 ** p - 1)))


def convergence_study(sc, ref, frames, vol, log=print):
    """The reference's own discretisation error, estimated by Richardson extrapolation of the
    differences of three levels: meshes reference / coarse / coarser (representative cell
    size h = (V / cells)^(1/3)) with the reference substeps, and substeps S / S/2 / S/4 on
    the reference mesh (S/4 only when S is a multiple of 4, else p = 2 is assumed).
    Differences: max (and rms) over 1000 material points on the analytic surface and every
    frame of the displacement difference (generate.compare)."""
    pts = dm.surface_points(sc["shape"], 1000, np.random.default_rng([sc["seed"], 7]))
    S = sc["substeps"]
    hrep = lambda b: (vol / b.mesh.t.shape[1]) ** (1 / 3)  # noqa: E731
    levels, failed = [(ref, frames)], None
    for lev in ("coarse", "coarser"):
        try:
            b = ph.DBody(sc, lev)
        except Exception as e:            # the coarsest tetrahedra: skfem's facet inversion
            if lev == "coarse":
                raise
            failed = f"the coarser mesh failed: {str(e)[:80]}"
            log(f"    {failed}; p = 2 assumed")
            break
        f, _ = ph.run(b, sc, S, log)
        levels.append((b, f))
    cm1 = g.compare([levels[0], levels[1]], pts)
    cm2 = g.compare([levels[1], levels[2]], pts) if len(levels) > 2 else None
    h = [hrep(b) for b, _ in levels]
    mesh = estimate(cm1["max_surface_point_difference"], cm2 and cm2["max_surface_point_difference"],
                    h[1] / h[0], h[2] / h[1] if cm2 else 1.5, 2.0, (1.0, 3.0))
    mesh.update(max_ref_coarse=cm1["max_surface_point_difference"],
                rms_ref_coarse=cm1["rms_surface_point_difference"],
                max_coarse_coarser=cm2 and cm2["max_surface_point_difference"],
                rms_coarse_coarser=cm2 and cm2["rms_surface_point_difference"], third_level_failure=failed,
                dofs=[int(b.N) for b, _ in levels], cells=[int(b.mesh.t.shape[1]) for b, _ in levels],
                h_representative=h)
    subs = [S, S // 2] + ([S // 4] if S % 4 == 0 and S // 4 >= 2 else [])
    tl = [frames]
    for s in subs[1:]:
        f, _ = ph.run(ref, sc, s, log)
        tl.append(f)
    ct1 = g.compare([(ref, tl[0]), (ref, tl[1])], pts)
    ct2 = g.compare([(ref, tl[1]), (ref, tl[2])], pts) if len(tl) > 2 else None
    time_ = estimate(ct1["max_surface_point_difference"],
                     None if ct2 is None else ct2["max_surface_point_difference"], 2.0, 2.0, 2.0, (1.0, 2.0))
    time_.update(substeps=subs, max_ref_half=ct1["max_surface_point_difference"],
                 rms_ref_half=ct1["rms_surface_point_difference"],
                 max_half_quarter=None if ct2 is None else ct2["max_surface_point_difference"])
    c = dict(mesh=mesh, time=time_, points=1000,
             location_residual=max(cm1["location_residual"], ct1["location_residual"],
                                   cm2["location_residual"] if cm2 else 0.0),
             # the raw differences as before (the cheaper run's error, an overestimate)
             mesh_max=cm1["max_surface_point_difference"], mesh_rms=cm1["rms_surface_point_difference"],
             time_max=ct1["max_surface_point_difference"], time_rms=ct1["rms_surface_point_difference"],
             mesh_error_estimate=mesh["reference_error_estimate"],
             time_error_estimate=time_["reference_error_estimate"])
    c["converged"] = bool(max(c["mesh_error_estimate"], c["time_error_estimate"]) < 0.2 * sc["sigma"])
    log(f"    convergence: mesh diffs {c['mesh_max']:.2e}, {mesh['max_coarse_coarser']} (h "
        f"{', '.join(f'{x:.3f}' for x in h)}), p {mesh['p_observed']} -> error {c['mesh_error_estimate']:.2e}; "
        f"time diffs {c['time_max']:.2e}, {time_['max_half_quarter']} p {time_['p_observed']} -> "
        f"error {c['time_error_estimate']:.2e}")
    if not c["converged"]:
        log(f"    WARNING {sc['name']}: estimated error above 0.2 sigma = {0.2 * sc['sigma']:.1e}")
    return c
