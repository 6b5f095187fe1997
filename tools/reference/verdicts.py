#!/usr/bin/env python3
"""Diagnosis verdicts on drawn reference scenarios (issue 50, item 5).

For every drawn scenario (a folder written by `draw.py`) two diagnoses are run with the
project's `softbody diagnose` (its defaults, the discretisation check included):

- **hidden**: one effect of the truth that the diagnosis' catalogue knows (gravity, damping,
  ground, initial_velocity, drag, corotation) is removed from the scene (its section and its
  `[model].effects` entry), chosen by `numpy.random.default_rng([seed, 9])`; the hidden effect
  should be named first, or listed as an alternative the data cannot tell from the first.
- **control**: the scene with every effect of the truth; nothing should be called missing.
  Each drawn scenario is its own trajectory, so the controls are independent trials.

Both start Young's modulus and the Poisson ratio 10-20% off the truth (same rng), as a user
who does not know them would. Each row (JSON lines) holds the verdict, the named effect, the
alternatives, the margin (the model's rms over the named effect's refit), the noise floor over
the true sigma, the named effect's short-refit rms over sigma (an upper bound of the refit
after adding it), the plausibility line and the seconds. `--table` prints the summary with
the Clopper-Pearson 95% upper bound of the false-alarm rate.

    /tmp/skfem-venv/bin/python tools/reference/verdicts.py DRAWS... --out R.jsonl
    /tmp/skfem-venv/bin/python tools/reference/verdicts.py --table R.jsonl
"""

import argparse
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from evaluate import scenario_folders  # noqa: E402  one walk over draw folders

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# the effects the diagnosis probes, with the scene section each one reads
HIDEABLE = {
    "gravity": "gravity",
    "damping": "damping",
    "ground": "ground",
    "initial_velocity": "initial",
    "drag": "drag",
    "corotation": None,
}


def without(text, effect):
    """The scene text without `effect`: its section removed and its entry in `[model].effects`."""
    section = HIDEABLE[effect]
    if section is not None:
        lines, keep, skip = text.splitlines(), [], False
        for line in lines:
            head = re.match(r"^\s*\[\[?([A-Za-z_.]+)\]?\]\s*$", line)
            if head:
                skip = head.group(1) == section
            if not skip:
                keep.append(line)
        text = "\n".join(keep) + "\n"
    pattern = re.compile(r"^effects\s*=\s*\[(.*)\]\s*$", re.M)
    m = pattern.search(text)
    items = [e.strip().strip('"') for e in m.group(1).split(",") if e.strip()]
    items = [e for e in items if e != effect]
    return pattern.sub("effects = [" + ", ".join(f'"{e}"' for e in items) + "]", text)


def started(text, rng):
    """The scene text with Young's modulus and the Poisson ratio 10-20% off (random sign)."""
    def off(m, clip):
        v = float(m.group(2)) * (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.2))
        return f"{m.group(1)}{float(min(max(v, clip[0]), clip[1]))!r}"
    text = re.sub(r"^(young\s*=\s*)([0-9.eE+-]+)", lambda m: off(m, (1e-300, 1e300)), text, flags=re.M)
    return re.sub(r"^(poisson\s*=\s*)([0-9.eE+-]+)", lambda m: off(m, (0.02, 0.48)), text, flags=re.M)


def diagnose(binary, scene_text, folder, out, tag):
    """Runs `softbody diagnose --json` on `scene_text` placed beside the scenario's files."""
    path = os.path.join(out, f"{tag}.toml")
    with open(path, "w") as f:
        f.write(scene_text)
    obs = os.path.join(folder, "observations.csv")
    cmd = [binary, "diagnose", path, "--observations", obs, "--out", os.path.join(out, tag), "--json"]
    cams = os.path.join(folder, "observations.cameras.json")
    if os.path.exists(cams):
        cmd += ["--cameras", cams]
    t = time.time()
    p = subprocess.run(cmd, capture_output=True, text=True)
    seconds = time.time() - t
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["?"])[-1], "seconds": seconds}
    d = json.loads(p.stdout)
    d["seconds"] = seconds
    return d


