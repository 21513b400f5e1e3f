#!/usr/bin/env python3
"""Offline: what positivity at the nodes costs a registered POD of the contact pressure.

Reads a store after `crom run ironing-fine` (the mesh and the train and test sets), pulls the
training pressures back by whole-node translation (`registration.rs`, `Interpolation::Nodes`),
takes their POD, and for each test pressure `s` at m = 5, 8, 10 compares the projection on the
pushed-forward modes `B` (the comparison table's registered POD curve) with the projection
constrained to `B a >= -1e-6 max s` (SLSQP) and to `B a >= 0` (the NNLS dual
`min_{nu >= 0} |Q^T (s + nu)|`, `Q` an orthonormal basis of B's span). Prints mean errors, the
most negative value of the unconstrained projection, and the largest mode value where every
snapshot vanishes. Numbers: docs/design-notes.md#the-registered-approximation-online-the-error-the-multiplier-adds.

Usage: scripts/registered_positivity.py STORE
"""

import pathlib
import sys

import h5py
import numpy as np
from scipy.optimize import minimize, nnls


def main():
    store = pathlib.Path(sys.argv[1])
    with h5py.File(next((store / "mesh").iterdir()) / "mesh.h5") as f:
        x = f["nodes"][:][f["contact_nodes"][:], 0]
    sets = {}
    for d in (store / "trainset").iterdir():
        with h5py.File(d / "snapshots.h5") as f:
            sets[f.attrs["set"]] = (f["dual"][:], f["parameters"][:].reshape(-1))
    (S, mu), (T, tmu) = sets["train"], sets["test"]
    order = np.argsort(x)
    n = len(x)
    h = (x[order][-1] - x[order][0]) / (n - 1)
    shift = lambda m: int(np.round(m / h))  # noqa: E731
    hi = max(shift(m) for m in mu)
    L = n + hi - min(shift(m) for m in mu)

    def index(m):
        q = np.arange(n) - shift(m) + hi
        return q, (q >= 0) & (q < L)

    def pull(s, m):
        r, (q, ok) = np.zeros(L), index(m)
        r[q[ok]] = s[order][ok]
        return r

    def push(r, m):
        (q, ok), v, out = index(m), np.zeros(n), np.zeros(n)
        v[ok] = r[q[ok]]
        out[order] = v
        return out

    R = np.stack([pull(S[:, j], mu[j]) for j in range(S.shape[1])], 1)
    U = np.linalg.svd(R, full_matrices=False)[0]
    zero = np.abs(R).max(1) == 0
    print(f"reference points {L}, where every snapshot is 0: {int(zero.sum())}; "
          f"largest |mode| there (m <= 10): {np.abs(U[zero, :10]).max():.1e}")
    for m in [5, 8, 10]:
        free, tol, exact, neg = [], [], [], []
        for j in range(T.shape[1]):
            s = T[:, j]
            ns, top = np.linalg.norm(s), s.max()
            Q = np.linalg.qr(np.stack([push(U[:, k], tmu[j]) for k in range(m)], 1))[0]
            b0 = Q.T @ s
            free.append(np.linalg.norm(s - Q @ b0) / ns)
            neg.append(-min(0.0, (Q @ b0).min()) / top)
            eps = 1e-6 * top
            r = minimize(lambda b: 0.5 * np.sum((Q @ b - s) ** 2), b0, jac=lambda b: Q.T @ (Q @ b - s),
                         constraints=[{"type": "ineq", "fun": lambda b: Q @ b + eps, "jac": lambda b: Q}],
                         method="SLSQP", options={"ftol": 1e-16, "maxiter": 1000})
            tol.append(np.linalg.norm(s - Q @ r.x) / ns)
            nu = nnls(Q.T, -Q.T @ s, maxiter=50 * n)[0]
            exact.append(np.linalg.norm(s - Q @ (Q.T @ (s + nu))) / ns)
        print(f"m = {m:2d}: unconstrained {100 * np.mean(free):.4f} %, p >= -1e-6 max s {100 * np.mean(tol):.4f} %, "
              f"p >= 0 {100 * np.mean(exact):.2f} % (median {100 * np.median(exact):.2f} %); "
              f"most negative unconstrained value / max s {max(neg):.1e}")


if __name__ == "__main__":
    main()
