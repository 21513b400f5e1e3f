#!/usr/bin/env python3
"""Why registration stops near 1 % on a vector parameter (docs/results.md#the-vector-parameter-ironing-fine-2d).

Reads a finished `crom run SCENE` of a vector-parameter scene (ironing-fine-2d, ironing-3d-2d):
its published train.h5 and test.h5, and the contact nodes' abscissae (and, on a 3-D contact area,
their coordinates across the travel) from model.h5's `reg_surface` (`reg_across`). Independently
of crom's Rust code (NumPy and SciPy) it

1. rebuilds the registered POD on the moments map (centre and width from each training
   pressure's moments along x, summed over the lines of a contact area; multilinear over the
   grid for the test points; reference grid refine 16) and prints C(m) and the mean test error,
   which should read what crom's comparison reports (1.07 % and 1.06 % at m = 5);
2. replaces the map by piecewise-linear warps through 3, 5 and 7 quantiles of each pressure's
   cumulative distribution along x, and through the points where the profile crosses 3 or 4
   levels of its peak on either side (richer families of smooth maps);
3. measures where the remaining error lives: the share of the m = 5 test residual's energy in
   the upper half of the nodal spectrum along each line, over the contact (a smooth residual has
   little; a node-to-node ripple nearly all).

Usage: scripts/vector_map_floor.py [SCENE [STORE]]   (default ironing-fine-2d, data/store)
"""
import pathlib
import sys

import numpy as np
from scipy.interpolate import RegularGridInterpolator

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from vector_store import VectorStore  # noqa: E402

scene = sys.argv[1] if len(sys.argv) > 1 else "ironing-fine-2d"
store = sys.argv[2] if len(sys.argv) > 2 else "data/store"
vs = VectorStore(scene, store)
S, P, T, Q, x, lines, W, has = vs.S, vs.P, vs.T, vs.Q, vs.x, vs.lines, vs.W, vs.has
h = min(np.min(np.diff(x[line])[np.diff(x[line]) > 0]) for line in lines)
xg = np.unique(x)


moments = vs.moments


def quantiles(s, qs):
    """Where the cumulative of the pressure summed over the lines reaches each of `qs`."""
    prof = sum(np.interp(xg, x[line], s[line], left=0, right=0) for line in lines)
    F = np.concatenate([[0], np.cumsum(0.5 * (prof[1:] + prof[:-1]) * np.diff(xg))])
    return np.interp(qs, F / F[-1], xg)


def level_sets(s, levels):
    """Where the profile summed over the lines (normalised to its peak) crosses each of `levels`,
    on its rising side and then on its falling side (2 len(levels) knots, increasing)."""
    prof = sum(np.interp(xg, x[line], s[line], left=0, right=0) for line in lines)
    xf = np.linspace(xg[0], xg[-1], 20 * len(xg))
    pf = np.interp(xf, xg, prof) / prof.max()
    k = np.argmax(pf)
    rising = [np.interp(t, pf[:k + 1], xf[:k + 1]) for t in levels]
    falling = [np.interp(t, pf[k:][::-1], xf[k:][::-1]) for t in levels]
    return np.array(rising + falling[::-1])


def over_grid(vals):
    """The training points' map parameters interpolated multilinearly at the test points."""
    ux, uy = np.unique(P[:, 0]), np.unique(P[:, 1])
    G = np.full((len(ux), len(uy), vals.shape[1]), np.nan)
    G[np.searchsorted(ux, P[has, 0]), np.searchsorted(uy, P[has, 1])] = vals[has]
    f = RegularGridInterpolator((ux, uy), G, bounds_error=False, fill_value=None)
    return f(np.clip(Q, [ux[0], uy[0]], [ux[-1], uy[-1]]))


def warp(k, ref):
    """x -> xi and xi -> x, piecewise linear through (k_i, ref_i), extended by the end slopes."""
    def through(a, b, v):
        out = np.interp(v, a, b)
        lo, hi = v < a[0], v > a[-1]
        out[lo] = b[0] + (b[1] - b[0]) / (a[1] - a[0]) * (v[lo] - a[0])
        out[hi] = b[-1] + (b[-1] - b[-2]) / (a[-1] - a[-2]) * (v[hi] - a[-1])
        return out
    return (lambda v: through(k, ref, v)), (lambda v: through(ref, k, v))


