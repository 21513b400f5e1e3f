#!/usr/bin/env python3
"""The stress matrix: scenes derived from the shipped ones, pushed to the extremes a
user pushes them to, each with an expectation that comes from outside the code under test (a
formula, the geometry, the KKT conditions checked on the stored fields). Every case either
states what it expects: an answer that passes its check (the default), a refusal with a reason
(exit 2 naming the field, the store not created: `refusal`), or either (`either`: a case whose
machine decides, said in its docstring). A refusal where an answer is expected is a FAIL, as is
an answer where a refusal is, and anything else. Every artifact of every case is scanned for
NaN and infinity.

  python3 scripts/stress.py           the whole matrix (`just stress`), release build
  python3 scripts/stress.py --fast    the fast subset (run by tests/python/test_stress.py in CI)
  CROM_BIN=target/debug/crom ...      another binary

Prints one Markdown row per case: case, expectation, measured, verdict. Exit 1 if any case
FAILs.
"""
import argparse
import json
import math
import os
import pathlib
import re
import shutil
import subprocess
import sys
import tempfile
import time

import h5py
import numpy as np
import pandas as pd


def either(check):
    """Mark `check` as a case that may be answered or refused with a reason (its docstring says
    why the machine decides)."""
    check.outcome = "either"
    return check


def verdict(expect, returncode, out, problems, field=None, store_exists=False):
    """The verdict of one case: `expect` is "pass", "refused" or "either"; `problems` are the
    check's findings on an answer (exit 0) or the scan's on a refusal. A refusal needs exit 1 or
    2 with a fix, and, for an expected one naming `field`, that field and no store."""
    if returncode == 0:
        if expect == "refused":
            return "FAIL: answered, though the case should be refused: " + "; ".join(problems or ["ran"])
        return "pass" if not problems else "FAIL: " + "; ".join(problems)
    if returncode in (1, 2) and "fix" in out:
        first = out.strip().splitlines()[0] if out.strip() else ""
        if expect == "pass":
            return f"FAIL: refused, though the case should be answered: {first}"
        problems = list(problems)
        if field and (f"field `{field}`" not in out or store_exists):
            problems.append(f"refused without naming `{field}`, or after writing to the store")
        return "refused (exit %d)" % returncode if not problems else "FAIL: " + "; ".join(problems)
    return f"FAIL: no answer and no reason (exit {returncode})"

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from scene_variant import variant  # noqa: E402
from artifact_scan import nonfinite  # noqa: E402

REPO = pathlib.Path(__file__).resolve().parents[1]

# KKT tolerances of the stored solver evidence, as the Rust and Python suites state them: the
# solver stops at rel_tol = 1e-10 on penetration and complementarity (scene files), the
# equilibrium residual is relative to the load and carries the factorisation's round-off (1e-8).
PEN_TOL, COMP_TOL, KKT_TOL = 1e-10, 1e-10, 1e-8


GIB = 1 << 30


class Measured:
    """A finished child: returncode, stdout, stderr and its own peak RSS in bytes."""

    def __init__(self, returncode, stdout, stderr, rss):
        self.returncode, self.stdout, self.stderr, self.rss = returncode, stdout, stderr, rss


def run_measured(cmd):
    """Run cmd in the repository with its output in temporary files; its peak RSS comes from
    wait4's rusage of that child alone (no /usr/bin/time needed)."""
    with tempfile.TemporaryFile() as o, tempfile.TemporaryFile() as e:
        p = subprocess.Popen(cmd, cwd=REPO, stdout=o, stderr=e)
        _, status, usage = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
        o.seek(0)
        e.seek(0)
        return Measured(p.returncode, o.read().decode(), e.read().decode(), usage.ru_maxrss * 1024)


def estimate_of(scene):
    """crom's own memory estimate of a scene, in bytes, from the refusal under a 1 KiB limit."""
    p = run_measured([str(MEMO["binary"]), "--store", str(pathlib.Path(scene).with_suffix(".none")),
                      "--max-memory", "1K", "solve", str(scene)])
    m = re.search(r"estimated ([0-9.]+) (KiB|MiB|GiB|TiB|B)\b", p.stdout + p.stderr)
    assert m, p.stdout + p.stderr
    return float(m.group(1)) * {"B": 1, "KiB": 1 << 10, "MiB": 1 << 20, "GiB": 1 << 30, "TiB": 1 << 40}[m.group(2)]


