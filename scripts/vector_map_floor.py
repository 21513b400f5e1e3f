#!/usr/bin/env python3
"""Why registration stops near 1 % on a vector parameter (docs/results.md#the-vector-parameter-ironing-fine-2d).

Reads a finished `crom run ironing-fine-2d` (its published train.h5, test.h5 and the contact nodes'
abscissae in model.h5's `reg_surface`) and, independently of crom's Rust code (NumPy and SciPy):

1. rebuilds the registered POD on the moments map (centre and width from each training
   pressure's moments, interpolated multilinearly over the (d_x, d_y) grid for the test points;
   reference grid refine 16) and prints C(m) and the mean test error: it should read what
   crom's comparison reports (1.07 % at m = 5);
2. replaces the map by piecewise-linear warps through 3, 5 and 7 quantiles of each pressure's
   cumulative distribution (a strictly richer family of smooth maps than centre and width);
3. measures where the remaining error lives: the share of the m = 5 residual's energy in the
   upper half of the nodal spectrum over the contact (a smooth residual has almost none).

Usage: scripts/vector_map_floor.py [STORE]   (default data/store)
"""
import sys

import h5py
import numpy as np
from scipy.interpolate import RegularGridInterpolator

store = sys.argv[1] if len(sys.argv) > 1 else "data/store"
D = f"{store}/scenes/ironing-fine-2d"
train, test = h5py.File(f"{D}/train.h5"), h5py.File(f"{D}/test.h5")
S, P, T, Q = train["dual"][:], train["parameters"][:], test["dual"][:], test["parameters"][:]
x = h5py.File(f"{D}/model.h5")["reg_surface"][:]
order = np.argsort(x, kind="stable")
xs, n = x[order], len(x)
w = np.empty(n)
w[1:-1], w[0], w[-1] = 0.5 * (xs[2:] - xs[:-2]), 0.5 * (xs[1] - xs[0]), 0.5 * (xs[-1] - xs[-2])
h = np.min(np.diff(xs)[np.diff(xs) > 0])
has = S.sum(axis=0) > 0


def moments(s):
    """(c, a): centre and twice the standard deviation of the pressure along x (crom's rule)."""
    ss = s[order]
    m0 = (w * ss).sum()
    c = (w * ss * xs).sum() / m0
    return np.array([c, 2 * np.sqrt((w * ss * ((xs - c) ** 2 + w * w / 12)).sum() / m0)])


def quantiles(s, qs):
    """Where the cumulative of the piecewise-linear pressure reaches each of `qs`."""
    ss = s[order]
    F = np.concatenate([[0], np.cumsum(0.5 * (ss[1:] + ss[:-1]) * np.diff(xs))])
    return np.interp(qs, F / F[-1], xs)


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


def study(knots, ref, ms=(1, 3, 5, 6), report_spectrum=False):
    """C(m) with each training pressure's own map and the mean test error with the interpolated one."""
    maps = {j: warp(knots[j], ref) for j in np.flatnonzero(has)}
    lo, hi, step = np.inf, -np.inf, np.inf
    for j, (fwd, _) in maps.items():
        sup = xs[S[order, j] > 0]
        lo, hi = min(lo, fwd(np.array([sup[0] - 2 * h]))[0]), max(hi, fwd(np.array([sup[-1] + 2 * h]))[0])
        step = min(step, np.min(np.diff(fwd(xs))))
    xi = np.arange(lo, hi + step / 16, step / 16)
    R = np.array([np.interp(inv(xi), xs, S[order, j], left=0, right=0) for j, (_, inv) in maps.items()]).T
    U = np.linalg.svd(R, full_matrices=False)[0]
    test_knots = over_grid(knots)

    def errors(cols, snaps, kn, m, spectrum=None):
        out = []
        for j in cols:
            s = snaps[order, j]
            if not s.any():
                continue
            u = warp(kn[j], ref)[0](xs)
            B = np.array([np.interp(u, xi, U[:, i], left=0, right=0) for i in range(m)]).T
            r = s - B @ np.linalg.lstsq(B, s, rcond=None)[0]
            out.append(np.linalg.norm(r) / np.linalg.norm(s))
            if spectrum is not None:
                sup = np.flatnonzero(s > 0)
                F = np.abs(np.fft.rfft(r[sup[0]:sup[-1] + 1])) ** 2
                spectrum.append(F[len(F) // 2:].sum() / F.sum())
        return np.mean(out)

    cells = []
    for m in ms:
        c = errors(np.flatnonzero(has), S, knots, m)
        t = errors(range(T.shape[1]), T, test_knots, m)
        cells.append(f"{c * 100:.2f} / {t * 100:.2f}")
    spectrum = []
    if report_spectrum:
        errors(range(T.shape[1]), T, test_knots, 5, spectrum)
    return cells, spectrum


ms = (1, 3, 5, 6)
print("| map | " + " | ".join(f"C / test, m = {m} (%)" for m in ms) + " |")
print("|---|" + "---|" * len(ms))
mom = np.array([moments(S[:, j]) if has[j] else [np.nan, np.nan] for j in range(S.shape[1])])
# centre and width as a two-knot warp: xi = (x - c) / a
knots2 = np.stack([mom[:, 0], mom[:, 0] + mom[:, 1]], axis=1)
cells, spectrum = study(knots2, np.array([0.0, 1.0]), ms, report_spectrum=True)
print("| moments (centre, width) | " + " | ".join(cells) + " |")
for qs in ([0.1, 0.5, 0.9], [0.02, 0.25, 0.5, 0.75, 0.98], [0.01, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99]):
    qs = np.array(qs)
    kn = np.array([quantiles(S[:, j], qs) if has[j] else np.full(len(qs), np.nan) for j in range(S.shape[1])])
    ref = np.nanmean(kn, axis=0)
    cells, _ = study(kn, ref - ref[len(ref) // 2], ms)
    print(f"| {len(qs)} quantiles {qs.tolist()} | " + " | ".join(cells) + " |")
print(f"\nmoments map, m = 5: median share of the test residual's energy in the upper half of the nodal "
      f"spectrum over the contact: {np.median(spectrum) * 100:.0f} %")
