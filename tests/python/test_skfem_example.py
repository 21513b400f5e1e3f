"""The outside client: examples/skfem_membrane/membrane.py computes contact snapshots with
scikit-fem (an independent finite-element code) and writes them as plain HDF5; `crom run` studies
them as an external scene. Checked here: the snapshots are contact solutions (KKT conditions of
the discrete obstacle problem, from the files alone), and crom's tables cover every basis size of
the training set."""
import subprocess
import sys

import h5py
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
