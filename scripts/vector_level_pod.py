#!/usr/bin/env python3
"""The moments map's registered POD, one for all press levels and one per press interval, rebuilt
independently of crom's Rust code (docs/results.md, "The vector parameter in 3-D").

Reads a finished `crom run SCENE` of a vector-parameter scene (ironing-3d-2d, ironing-fine-2d):
its published train.h5 and test.h5, the contact nodes' coordinates from model.h5 (`reg_surface`,
and `reg_across` on a contact area), and crom's comparison.parquet. With NumPy and SciPy only it

1. takes each training pressure's centre and width along x from its moments (summed over the
   lines of a contact area), and a test point's by multilinear interpolation over the grid;
2. pulls every training pressure back to xi = (x - c) / a on a reference grid 16 times finer
   than the nodes (relative to the narrowest width);
3. builds the POD of all of them (crom's `registered-moments-pod`) and, per interval between two
   consecutive levels of the second component, the POD of the pressures on those two levels
   (crom's `registered-moments-level-pod`);
4. pushes the modes forward to each test point (its interval's, for the level PODs) and prints
   the mean relative test error (least squares, Euclidean) beside crom's `test` rows.

The reference grid is not crom's (crom refines by `refine` within the training range), so the
two agree to the interpolation's rounding, about 0.01 points, not to the last digit.

Usage: scripts/vector_level_pod.py [SCENE [STORE]]   (default ironing-3d-2d, data/store)
"""
import pathlib
import sys

import numpy as np
import pandas as pd
from scipy.interpolate import RegularGridInterpolator

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from vector_store import VectorStore  # noqa: E402

scene = sys.argv[1] if len(sys.argv) > 1 else "ironing-3d-2d"
store = sys.argv[2] if len(sys.argv) > 2 else "data/store"
vs = VectorStore(scene, store)
S, P, T, Q, x, lines, has, moments = vs.S, vs.P, vs.T, vs.Q, vs.x, vs.lines, vs.has, vs.moments
D = vs.dir
M = np.array([moments(S[:, j]) if has[j] else [np.nan, np.nan] for j in range(S.shape[1])])
ux, uy = np.unique(P[:, 0]), np.unique(P[:, 1])
G = np.full((len(ux), len(uy), 2), np.nan)
G[np.searchsorted(ux, P[has, 0]), np.searchsorted(uy, P[has, 1])] = M[has]
grid = RegularGridInterpolator((ux, uy), G, bounds_error=False, fill_value=None)
MQ = grid(np.clip(Q, [ux[0], uy[0]], [ux[-1], uy[-1]]))
h = min(np.min(np.diff(x[line])) for line in lines)
xi = np.arange(-4.0, 4.0, h / np.nanmin(M[:, 1]) / 16)
L = len(xi)


def pull(s, c, a):
    return np.concatenate([np.interp(c + a * xi, x[line], s[line], left=0, right=0) for line in lines])


def push(r, c, a):
    out = np.zeros(len(x))
    for li, line in enumerate(lines):
        out[line] = np.interp((x[line] - c) / a, xi, r[li * L:(li + 1) * L], left=0, right=0)
    return out


R = np.array([pull(S[:, j], *M[j]) if has[j] else np.zeros(L * len(lines)) for j in range(S.shape[1])]).T
MS = [1, 2, 3, 4, 5, 6, 8, 16]
whole = np.linalg.svd(R[:, has], full_matrices=False)[0][:, :max(MS)]
per = [np.linalg.svd(R[:, has & ((P[:, 1] == lo) | (P[:, 1] == hi))], full_matrices=False)[0][:, :max(MS)]
       for lo, hi in zip(uy[:-1], uy[1:])]


def interval(v):
    return min(max(np.searchsorted(uy, v, side="right") - 1, 0), len(per) - 1)


errs = {"registered-moments-pod": {m: [] for m in MS}, "registered-moments-level-pod": {m: [] for m in MS}}
for q in range(T.shape[1]):
    t = T[:, q]
    if not t.any():
        continue
    for name, U in (("registered-moments-pod", whole), ("registered-moments-level-pod", per[interval(Q[q, 1])])):
        B = np.array([push(U[:, i], *MQ[q]) for i in range(U.shape[1])]).T
        for m in MS:
            Bm = B[:, :m]
            r = t - Bm @ np.linalg.lstsq(Bm, t, rcond=None)[0]
            errs[name][m].append(np.linalg.norm(r) / np.linalg.norm(t))
cmp = pd.read_parquet(f"{D}/comparison/comparison.parquet")
print(f"{scene}: {len(uy)} levels of the second component, {len(per)} intervals")
print("| mean test error (%) | " + " | ".join(f"m = {m}" for m in MS) + " |")
print("|---|" + "---|" * len(MS))
for name, e in errs.items():
    row = cmp[(cmp.approximation == name) & (cmp.metric == "test")]
    crom = {int(m): 100 * v for m, v in zip(row.m, row["mean"])}
    print(f"| {name}, this script | " + " | ".join(f"{100 * np.mean(e[m]):.3f}" for m in MS) + " |")
    print(f"| {name}, crom | " + " | ".join(f"{crom.get(m, float('nan')):.3f}" for m in MS) + " |")
