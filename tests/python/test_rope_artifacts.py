"""Validate the rope artifacts from h5py / pandas, recomputing metrics independently.

Tolerances: values recomputed with numpy/scipy agree to 1e-8 (absolute, on relative errors of
order 1): both sides are double-precision SVD / NNLS of the same 201 x 10 matrix, whose rounding
is ~1e-14; 1e-8 leaves room for different algorithms (LAPACK vs faer, scipy's NNLS vs crom's
Gram-based active set) without hiding a wrong formula, which would differ at the 1e-2 level.
"""
import json

import h5py
import numpy as np
import pandas as pd
import pytest
from scipy.optimize import nnls

from conftest import only_artifact

SCHEMA_VERSION = 4


def train_file(store):
    return only_artifact(store, "trainset", "snapshots.h5",
                         where=lambda p: h5py.File(p, "r").attrs["set"] == "train")


def test_training_set_shapes_attributes_and_parameters(rope_store):
    path = train_file(rope_store)
    with h5py.File(path, "r") as f:
        assert f["primal"].shape == (201, 10)
        assert f["dual"].shape == (201, 10)
        # numpy's linspace rounds differently from crom's in the last bit: 1e-15 absolute.
        np.testing.assert_allclose(f["parameters"][:], np.linspace(-0.5, 0.5, 10), rtol=0, atol=1e-15)
        assert f.attrs["scene"] == "rope"
        assert f.attrs["schema_version"] == SCHEMA_VERSION
        assert f.attrs["cache_key"] == path.parent.name
        dual = f["dual"][:]
        assert (dual >= 0).all(), "contact pressure is non-negative"
        # A view on the column store: virtual datasets, nothing copied.
        assert f["primal"].is_virtual and f["dual"].is_virtual
    manifest = json.loads((path.parent / "manifest.json").read_text())
    assert manifest["stage"] == "trainset" and manifest["schema_version"] == SCHEMA_VERSION
    assert {e["name"] for e in manifest["files"]} == {"snapshots.h5", "solver_stats.parquet", "solver_timings.parquet"}


def test_solver_statistics_table(rope_store):
    stats = pd.read_parquet(only_artifact(rope_store, "trainset", "solver_stats.parquet",
                                          where=lambda p: len(pd.read_parquet(p)) == 10))
    assert list(stats.columns) == ["scene", "index", "parameter", "snapshot_key", "block", "column", "blake3",
                                   "iterations", "active", "max_penetration", "min_lambda", "complementarity",
                                   "kkt_residual", "vertex_ties", "vertex_nodes", "vertex_rounds", "min_gap",
                                   "active_gap", "cone_angle"]
    # The rope's geometric check is its obstacle gap u - g: no penetration beyond the solver's
    # tolerance, and no vertices to tie.
    assert (stats["min_gap"] >= -1e-10).all() and (stats["active_gap"] <= 1e-10).all()
    assert (stats["vertex_ties"] == 0).all() and (stats["vertex_nodes"] == "").all()
    assert (stats["complementarity"] <= 1e-10).all()
    # The solve times, apart from the results: same rows, same snapshots.
    times = pd.read_parquet(only_artifact(rope_store, "trainset", "solver_timings.parquet",
                                          where=lambda p: len(pd.read_parquet(p)) == 10))
    assert list(times.columns) == ["scene", "index", "snapshot_key", "seconds"]
    assert times["snapshot_key"].tolist() == stats["snapshot_key"].tolist()
    assert (times["seconds"] > 0).all()
    assert (stats["active"] > 0).all()
    assert stats["snapshot_key"].str.len().eq(64).all()


def test_snapshot_primal_is_above_the_obstacle(rope_store):
    with h5py.File(train_file(rope_store), "r") as f:
        u, gammas = f["primal"][:], f["parameters"][:]
    x = np.linspace(0.0, 1.0, 201)
    for j, g in enumerate(gammas):
        obstacle = -0.2 * (np.sin(np.pi * x) - np.sin(3 * np.pi * x)) - 0.5 + g * x
        # Feasible up to rounding of O(1) values.
        assert (u[:, j] - obstacle >= -1e-12).all()


def test_dual_orth_compactness_matches_numpy_svd(rope_store):
    with h5py.File(train_file(rope_store), "r") as f:
        dual = f["dual"][:]
    table = pd.read_parquet(only_artifact(rope_store, "compactness", "compactness.parquet"))
    assert list(table.columns) == ["scene", "field", "basis", "m", "value"]
    stored = table[(table.field == "dual") & (table.basis == "orth")].sort_values("m")["value"].to_numpy()
    s = np.linalg.svd(dual, compute_uv=False)
    total = np.sqrt((s ** 2).sum())
    expected = np.array([np.sqrt((s[m:] ** 2).sum()) / total for m in range(len(stored))])
    np.testing.assert_allclose(stored, expected, rtol=0, atol=1e-8)