def refined(k):
    """ironing-fine refined k times per direction, two training points (the finest-mesh row)."""
    return [("nx = 200", f"nx = {200 * k}"), ("ny = 40", f"ny = {40 * k}"), ("nx = 60", f"nx = {60 * k}"),
            ("ny = 60", f"ny = {60 * k}"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2"),
            ("nested_levels = 7", "nested_levels = 0")]


@either
def finest_mesh(store, out):
    """The finest mesh the matrix runs (answered, or refused by the memory estimate on a machine
    too small for it), with the memory estimate that decides which meshes a machine holds: KKT checks at every point; the run's peak RSS within a factor 1.5 of crom's
    estimate either way (the estimate must neither let through a mesh that cannot fit nor
    refuse one that can); and the largest refinement per direction whose estimate fits in this
    machine's MemAvailable, reported."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    est, rss = estimate_of(MEMO["scene"]), MEMO["rss"]
    if not est / 1.5 <= rss <= 1.5 * est:
        problems.append(f"peak RSS {rss / GIB:.2f} GiB vs estimate {est / GIB:.2f} GiB: off by more than 1.5x")
    avail = next(int(l.split()[1]) * 1024 for l in pathlib.Path("/proc/meminfo").read_text().splitlines()
                 if l.startswith("MemAvailable:"))
    tmp = pathlib.Path(MEMO["scene"]).parent
    k = 4
    while k < 64 and estimate_of(variant(tmp, "ironing-fine", f"finest-{k + 1}", refined(k + 1), ["comparison"])) <= avail:
        k += 1
    return (f"{len(idx)} points, max KKT {idx.kkt_residual.max():.1e}; peak RSS {rss / GIB:.2f} GiB, estimate "
            f"{est / GIB:.2f} GiB; the estimate admits up to {k}x per direction in this machine's "
            f"{avail / GIB:.1f} GiB"), problems


def index_of(store):
    (path,) = list((store / "columns").glob("*/index.parquet"))
    return pd.read_parquet(path)


def mesh_of(store):
    (path,) = list((store / "mesh").glob("*/mesh.h5"))
    with h5py.File(path, "r") as f:
        return f["nodes"][:], f["contact_nodes"][:], f["node_body"][:]


def dual_of(store, row):
    with h5py.File(store / row["block"], "r") as f:
        return f["dual"][:, int(row["column"])]


def kkt(index, max_iter):
    """The solver evidence of every stored point against the KKT tolerances."""
    problems = []
    for col, ok in [("max_penetration", index.max_penetration <= PEN_TOL),
                    ("complementarity", index.complementarity <= COMP_TOL),
                    ("kkt_residual", index.kkt_residual <= KKT_TOL),
                    ("min_lambda", index.min_lambda >= 0),
                    ("iterations", index.iterations < max_iter)]:
        if not ok.all():
            problems.append(f"{col} {index.loc[~ok, col].tolist()}")
    return problems


# ---- the cases -------------------------------------------------------------------------------

def hertz_first_touch(store, out):
    """d = 1e-6 .. 1e-4: the bodies overlap geometrically over a half-width sqrt(R d) (two
    circles of radius R = 1 approaching by d, d/2 each), far below the arc's node spacing
    h = 2 sin(pi/156): at most the bottom node and its two neighbours can carry pressure."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    h = 2 * math.sin(math.pi / 156)
    bound = [2 * math.ceil(math.sqrt(d) / h) + 1 for d in idx.d]
    over = [(d, a, b) for d, a, b in zip(idx.d, idx.active, bound) if a > b or a < 1]
    if over:
        problems.append(f"active (d, count, bound) {over}")
    return f"active {sorted(idx.active.tolist())} (bound {max(bound)}), {len(idx)} points", problems


def hertz_theory(store, out):
    """Hertz theory for two equal cylinders in plane strain (R* = R / 2, E* = E / (2 (1 - nu^2)),
    R = 1, E = 1, nu = 0.3): from the total force P (pressure times tributary arc length),
    half-width a = sqrt(4 P R* / (pi E*)) and peak p0 = 2 P / (pi a). The outermost pressed node
    lies within a, the next one outside, so a is at most one node spacing h (in x) beyond the
    pressed half-width; the peak is p0. Hertz idealises the bodies as half-spaces, an error of
    order a / R (up to 0.43 here), allowed as 10 % of a and of p0."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    nodes, contact, _ = mesh_of(store)
    pts = nodes[contact]
    order = np.argsort(pts[:, 0])
    xs, seg = pts[order, 0], np.linalg.norm(np.diff(pts[order], axis=0), axis=1)
    trib = np.zeros(len(xs))
    trib[1:] += seg / 2
    trib[:-1] += seg / 2
    e_star, r_star = 1.0 / (2 * (1 - 0.3 ** 2)), 0.5
    worst_a, worst_p = 0.0, 0.0
    for _, row in idx.sort_values("d").iterrows():
        lam = dual_of(store, row)[order]
        force = float(lam @ trib)
        a = math.sqrt(4 * force * r_star / (math.pi * e_star))
        p0 = 2 * force / (math.pi * a)
        on = np.flatnonzero(lam > 0)
        half = (xs[on].max() - xs[on].min()) / 2
        h = float(np.diff(xs).max())
        # distance of a outside [half, half + h], relative to a; the peak's relative misfit
        off = max(half - a, a - (half + h), 0.0) / a
        worst_a, worst_p = max(worst_a, off), max(worst_p, abs(lam.max() / p0 - 1))
        if off > 0.1 or abs(lam.max() / p0 - 1) > 0.1:
            problems.append(f"d {row['d']:.4g}: a {a:.4f} vs pressed half-width {half:.4f} (h {h:.4f}), "
                            f"peak {lam.max():.4g} vs p0 {p0:.4g}")
    return (f"a outside [pressed half-width, + h] by <= {100 * worst_a:.1f} % of a, peak vs p0 <= "
            f"{100 * worst_p:.1f} %, {len(idx)} points"), problems


def ironing_active_extent(store, idx):
    nodes, contact, _ = mesh_of(store)
    extents = []
    for _, row in idx.iterrows():
        lam = dual_of(store, row)
        on = np.flatnonzero(lam > 0)
        extents.append(float(np.ptp(nodes[contact[on], 0])) if len(on) else 0.0)
    return extents


def ironing_grazing(store, out):
    """d_y = 1e-5: the sole (radius R = 2) overlaps the slab over a half-width sqrt(2 R d_y) =
    0.0063, below both meshes' spacings (slab 0.05): at most 3 slab nodes carry pressure, and
    at least one (the iron presses)."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    bad = [int(a) for a in idx.active if a < 1 or a > 3]
    if bad:
        problems.append(f"active counts {bad} outside [1, 3]")
    return f"active {sorted(set(idx.active.tolist()))}, {len(idx)} points", problems


def ironing_deep(store, out):
    """d_y = 0.06, just below the depth 0.0635 at which the sole's corners would reach the slab:
    the contact may span the sole (width 1) but not beyond it: the pressed slab nodes' extent
    is at most 1 + 2 h (h = 0.05, the slab spacing)."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    ext = ironing_active_extent(store, idx)
    if max(ext) > 1 + 2 * 0.05:
        problems.append(f"contact extent {max(ext):.3f} > 1.1")
    return f"contact extent {min(ext):.3f}-{max(ext):.3f}, {len(idx)} points", problems


def kkt_only(what):
    def check(store, out):
        idx = index_of(store)
        return f"{len(idx)} points, max iterations {int(idx.iterations.max())}, max KKT {idx.kkt_residual.max():.1e}", \
            kkt(idx, 200)
    check.__doc__ = what
    return check


def reduced_solve(store, out):
    """The whole study on 129 near-duplicate points: the online solve meets nearly parallel dual
    vectors (CPG generators whose Gram is singular to working precision) and primal ranks 1-3
    against up to 21 of them. The reduced inf-sup constant is computed and reported for every
    rank pair (finite; 0 where the dual vectors outnumber the primal modes or coincide); no
    exact query fails — each converges or is refused as infeasible; and at the largest ranks
    the answers match the full-order solutions to 1e-6 in relative H1 (the primal snapshots
    span 3 dimensions to 1e-10, and the test points interpolate them)."""
    (path,) = list((store / "rom").glob("*/tradeoff.parquet"))
    t = pd.read_parquet(path)
    problems = []
    if not np.isfinite(t.min_inf_sup).all() or not (t.min_inf_sup == 0).any():
        problems.append(f"min_inf_sup {t.min_inf_sup.tolist()}: not finite everywhere, or never 0")
    ex = t[t.algorithm == "exact"]
    if (ex.failed > 0).any():
        problems.append(f"exact failures {ex[ex.failed > 0][['r_primal', 'r_dual', 'failed']].values.tolist()}")
    top = ex[(ex.r_primal == ex.r_primal.max()) & (ex.r_dual == ex.r_dual.max())]
    err = float(top.max_primal_error.max())
    if not err <= 1e-6:
        problems.append(f"largest-rank primal error {err:.1e} > 1e-6")
    zero = int((t.min_inf_sup == 0).sum())
    return (f"{len(t)} rank pairs, inf-sup 0 at {zero}; exact: {int(ex.converged.sum())} converged, "
            f"{int(ex.infeasible.sum())} infeasible, {int(ex.failed.sum())} failed; max H1 error at full ranks "
            f"{err:.1e}"), problems


def published(store):
    """The scene's published directory (stable names) of the case that just ran."""
    return store / "scenes" / pathlib.Path(MEMO["scene"]).stem


def no_contact(store, out):
    """The obstacle 50 below the rope: every pressure snapshot is zero, so the lifted
    contact-free solution is exact (primal error <= 1e-12 at every point, both algorithms) and
    the relative dual error is 0/0: a null in the file, never NaN."""
    d = published(store)
    with h5py.File(d / "train.h5", "r") as f:
        zero = not np.any(f["dual"][()])
    e = pd.read_parquet(d / "rom_errors.parquet")
    problems = [] if zero else ["a pressure snapshot is not zero"]
    if not ((e.outcome == "converged").all() and (e.primal_error <= 1e-12).all() and e.dual_error.isna().all()):
        problems.append(f"outcomes {set(e.outcome)}, max primal error {e.primal_error.max():.1e}, "
                        f"{int(e.dual_error.notna().sum())} dual errors not null")
    return f"{len(e)} queries, max primal error {e.primal_error.max():.1e}, dual errors null", problems


def tolerance_one(store, out):
    """Truncation tolerance 1 is met by the empty cone (||lambda - 0|| / ||lambda|| = 1): the
    truncated dual basis is empty, the reduced pressure zero (dual error exactly 1 where there
    is contact), and the contact-free answer penetrates the obstacle, which the indicator
    reports at every such point."""
    e = pd.read_parquet(published(store) / "rom_errors.parquet")
    t = e[(e.dual_basis == "truncated") & e.dual_error.notna()]
    problems = []
    if not (len(t) and (t.r_dual == 0).all() and np.allclose(t.dual_error, 1.0, rtol=0, atol=1e-15)
            and (t.penetration > 0).all()):
        problems.append("the empty basis is not what the run reports")
    return f"{len(t)} queries with an empty dual basis, dual error 1, penetration flagged", problems


def rank_beyond(store, out):
    """study.max_rank = 1000 with 10 snapshots: the curves stop at m = 10."""
    c = pd.read_parquet(published(store) / "compactness.parquet")
    return f"curves up to m = {int(c.m.max())}", [] if c.m.max() == 10 else [f"curves up to {c.m.max()}"]


def refusal(field, why=""):
    """A check for a setting that cannot work: refused with exit 2 naming `field` and the fix,
    the store not even created (the harness checks both; an answer is a FAIL)."""
    def check(store, out):
        return "ran", [f"ran instead of refusing `{field}`"]
    check.__doc__ = f"Refused with exit 2 naming `{field}` and the fix, nothing written to the store{why}."
    check.field = field
    check.outcome = "refused"
    return check



MEMO = {}


def total_force(store, idx):
    """Total contact force per point: the pressure at each slab-top node times its tributary
    length (half the distance to each neighbour along the surface), from the mesh."""
    nodes, contact, _ = mesh_of(store)
    x = nodes[contact, 0]
    order = np.argsort(x)
    xs = x[order]
    trib = np.zeros_like(xs)
    trib[1:] += np.diff(xs) / 2
    trib[:-1] += np.diff(xs) / 2
    out = []
    for _, row in idx.sort_values("d_x").iterrows():
        out.append(float(dual_of(store, row)[order] @ trib))
    return np.array(out)


def locking(store, out):
    """nu = 0.4999 in both bodies, full integration: lambda/mu = 2 nu / (1 - 2 nu) = 5000 and
    fully integrated Q1 elements lock; the run must say so, naming each material field and the
    remedy (integration = "selective"), and still give KKT-checked answers."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    warned = [f for f in ("model.ironing.slab.material", "model.ironing.iron.material")
              if f in out and "lock" in out and 'integration = "selective"' in out]
    if len(warned) != 2:
        problems.append(f"locking warning for {warned}, expected both bodies")
    MEMO["locked_force"] = total_force(store, idx)
    return f"{len(idx)} points; warned for {len(warned)} bodies", problems


def selective(store, out):
    """The same with integration = "selective" in both materials: no warning, KKT-checked
    answers, and a smaller contact force at every point than the locked run's (locking is
    spurious stiffness: at an imposed indentation, a stiffer model pushes back harder)."""
    idx = index_of(store)
    problems = kkt(idx, 200)
    if "lock" in out:
        problems.append("warned although the remedy is on")
    force = total_force(store, idx)
    locked = MEMO.get("locked_force")
    if locked is None:
        problems.append("the locked case did not run")
        ratio = float("nan")
    else:
        ratio = float(np.max(force / locked))
        if not (force < locked).all():
            problems.append(f"force not below the locked run's: {force} vs {locked}")
    return f"force / locked force <= {ratio:.3f}", problems


@either
def coarse_mesh_run(store, out):
    """A 5 x 1 slab (one element through the thickness): the study runs to the end or stops
    with a reason (its bases may be too poor for a stage); its snapshots satisfy the KKT checks;
    no artifact holds NaN (tested below)."""
    idx = index_of(store)
    return f"{len(idx)} points, report {'yes' if list(store.glob('report/*/index.html')) else 'no'}", kkt(idx, 200)


def near_duplicates(store, out):
    """Near-duplicate training points (neighbouring pressure snapshots nearly equal): the
    cone-projected greedy basis selects no snapshot twice and adds no generator once the
    selected ones represent the set to the snapshots' own accuracy (C(m) below the solver's
    rel_tol = 1e-10: a further generator would fit solver noise); its compactness C(m) agrees
    with scipy's NNLS (Lawson-Hanson on a QR factorisation, an independent implementation) on
    the stored generators to 1e-6 absolute: crom's NNLS works on the Gram and refuses a
    generator whose squared pivot is below 1e-12 of its diagonal (NnlsParams::pivot_tol), i.e.
    one within an angle of 1e-6 of the span of the others, so its residual may exceed the QR
    optimum by up to 1e-6 of a snapshot's norm; the Gram's condition estimate is stored, finite
    or 0 (singular to working precision), for every step; every metric is finite (tested
    below)."""
    from scipy.optimize import nnls
    (path,) = list((store / "basis").glob("*/basis.h5"))
    with h5py.File(path, "r") as f:
        sel = f["dual_cpg/selected"][:]
        comp = f["dual_cpg/compactness"][:]
        modes = f["dual_cpg/modes"][:]
        rcond = f["dual_cpg/gram_rcond"][:]
        sv = f["dual_pod/singular_values"][:]
    problems = [] if len(np.unique(sel)) == len(sel) else ["a snapshot selected twice"]
    noise = int(np.sum(comp[:-1] < 1e-10))
    if noise:
        problems.append(f"{noise} generators added after C(m) < 1e-10")
    if len(rcond) != len(sel) or not np.all(np.isfinite(rcond)):
        problems.append(f"gram_rcond has {int(np.isfinite(rcond).sum())} finite values for {len(sel)} generators")
    # C(m) of eq. 16 over every training snapshot, recomputed with scipy on the stored generators
    basis_manifest = json.loads(path.with_name("manifest.json").read_text())
    train = store / "trainset" / basis_manifest["inputs"]["train"] / "snapshots.h5"
    with h5py.File(train, "r") as f:
        dual = f["dual"][:]
    gens = modes
    worst = 0.0
    total = np.linalg.norm(dual)
    for m in range(1, len(sel) + 1):
        res = np.sqrt(sum(nnls(gens[:, :m], dual[:, j])[1] ** 2 for j in range(dual.shape[1])))
        worst = max(worst, abs(res / total - comp[m]))
    if worst > 1e-6:
        problems.append(f"C(m) differs from scipy's NNLS by {worst:.1e}")
    rank = int(np.sum(sv > 1e-10 * sv[0]))
    return (f"CPG selected {len(sel)} of {dual.shape[1]} (dual POD rank at 1e-10: {rank}); {noise} after C(m) < 1e-10; "
            f"C(m) vs scipy NNLS {worst:.1e}; Gram rcond >= {rcond.min():.1e}"), problems


IRON_2 = [("nested_levels = 7", "nested_levels = 0")]
# The rope's near-duplicates: its 201-dof primal keeps the primal leave-one-out cheap at
# 16 385 snapshots (one SVD per fold of a 201 x N matrix), where ironing-coarse's 6 164 dofs make
# each of its folds an SVD of a 4 097 x 4 096 matrix (minutes per fold).
ROPE_NEAR = [("min = -0.5", "min = 0.1"), ("max = 0.5", "max = 0.1001"),
             ("specificity_samples = 1000", "specificity_samples = 50"), ("[study]", "[study]\nloo_folds = 64")]


def cases(fast):
    c = [
        ("hertz first touch, d = 1e-6 .. 1e-4", "hertz", [("min = 0.025", "min = 1e-6"), ("max = 0.3", "max = 1e-4"),
                                                          ("n_train = 12", "n_train = 2")], "solve", hertz_first_touch,
         True),
        ("hertz against Hertz theory, d = 0.025 .. 0.3", "hertz", [], "solve", hertz_theory, True),
        ("ironing grazing, d_y = 1e-5", "ironing-coarse",
         [("d_y = 0.04", "d_y = 1e-5"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", ironing_grazing, True),
        ("ironing deep, d_y = 0.06 (sole limit 0.0635)", "ironing-coarse",
         [("d_y = 0.04", "d_y = 0.06"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", ironing_deep, True),
        ("ironing E_iron / E_slab = 1e6 (nearly rigid iron)", "ironing-coarse",
         [("young = 10.0", "young = 1e6"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", kkt_only("KKT checks at every point, the active-set loop terminating"), True),
        ("ironing E_iron / E_slab = 1e-3 (soft iron)", "ironing-coarse",
         [("young = 10.0", "young = 1e-3"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", kkt_only("KKT checks at every point, the active-set loop terminating"), True),
        ("ironing E_iron / E_slab = 1", "ironing-coarse",
         [("young = 10.0", "young = 1.0"), ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", kkt_only("KKT checks at every point"), False),
        ("ironing 5 x 1 slab mesh, whole study", "ironing-coarse",
         [("nx = 100", "nx = 5"), ("ny = 20", "ny = 1"), ("n_train = 128", "n_train = 8")] + IRON_2,
         "run", coarse_mesh_run, True),
        ("ironing slab elements of aspect ratio 50 (nx = 10, ny = 100)", "ironing-coarse",
         [("nx = 100", "nx = 10"), ("ny = 20", "ny = 100"), ("max = 3.0", "max = 1.5"),
          ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", kkt_only("KKT checks at every point"), False),
        ("ironing-fine refined 4x per direction (slab 800 x 160, iron 240 x 240; ~380 000 dofs)", "ironing-fine",
         refined(4), "solve", finest_mesh, False),
        ("ironing mesh beyond the machine (slab 100 000 x 20 000)", "ironing-coarse",
         [("nx = 100", "nx = 100000"), ("ny = 20", "ny = 20000")] + IRON_2,
         "solve", refusal("model.ironing.slab.nx", " (by the memory estimate, before anything is allocated: a mesh "
                          "that cannot be factored is not fixed by fewer points; an answer would mean the "
                          "estimate let through about 4e9 dofs)"), True),
        ("ironing nu = 0.4999 (both bodies)", "ironing-coarse",
         [("poisson = 0.3 }", "poisson = 0.4999 }"),
          ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", locking, False),
        ("ironing nu = 0.4999, selective reduced integration", "ironing-coarse",
         [("poisson = 0.3 }", 'poisson = 0.4999, integration = "selective" }'),
          ("max = 3.0", "max = 1.5"), ("n_train = 128", "n_train = 2")] + IRON_2,
         "solve", selective, False),
        ("1 025 near-duplicate training points (d_x in [1.5, 1.5001])", "ironing-coarse",
         [("min = 0.0", "min = 1.5"), ("max = 3.0", "max = 1.5001"), ("n_train = 128", "train_level = 10"),
          ("specificity_samples = 1000", "specificity_samples = 50"), ("[study]", "[study]\nloo_folds = 64")] + IRON_2,
         "offline", near_duplicates, False),
        ("reduced solve on nearly parallel dual vectors, primal ranks 1-3 (129 near-duplicates)", "ironing-coarse",
         [("min = 0.0", "min = 1.5"), ("max = 3.0", "max = 1.5001"), ("n_train = 128", "train_level = 7")] + IRON_2,
         "run", reduced_solve, True),
        ("degenerate: no contact anywhere (rope, obstacle 50 below)", "rope", [("offset = -0.5", "offset = -50.0")],
         "run", no_contact, False),
        ("degenerate: one training point", "rope", [("n_train = 10", "n_train = 1")], "run",
         refusal("parameter.n_train"), False),
        ("degenerate: two identical parameter values (min = max)", "rope",
         [("min = -0.5", "min = 0.25"), ("max = 0.5", "max = 0.25")], "run", refusal("parameter.max"), False),
        ("degenerate: rank request 0", "rope", [("[study]", "[study]\nmax_rank = 0")], "run",
         refusal("study.max_rank"), False),
        ("degenerate: rank request 1000 > N = 10", "rope", [("[study]", "[study]\nmax_rank = 1000")], "run",
         rank_beyond, False),
        ("degenerate: truncation tolerance 1", "rope",
         [("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = 1.0")], "run", tolerance_one, False),
        ("degenerate: solver tolerance 0", "rope", [("rel_tol = 1e-10", "rel_tol = 0.0")], "run",
         refusal("solver.rel_tol"), False),
        ("rope, 4 097 near-duplicate training points (gamma in [0.1, 0.1001])", "rope",
         ROPE_NEAR + [("n_train = 10", "train_level = 12")], "offline", near_duplicates, False),
        ("rope, 16 385 near-duplicate training points (gamma in [0.1, 0.1001])", "rope",
         ROPE_NEAR + [("n_train = 10", "train_level = 14")], "offline", near_duplicates, False),
    ]
    return [x for x in c if x[5] or not fast]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fast", action="store_true", help="only the fast subset (CI)")
    args = ap.parse_args()
    binary = pathlib.Path(os.environ.get("CROM_BIN", REPO / "target" / "release" / "crom"))
    if "CROM_BIN" not in os.environ:
        subprocess.run(["just", "build"], cwd=REPO,
                       check=True)
    rows, failed = [], 0
    tmp = pathlib.Path(tempfile.mkdtemp(prefix="crom-stress-"))
    try:
        for i, (name, base, edits, command, check, _) in enumerate(cases(args.fast)):
            # The matrix stresses the solver and the paper's bases; a shipped [comparison] is
            # dropped, its settings being sized for the shipped training sets.
            text = (REPO / "data" / "scenes" / f"{base}.toml").read_text()
            drop = ["comparison"] if "[comparison]" in text else []
            scene = variant(tmp, base, f"stress-{i}", edits, drop)
            store = tmp / f"store-{i}"
            cmd = {"solve": ["solve"], "run": ["run"], "offline": ["run", "--offline"]}[command]
            t = time.perf_counter()
            p = run_measured([str(binary), "--store", str(store), "--quiet", *cmd, str(scene)])
            wall = time.perf_counter() - t
            out = p.stdout + p.stderr
            MEMO.update(rss=p.rss, scene=scene, binary=binary)
            expectation = " ".join((check.__doc__ or "").split())
            expect = getattr(check, "outcome", "pass")
            if p.returncode == 0:
                measured, problems = check(store, out)
                problems += [f"non-finite {b}" for b in nonfinite(store)]
            elif p.returncode in (1, 2) and "fix" in out:
                measured = out.strip().splitlines()[0] if out.strip() else ""
                problems = [f"non-finite {b}" for b in nonfinite(store)] if store.exists() else []
            else:
                measured, problems = f"exit {p.returncode}: {out.strip()[-300:]}", []
            verdict_ = verdict(expect, p.returncode, out, problems, getattr(check, "field", None), store.exists())
            expectation = f"[{expect}] {expectation}"
            failed += verdict_.startswith("FAIL")
            rows.append((name, expectation, f"{measured} ({wall:.1f} s, {p.rss / GIB:.2f} GiB)", verdict_))
            print(f"{name}: {verdict_}", file=sys.stderr)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print("\n### Stress matrix (`scripts/stress.py%s`)\n" % (" --fast" if args.fast else ""))
    print("| case | expectation | measured | verdict |")
    print("|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(x.replace("|", "/") for x in r) + " |")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
