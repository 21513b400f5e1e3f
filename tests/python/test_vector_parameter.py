"""A two-component parameter μ = (d_x, d_y) end to end: a coarse, small version of
`ironing-fine-2d` (3 × 3 training points, 2 × 2 test points) runs through every stage, and its
snapshots at d_y = 0.04 equal those of the 1-D ironing scene with d_y fixed at 0.04. Its stored
model, pinned to the registered CPG on the moments map, is rebuilt in NumPy from model.h5 as
docs/store-format.md describes it (the table over both components, level by level).

Tolerance of that comparison: 1e-12 relative to the largest displacement — the two models solve
the same linear system, assembled from a different affine split of the Dirichlet data (one
addition per Dirichlet dof in another order); the contact pressure goes through the LCP, 1e-9.
"""
import pathlib
import subprocess

import h5py
import numpy as np
import pandas as pd

from conftest import REPO, crom_bin, only_artifact
from test_model_artifact import _push

COARSE = {"nx = 200": "nx = 100", "ny = 40": "ny = 20", "nx = 60": "nx = 30", "ny = 60": "ny = 30"}


def scene_2d(tmp: pathlib.Path) -> pathlib.Path:
    text = (REPO / "data/scenes/ironing-fine-2d.toml").read_text()
    for a, b in COARSE.items():
        text = text.replace(a, b)
    text = text.replace("train_level = 7", "train_level = 1").replace("train_level = 5", "train_level = 1")
    text = text.replace('name = "ironing-fine-2d"', 'name = "ironing-2d-small"')
    path = tmp / "ironing-2d-small.toml"
    path.write_text(text)
    return path


def scene_1d(tmp: pathlib.Path) -> pathlib.Path:
    text = (REPO / "data/scenes/ironing-coarse.toml").read_text()
    text = text.replace("n_train = 128", "train_level = 1").replace("nested_levels = 7", "nested_levels = 0")
    text = text.replace('name = "ironing-coarse"', 'name = "ironing-1d-small"')
    path = tmp / "ironing-1d-small.toml"
    path.write_text(text)
    return path


def run(store, scene):
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", str(scene)], cwd=REPO, check=True,
                   capture_output=True)


def test_two_component_parameter_runs_every_stage_and_matches_the_1d_scene(tmp_path):
    store = tmp_path / "store"
    run(store, scene_2d(tmp_path))
    run(store, scene_1d(tmp_path))
    train2 = only_artifact(store, "trainset", "snapshots.h5",
                           where=lambda p: h5py.File(p, "r").attrs["set"] == "train"
                           and h5py.File(p, "r")["parameters"].ndim == 2)
    with h5py.File(train2, "r") as f:
        mu = f["parameters"][:]
        assert mu.shape == (9, 2)
        assert f.attrs["parameter_names"] == "d_x,d_y"
        u2, lam2 = f["primal"][:], f["dual"][:]
    # Tensor grid, the first component fastest: d_x in {0, 1.5, 3}, d_y in {0.02, 0.04, 0.06}.
    np.testing.assert_array_equal(mu[:, 0], np.tile([0.0, 1.5, 3.0], 3))
    np.testing.assert_allclose(mu[:, 1], np.repeat([0.02, 0.04, 0.06], 3), rtol=0, atol=1e-17)
    stats = pd.read_parquet(train2.parent / "solver_stats.parquet")
    assert {"parameter", "d_x", "d_y"} <= set(stats.columns)
    rom = pd.read_parquet(only_artifact(store, "rom", "rom_errors.parquet",
                                        where=lambda p: "d_y" in pd.read_parquet(p).columns))
    # full and truncated dual basis, exact and paper algorithm, training and test points
    assert len(rom) == 2 * 2 * (9 + 4)
    for stage in ["compactness", "generalization", "specificity"]:
        assert len(list((store / stage).glob("*/*.parquet"))) == 2, stage  # one per scene

    train1 = only_artifact(store, "trainset", "snapshots.h5",
                           where=lambda p: h5py.File(p, "r").attrs["set"] == "train"
                           and h5py.File(p, "r")["parameters"].ndim == 1)
    with h5py.File(train1, "r") as f:
        d_x, u1, lam1 = f["parameters"][:], f["primal"][:], f["dual"][:]
    for j, dx in enumerate(d_x):
        k = int(np.flatnonzero((mu[:, 0] == dx) & (np.abs(mu[:, 1] - 0.04) < 1e-15))[0])
        scale = np.abs(u1[:, j]).max()
        np.testing.assert_allclose(u2[:, k], u1[:, j], rtol=0, atol=1e-12 * scale)
        np.testing.assert_allclose(lam2[:, k], lam1[:, j], rtol=0, atol=1e-9 * np.abs(lam1[:, j]).max())


def test_a_moments_map_over_two_components_rebuilds_from_the_model_file(tmp_path):
    """Θ(μ) from model.h5 alone (NumPy, the documented level-by-level rule) times the answer's
    dual coefficients is the pressure `rom.solve` returns, at grid points, between them and
    outside the grid (clamped), to 1e-12 of the largest pressure (the same sums in another
    order). The report's example query names both components and runs."""
    import crom_data

    store = tmp_path / "store"
    scene = scene_2d(tmp_path)
    scene.write_text(scene.read_text().replace("seed = 20234", 'seed = 20234\nmodel_dual = "registered-moments-cpg"'))
    run(store, scene)
    with h5py.File(store / "scenes/ironing-2d-small/model.h5", "r") as model:
        assert model.attrs["dual_basis"] == "registered-moments-cpg" and int(model.attrs["reg_dims"]) == 2
        assert len(model["reg_table"]) % 4 == 0 and len(model["reg_table"]) // 4 <= 9
        rom = crom_data.open_store(store).scene("ironing-2d-small").rom()
        for d_x, d_y in [(0.0, 0.02), (1.5, 0.04), (0.7, 0.031), (2.9, 0.055), (3.0, 0.06), (1.1, 0.0201)]:
            r = rom.solve(d_x=d_x, d_y=d_y)
            theta = _push(model, [d_x, d_y])
            assert theta.shape[1] == len(r.dual_coefficients)
            p = theta @ r.dual_coefficients
            assert r.pressure.max() > 0, (d_x, d_y)
            np.testing.assert_allclose(p, r.pressure, rtol=0, atol=1e-12 * np.abs(r.pressure).max())
    # the report's example query gives both components, and it runs
    import re
    html = (store / "scenes/ironing-2d-small/report/index.html").read_text()
    example = re.search(r"<code>crom query (\S+) --at (\S+)</code>", html)
    assert example and example.group(2).startswith("d_x=") and ",d_y=" in example.group(2), example
    subprocess.run([str(crom_bin()), "--store", str(store), "query", str(scene), "--at", example.group(2)], cwd=REPO,
                   check=True, capture_output=True)