def refit(binary, scene_text, folder, out, d):
    """Adds the named effect with its suggested values to `scene_text` and fits it on with
    `softbody fit` (Young's modulus, the Poisson ratio and the effect's parameters), as a user
    does after the verdict; returns the rms, or None."""
    named = d.get("missing_effect")
    cand = next((c for c in d.get("candidates", []) if c["effect"] == named), None)
    if cand is None:
        return None
    text = scene_text
    if cand["suggestion"].startswith("[") and not cand["suggestion"].startswith("[model]"):
        text = text.replace("\n[time]", "\n" + cand["suggestion"] + "\n\n[time]", 1)
    elif cand["suggestion"].startswith("[model]"):
        return None  # a stiffness field's basis is not a scene section a fit can start from here
    pattern = re.compile(r"^effects\s*=\s*\[(.*)\]\s*$", re.M)
    m = pattern.search(text)
    items = [e.strip().strip('"') for e in m.group(1).split(",") if e.strip()] + [named]
    text = pattern.sub("effects = [" + ", ".join(f'"{e}"' for e in items) + "]", text)
    groups = []
    for label in cand["parameters"]:
        g = re.split(r"[.\[]", label)[0]
        if g not in groups:
            groups.append(g)
    path = os.path.join(out, "refit.toml")
    with open(path, "w") as f:
        f.write(text)
    obs = os.path.join(folder, "observations.csv")
    params = ",".join(["young", "poisson"] + groups)
    cmd = [binary, "fit", path, "--observations", obs, "--params", params, "--out", os.path.join(out, "refit"), "--json"]
    cams = os.path.join(folder, "observations.cameras.json")
    if os.path.exists(cams):
        cmd += ["--cameras", cams]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return None
    rms = json.loads(p.stdout).get("rms")
    return rms.get("final") if isinstance(rms, dict) else rms


def row(kind, folder, truth, hidden, d):
    sigma = truth["scenario"]["sigma"]
    r = {
        "name": truth["name"],
        "seed": truth["seed"],
        "kind": kind,
        "hidden": hidden,
        "geometry": truth["scenario"]["geometry"],
        "clamp": truth["scenario"]["clamp"],
        "motion": truth["scenario"]["motion"],
        "effects": truth["scenario"]["effects"],
        "observation": truth["scenario"]["observation"],
        "sigma": sigma,
        "seconds": d.get("seconds"),
    }
    if "error" in d:
        r["error"] = d["error"]
        return r
    named = d.get("missing_effect")
    cands = {c["effect"]: c for c in d.get("candidates", [])}
    after = cands.get(named, {}).get("rms_after") if named else None
    r.update({
        "missing_effect": named,
        "alternatives": d.get("alternatives", []),
        "verdict": d.get("verdict", "").splitlines()[0] if d.get("verdict") else None,
        "rms": d.get("rms"),
        "margin": (d["rms"] / after) if after else None,
        "after_over_sigma": (after / sigma) if after else None,
        "floor_over_sigma": (d["noise_floor"] / sigma) if d.get("noise_floor") else None,
        "plausibility": d.get("plausibility"),
        "refit_over_sigma": (d["refit_rms"] / sigma) if d.get("refit_rms") else None,
        "refit_seconds": d.get("refit_seconds"),
        "unverified": d.get("unverified"),
        "unchecked": d.get("unchecked"),
    })
    if kind == "hidden":
        r["named_first"] = named == hidden
        r["named_or_alternative"] = named == hidden or (named is not None and hidden in r["alternatives"])
    else:
        r["false_alarm"] = named is not None
    return r


def clopper_pearson_upper(k, n, level=0.95):
    """One-sided upper bound of a binomial rate with `k` events in `n` trials."""
    if n == 0:
        return 1.0
    if k >= n:
        return 1.0
    lo, hi = k / n, 1.0
    from math import comb
    def cdf(p):
        return sum(comb(n, i) * p**i * (1 - p) ** (n - i) for i in range(k + 1))
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if cdf(mid) > 1 - level:
            lo = mid
        else:
            hi = mid
    return hi