def test_primal_pod_is_orthonormal(rope_store):
    with h5py.File(only_artifact(rope_store, "basis", "basis.h5"), "r") as f:
        modes = f["primal_pod/modes"][:]
        sv = f["primal_pod/singular_values"][:]
        assert f["dual_cpg_truncated"].attrs["rank"] == 7, "paper Table 1: CPG at 0.2 keeps 7"
    np.testing.assert_allclose(modes.T @ modes, np.eye(modes.shape[1]), atol=1e-12)
    assert (np.diff(sv) <= 0).all()


@pytest.mark.parametrize("m", [1, 3, 7])
def test_cone_compactness_matches_scipy_nnls(rope_store, m):
    with h5py.File(train_file(rope_store), "r") as f:
        dual = f["dual"][:]
    with h5py.File(only_artifact(rope_store, "basis", "basis.h5"), "r") as f:
        cone = f["dual_cpg/modes"][:, :m]
    assert (cone >= 0).all()
    residuals = [nnls(cone, dual[:, j])[1] for j in range(dual.shape[1])]
    expected = np.sqrt(np.sum(np.square(residuals))) / np.linalg.norm(dual)
    table = pd.read_parquet(only_artifact(rope_store, "compactness", "compactness.parquet"))
    stored = table[(table.field == "dual") & (table.basis == "cone") & (table.m == m)]["value"].item()
    assert abs(stored - expected) <= 1e-8


def test_mesh_opens_and_xdmf_points_at_it(rope_store):
    path = only_artifact(rope_store, "mesh", "mesh.h5")
    with h5py.File(path, "r") as f:
        assert f["nodes"].shape == (201, 2)
        assert f["cells"].shape == (200, 2)
        assert len(f["contact_nodes"]) == 201
    xdmf = (path.parent / "mesh.xdmf").read_text()
    assert "mesh.h5:/nodes" in xdmf and "Polyline" in xdmf


def loo_orth_errors(s, i, ms):
    """Leave-one-out orthogonal projection errors of column i, POD at numerical rank (numpy)."""
    rest = np.delete(s, i, axis=1)
    u, sv, _ = np.linalg.svd(rest, full_matrices=False)
    rank = int((sv > max(rest.shape) * np.finfo(float).eps * sv[0]).sum())
    out = []
    for m in ms:
        q = u[:, :min(m, rank)]
        r = s[:, i] - q @ (q.T @ s[:, i])
        out.append(np.linalg.norm(r) / np.linalg.norm(s[:, i]))
    return np.array(out)


@pytest.mark.parametrize("field", ["primal", "dual"])
def test_generalization_matches_numpy_leave_one_out(rope_store, field):
    with h5py.File(train_file(rope_store), "r") as f:
        s = f[field][:]
    ms = [1, 3, 5]
    errs = np.array([loo_orth_errors(s, i, ms) for i in range(s.shape[1])])
    table = pd.read_parquet(only_artifact(rope_store, "generalization", "generalization.parquet"))
    assert list(table.columns) == ["scene", "field", "basis", "m", "mean", "std", "count", "padded", "n_zero"]
    rows = table[(table.field == field) & (table.basis == "orth")].set_index("m")
    for k, m in enumerate(ms):
        assert abs(rows.loc[m, "mean"] - errs[:, k].mean()) <= 1e-8
        # Population standard deviation over the folds.
        assert abs(rows.loc[m, "std"] - errs[:, k].std()) <= 1e-8
        assert rows.loc[m, "count"] == 10 and rows.loc[m, "n_zero"] == 0


def test_specificity_table_is_complete_and_seeded(rope_store):
    table = pd.read_parquet(only_artifact(rope_store, "specificity", "specificity.parquet"))
    manifest = json.loads((only_artifact(rope_store, "specificity", "manifest.json")).read_text())
    # max_rank: every m for N = 10 training snapshots (default while N <= 256).
    # The key also holds the NNLS settings of the cone projections (crom_stages NnlsParams).
    params = dict(manifest["parameters"])
    assert set(params.pop("nnls")) == {"max_iter", "tol", "pivot_tol"}
    assert params == {"samples": 1000, "seed": 20231, "max_rank": 10}
    for (field, basis), g in table.groupby(["field", "basis"]):
        assert (g["count"] == 1000).all(), (field, basis)
        assert (g["mean"] > 0).all()
