"""Contact snapshots from an independent finite-element code, studied with crom.

A membrane under tension on the unit square, fixed on its boundary and pressed down by a uniform
load onto a rigid paraboloid bump whose position along x is the parameter mu:

    find u >= psi(., mu) with  (grad u, grad v) >= (f, v)  for v - u >= psi - u, u = 0 on the boundary,
    psi(x, y; mu) = h - a ((x - mu)^2 + (y - 1/2)^2)

(the obstacle problem). scikit-fem assembles the P1 stiffness K and load F; the discrete problem
min 1/2 u'Ku - F'u subject to u_i >= psi_i at the interior nodes has the KKT conditions

    K u - F = lam,   lam >= 0,   u - psi >= 0,   lam_i (u_i - psi_i) = 0,

solved by the primal-dual active-set method (Hintermueller, Ito, Kunisch 2002): active set
A = {i : lam_i + c (psi_i - u_i) > 0}, u_A = psi_A, lam = 0 off A, until A repeats. The contact
pressure written is lam_i divided by the lumped mass of node i (a force per area), one entry per
interior node (the potential contact set; zero off the contact set); the primal field is u, one
entry per node.

The script writes `membrane.h5` (datasets `primal` n_nodes x N, `dual` n_interior x N, `mu` N,
and the mesh: `mesh/nodes` n_nodes x 2, `mesh/cells` n_triangles x 3, `mesh/dual_nodes`
n_interior, the node of each dual entry) and `membrane.toml`, an external scene whose training
points are `n_train` equidistant values of mu and whose test points are their midpoints, then
prints the `crom run` command; the report opens with the pressure on the mesh. Usage:

    python examples/skfem_membrane/membrane.py OUTDIR [--refine 4] [--n-train 33]
    crom run OUTDIR/membrane.toml
"""
import argparse
import pathlib

import h5py
import numpy as np
import scipy.sparse.linalg as spla
from skfem import Basis, ElementTriP1, MeshTri
from skfem.models.poisson import laplace, mass, unit_load

LOAD = -20.0          # f: uniform load, downwards
HEIGHT = 0.02         # h: top of the bump
CURVATURE = 2.0       # a: the bump's curvature
MU_RANGE = (0.3, 0.7)


def setup(refine: int):
    mesh = MeshTri.init_symmetric().refined(refine)
    basis = Basis(mesh, ElementTriP1())
    K = laplace.assemble(basis).tocsr()
    F = LOAD * unit_load.assemble(basis)
    lumped = np.asarray(mass.assemble(basis).sum(axis=1)).ravel()
    interior = basis.complement_dofs(basis.get_dofs())
    return mesh, K, F, lumped, interior


def solve(mesh, K, F, interior, mu: float, c: float = 1e3, max_iter: int = 100):
    """Primal-dual active set on the interior nodes; returns (u, lam, iterations)."""
    x, y = mesh.p
    psi = HEIGHT - CURVATURE * ((x - mu) ** 2 + (y - 0.5) ** 2)
    n = K.shape[0]
    u, lam = np.zeros(n), np.zeros(n)
    active = np.zeros(n, dtype=bool)
    for it in range(1, max_iter + 1):
        new = np.zeros(n, dtype=bool)
        new[interior] = lam[interior] + c * (psi[interior] - u[interior]) > 0
        if it > 1 and np.array_equal(new, active):
            return u, lam, it - 1
        active = new
        free = interior[~active[interior]]
        fixed = interior[active[interior]]
        u = np.zeros(n)
        u[fixed] = psi[fixed]
        if free.size:
            rhs = F[free] - K[free][:, fixed] @ u[fixed]
            u[free] = spla.spsolve(K[free][:, free].tocsc(), rhs)
        lam = np.zeros(n)
        lam[fixed] = (K @ u - F)[fixed]
    raise RuntimeError(f"active set did not settle in {max_iter} iterations at mu = {mu}")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("outdir", type=pathlib.Path)
    ap.add_argument("--refine", type=int, default=4)
    ap.add_argument("--n-train", type=int, default=33)
    args = ap.parse_args()
    out = args.outdir
    out.mkdir(parents=True, exist_ok=True)
    mesh, K, F, lumped, interior = setup(args.refine)
    train = np.linspace(*MU_RANGE, args.n_train)
    test = 0.5 * (train[1:] + train[:-1])
    mus = np.concatenate([train, test])
    primal, dual = [], []
    for mu in mus:
        u, lam, _ = solve(mesh, K, F, interior, mu)
        primal.append(u)
        dual.append(lam[interior] / lumped[interior])
    with h5py.File(out / "membrane.h5", "w") as f:
        f["primal"] = np.array(primal).T   # one snapshot per column, node-major (one dof per node)
        f["dual"] = np.array(dual).T       # one entry per interior node
        f["mu"] = mus
        f["mesh/nodes"] = mesh.p.T         # (n_nodes, 2)
        f["mesh/cells"] = mesh.t.T         # (n_triangles, 3), 0-based node indices
        f["mesh/dual_nodes"] = interior    # the node of each dual entry
    n = args.n_train
    (out / "membrane.toml").write_text(f'''# Written by examples/skfem_membrane/membrane.py: a membrane pressed onto a moving bump,
# solved with scikit-fem and a primal-dual active-set loop.
[scene]
name = "skfem-membrane"
description = "membrane on a paraboloid bump at x = mu (scikit-fem, P1, {mesh.p.shape[1]} nodes)"

[model.external]
dual = {{ file = "membrane.h5", dataset = "dual" }}
primal = {{ file = "membrane.h5", dataset = "primal" }}
parameters = {{ file = "membrane.h5", dataset = "mu", names = ["mu"], description = "x of the bump's top" }}
mesh = {{ file = "membrane.h5", nodes = "mesh/nodes", cells = "mesh/cells", dual_nodes = "mesh/dual_nodes" }}
train = {list(range(n))}
test = {list(range(n, len(mus)))}

[study]
primal_tol = 0.0
dual_orth_tol = 0.0
dual_cone_tol = 0.0
dual_cone_tol_truncated = 0.05
specificity_samples = 200
seed = 1

# The dual approximations side by side. The registered map acts along a contact curve, and the
# membrane's contact set is an area: it is skipped, with that reason in the progress and the report.
[comparison]
max_m = 16
loo_folds = 8
approximations = [
  {{ kind = "pod" }},
  {{ kind = "cpg" }},
  {{ kind = "dictionary" }},
  {{ kind = "registered", map = "translate", interpolation = "linear", basis = "cpg" }},
]
''')
    print(f"crom run {out / 'membrane.toml'}")


if __name__ == "__main__":
    main()