def table(paths):
    rows = [json.loads(l) for p in paths for l in open(p) if l.strip()]
    hidden = [r for r in rows if r["kind"] == "hidden" and "error" not in r]
    controls = [r for r in rows if r["kind"] == "control" and "error" not in r]
    # the hidden effect's own margin: the model without it over the full model, both fitted
    # (E, nu) by the diagnosis; the target counts the draws where it is >= 1.5
    full = {r["name"]: r["rms"] for r in controls}
    for r in hidden:
        r["truth_margin"] = r["rms"] / full[r["name"]] if full.get(r["name"]) else None
    errors = [r for r in rows if "error" in r]
    print("| draw | hidden | geometry | clamp | motion | observation | sigma | named | alternatives | margin | truth margin | floor/sigma | short refit/sigma | refit/sigma | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    f = lambda v: "-" if v is None else f"{v:.3g}"
    for r in hidden:
        print(f"| {r['name']} | {r['hidden']} | {r['geometry']} | {r['clamp']} | {r['motion']} | {r['observation']} | {r['sigma']} | {r['missing_effect'] or '-'} | {', '.join(r['alternatives']) or '-'} | {f(r['margin'])} | {f(r['truth_margin'])} | {f(r['floor_over_sigma'])} | {f(r['after_over_sigma'])} | {f(r.get('refit_over_sigma'))} | {r['seconds']:.0f} |")
    print()
    print("| draw | control: named | floor/sigma | s |")
    print("|---|---|---|---|")
    for r in controls:
        print(f"| {r['name']} | {r['missing_effect'] or '-'} | {f(r['floor_over_sigma'])} | {r['seconds']:.0f} |")
    n = len(hidden)
    first = sum(r["named_first"] for r in hidden)
    either = sum(r["named_or_alternative"] for r in hidden)
    visible = [r for r in hidden if (r["truth_margin"] or 0) >= 1.5]
    with_margin = sum(r["named_or_alternative"] for r in visible)
    visible_first = sum(r["named_first"] for r in visible)
    alarms = sum(r["false_alarm"] for r in controls)
    floors = [r["floor_over_sigma"] for r in hidden + controls if r["floor_over_sigma"]]
    within = sum(abs(x - 1) <= 0.2 for x in floors)
    refits = [r.get("refit_over_sigma") for r in hidden if r["named_first"] and r.get("refit_over_sigma")]
    secs = sorted(r["seconds"] for r in hidden + controls)
    print()
    print(f"hidden: named first {first}/{n}, first or alternative {either}/{n}")
    print(f"hidden with truth margin >= 1.5: named first {visible_first}/{len(visible)}, first or alternative {with_margin}/{len(visible)}")
    print(f"controls: false alarms {alarms}/{len(controls)}, Clopper-Pearson 95% upper bound {clopper_pearson_upper(alarms, len(controls)):.3f}")
    print(f"noise floor within +-20% of sigma: {within}/{len(floors)}")
    print(f"refit after adding the named (hidden) effect within 1.3 sigma: {sum(x <= 1.3 for x in refits)}/{len(refits)}")
    if secs:
        print(f"seconds per diagnosis: median {secs[len(secs) // 2]:.0f}, max {secs[-1]:.0f}")
    print(f"errors: {len(errors)}" + "".join(f"\n  {r['name']} {r['kind']}: {r['error']}" for r in errors))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("draws", nargs="*")
    ap.add_argument("--out", help="JSON lines, appended")
    ap.add_argument("--work", default="/tmp/verdicts", help="scratch folder for scenes and reports")
    ap.add_argument("--binary", default=os.path.join(REPO, "target", "release", "softbody"))
    ap.add_argument("--table", action="append")
    a = ap.parse_args()
    if a.table:
        table(a.table)
        return
    done = set()
    if a.out and os.path.exists(a.out):
        done = {(json.loads(l)["name"], json.loads(l)["kind"]) for l in open(a.out) if l.strip()}
    for folder in scenario_folders(a.draws):
        truth = json.load(open(os.path.join(folder, "truth.json")))
        text = open(os.path.join(folder, "scene.toml")).read()
        rng = np.random.default_rng([truth["seed"], 9])
        known = [e for e in truth["scenario"]["effects"] if e in HIDEABLE]
        hidden = str(rng.choice(known)) if known else None
        start = started(text, rng)
        work = os.path.join(a.work, truth["name"])
        os.makedirs(work, exist_ok=True)
        for kind in ("hidden", "control"):
            if (truth["name"], kind) in done or (kind == "hidden" and hidden is None):
                continue
            scene = without(start, hidden) if kind == "hidden" else start
            d = diagnose(a.binary, scene, folder, work, kind)
            if kind == "hidden" and "error" not in d and d.get("missing_effect"):
                t = time.time()
                d["refit_rms"] = refit(a.binary, scene, folder, work, d)
                d["refit_seconds"] = time.time() - t
            r = row(kind, folder, truth, hidden if kind == "hidden" else None, d)
            print(json.dumps(r), flush=True)
            if a.out:
                with open(a.out, "a") as f:
                    f.write(json.dumps(r) + "\n")


if __name__ == "__main__":
    sys.exit(main())