def study(knots, ref, ms, spectrum=None):
    """'C / test' (%) per m: C(m) with each training pressure's own map, the mean test error with the
    interpolated one; the m = 5 test residuals' spectra into `spectrum`."""
    lo, hi, step = np.inf, -np.inf, np.inf
    for j in np.flatnonzero(has):
        fwd = warp(knots[j], ref)[0]
        for line in lines:
            sup = x[line][S[line, j] > 0]
            if len(sup):
                e = fwd(np.array([sup[0] - 2 * h, sup[-1] + 2 * h]))
                lo, hi = min(lo, e[0]), max(hi, e[1])
        step = min(step, np.min(np.diff(fwd(xg))))
    xi = np.arange(lo, hi + step / 16, step / 16)
    L = len(xi)

    def pull(s, k):
        inv = warp(k, ref)[1]
        return np.concatenate([np.interp(inv(xi), x[line], s[line], left=0, right=0) for line in lines])

    R = np.array([pull(S[:, j], knots[j]) for j in np.flatnonzero(has)]).T
    U = np.linalg.svd(R, full_matrices=False)[0]
    test_knots = over_grid(knots)

    def errors(snaps, kn, cols, m, spec=None):
        out = []
        for j in cols:
            s = snaps[:, j]
            if not s.any():
                continue
            fwd = warp(kn[j], ref)[0]
            B = np.zeros((len(s), m))
            for i in range(m):
                for li, line in enumerate(lines):
                    B[line, i] = np.interp(fwd(x[line]), xi, U[li * L:(li + 1) * L, i], left=0, right=0)
            r = s - B @ np.linalg.lstsq(B, s, rcond=None)[0]
            out.append(np.linalg.norm(r) / np.linalg.norm(s))
            if spec is not None:
                upper = total = 0.0
                for line in lines:
                    sup = np.flatnonzero(s[line] > 0)
                    if len(sup) >= 4:
                        F = np.abs(np.fft.rfft(r[line][sup[0]:sup[-1] + 1])) ** 2
                        upper, total = upper + F[len(F) // 2:].sum(), total + F.sum()
                spec.append(upper / total)
        return np.mean(out)

    cells = []
    for m in ms:
        c = errors(S, knots, np.flatnonzero(has), m)
        t = errors(T, test_knots, range(T.shape[1]), m, spectrum if m == 5 else None)
        cells.append(f"{c * 100:.2f} / {t * 100:.2f}")
    return cells


ms = (1, 3, 5, 6)
print(f"{scene}: {len(lines)} line(s), {S.shape[1]} training and {T.shape[1]} test pressures\n")
print("| map (C / mean test error, %) | " + " | ".join(f"m = {m}" for m in ms) + " |")
print("|---|" + "---|" * len(ms))
mom = np.array([moments(S[:, j]) if has[j] else [np.nan, np.nan] for j in range(S.shape[1])])
spectrum = []
# centre and width as a two-knot warp: xi = (x - c) / a
cells = study(np.stack([mom[:, 0], mom[:, 0] + mom[:, 1]], axis=1), np.array([0.0, 1.0]), ms, spectrum)
print("| moments (centre, width) | " + " | ".join(cells) + " |")
for qs in ([0.1, 0.5, 0.9], [0.02, 0.25, 0.5, 0.75, 0.98], [0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99]):
    qs = np.array(qs)
    kn = np.array([quantiles(S[:, j], qs) if has[j] else np.full(len(qs), np.nan) for j in range(S.shape[1])])
    ref = np.nanmean(kn, axis=0)
    print(f"| warp through {len(qs)} quantiles {qs.tolist()} | " + " | ".join(study(kn, ref - ref[len(ref) // 2], ms)) + " |")
for levels in ([0.02, 0.3, 0.7], [0.02, 0.2, 0.5, 0.8]):
    kn = np.array([level_sets(S[:, j], levels) if has[j] else np.full(2 * len(levels), np.nan) for j in range(S.shape[1])])
    ref = np.nanmean(kn, axis=0)
    print(f"| warp through the level sets {levels} of the profile | " + " | ".join(study(kn, ref - ref.mean(), ms)) + " |")
print(f"\nmoments map, m = 5: median share of the test residual's energy in the upper half of the nodal "
      f"spectrum along the lines, over the contact: {np.median(spectrum) * 100:.0f} %")
