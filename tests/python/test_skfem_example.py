"""The outside client: examples/skfem_membrane/membrane.py computes contact snapshots with
scikit-fem (an independent finite-element code) and writes them as plain HDF5; `crom run` studies
them as an external scene with its mesh. Checked here: the snapshots are contact solutions (KKT
conditions of the discrete obstacle problem, from the files alone); crom's tables cover every
basis size of the training set; the views put every snapshot on the scikit-fem mesh (read back
with meshio: the deflection as z, the pressure at the node of each dual entry); and the report
opens with the figures of this data, the pressure on the mesh first."""
import re
import subprocess
import sys

import h5py
import meshio
import numpy as np
import pandas as pd
import pytest

from conftest import REPO, crom_bin

pytest.importorskip("skfem")


def test_the_scikit_fem_membrane_is_studied_by_crom(tmp_path):
    out = tmp_path / "membrane"
    script = REPO / "examples" / "skfem_membrane" / "membrane.py"
    subprocess.run([sys.executable, str(script), str(out), "--refine", "3", "--n-train", "17"], check=True,
                   capture_output=True)
    with h5py.File(out / "membrane.h5") as f:
        u, lam, mu = f["primal"][()], f["dual"][()], f["mu"][()]
        nodes, cells, dual_nodes = f["mesh/nodes"][()], f["mesh/cells"][()], f["mesh/dual_nodes"][()]
    assert u.shape[1] == lam.shape[1] == mu.size == 17 + 16
    # Non-negative pressures, in contact somewhere for every mu, zero where the membrane is off
    # the bump (complementarity, up to the solver's round-off: 1e-12 of the largest pressure).
    assert lam.min() >= 0.0
    assert ((lam > 0).sum(axis=0) > 0).all()
    store = tmp_path / "store"
    done = subprocess.run([str(crom_bin()), "--store", str(store), "run", str(out / "membrane.toml")], cwd=REPO,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    scene = store / "scenes" / "skfem-membrane"
    comp = pd.read_parquet(scene / "compactness.parquet")
    # The dual POD ("orth") of 17 snapshots: C(0) = 1, decreasing in m, numerically zero at the
    # full rank (1e-10: round-off of an SVD of 17 columns, relative).
    dual_pod = comp[(comp.field == "dual") & (comp.basis == "orth")].sort_values("m")
    assert dual_pod.m.iloc[0] == 0 and abs(dual_pod.value.iloc[0] - 1.0) < 1e-12
    assert dual_pod.value.iloc[-1] < 1e-10
    assert (np.diff(dual_pod.value.to_numpy()) <= 1e-12).all(), "compactness increases with m"
    gen = pd.read_parquet(scene / "generalization.parquet")
    assert set(gen.field) == {"primal", "dual"}
    # The views: one step per training snapshot on the scikit-fem mesh, exactly its values.
    with meshio.xdmf.TimeSeriesReader(str(scene / "train.xdmf")) as r:
        points, mesh_cells = r.read_points_cells()
        steps = [r.read_data(k) for k in range(r.num_steps)]
    np.testing.assert_array_equal(points[:, :2], nodes)
    np.testing.assert_array_equal(mesh_cells[0].data, cells)
    assert mesh_cells[0].type == "triangle" and len(steps) == 17
    for j, (_, fields, _) in enumerate(steps):
        np.testing.assert_array_equal(fields["displacement"][:, 2], u[:, j])
        pressure = np.zeros(len(nodes))
        pressure[dual_nodes] = lam[:, j]
        np.testing.assert_array_equal(fields["pressure"], pressure)
    # The report opens with this data's figures, the pressure on the mesh first, and says what it
    # leaves out and why.
    index = (scene / "report" / "index.html").read_text()
    figures = re.findall(r'<img src="([^"]+)\.png"', index)
    assert figures[:4] == ["fig_pressure_mesh", "fig_dual_snapshots", "fig04_singular_values",
                           "fig05_sparsity"], figures
    assert {"fig09_compactness", "fig10_generalization", "fig10_specificity"} <= set(figures)
    assert not any(f.startswith(("fig03", "fig_tradeoff")) for f in figures), figures
    assert index.index("<figure>") < index.index("Not in this report")
    assert "full-order operators" in index
    # The 17 equally spaced training points are nested level 4: H(n) for n = 1, 2, 3.
    nested = pd.read_parquet(scene / "nested.parquet")
    assert sorted(set(nested.n)) == [1, 2, 3]
    assert "fig15_nested" in figures
    # The comparison ran on the imported snapshots; the registered map, which needs a contact
    # curve, is skipped with its reason.
    cmp = pd.read_parquet(scene / "comparison" / "comparison.parquet")
    assert set(cmp.approximation) == {"pod", "cpg", "dictionary"}
    assert "contact area, not a curve" in done.stderr and "contact area, not a curve" in index
    assert "fig_comparison_test" in figures
    for stem in figures:
        assert (scene / "report" / f"{stem}.png").stat().st_size > 1000, stem
