"""Degenerate study settings (the fast subset of the stress matrix): each either gives
answers that pass a check derived outside crom, or is refused with exit 2 naming the field.
Variants of the rope scene, run with the real binary; artifacts read with pandas and h5py."""
import pathlib
import re
import subprocess

import h5py
import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest

from conftest import REPO, crom_bin


def rope_variant(tmp: pathlib.Path, name: str, edits) -> pathlib.Path:
    text = (REPO / "data" / "scenes" / "rope.toml").read_text()
    text = text.replace('name = "rope"', f'name = "{name}"', 1)
    for a, b in edits:
        assert a in text, f"rope.toml has no `{a}`: update this test"
        text = text.replace(a, b, 1)
    path = tmp / f"{name}.toml"
    path.write_text(text)
    return path


def run(tmp: pathlib.Path, scene: pathlib.Path):
    store = tmp / "store"
    p = subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", str(scene)], cwd=REPO,
                       capture_output=True, text=True)
    return p, store / "scenes" / scene.stem


def assert_all_finite(scene_dir: pathlib.Path):
    """No NaN or infinity in any table or array the scene's names lead to."""
    bad = []
    for path in scene_dir.glob("*.parquet"):
        t = pq.read_table(path)
        for name in t.column_names:
            col = t.column(name).drop_null()
            if pa.types.is_floating(col.type) and len(col) and pc.any(pc.invert(pc.is_finite(col))).as_py():
                bad.append(f"{path.name}:{name}")
    for path in scene_dir.glob("*.h5"):
        with h5py.File(path, "r") as f:
            f.visititems(lambda n, o: bad.append(f"{path.name}:{n}") if isinstance(o, h5py.Dataset)
                         and o.dtype.kind == "f" and o.size and not np.isfinite(o[()]).all() else None)
    assert not bad, f"non-finite values in {bad}"


def test_no_contact_anywhere(tmp_path):
    """The obstacle 50 below the rope: nothing touches, so every pressure snapshot is zero, the
    lifted contact-free solution is exact (primal error 0 at every point, both algorithms),
    and the relative dual error is undefined (0/0): a null, never NaN in the file."""
    scene = rope_variant(tmp_path, "no-contact", [("offset = -0.5", "offset = -50.0")])
    p, d = run(tmp_path, scene)
    assert p.returncode == 0, p.stderr
    with h5py.File(d / "train.h5", "r") as f:
        assert not np.any(f["dual"][()]), "a pressure snapshot is not zero"
    e = pd.read_parquet(d / "rom_errors.parquet")
    assert (e.outcome == "converged").all()
    assert (e.primal_error <= 1e-12).all(), e.primal_error.max()
    assert e.dual_error.isna().all()
    assert_all_finite(d)


def test_two_training_points(tmp_path):
    """The smallest training set: the full bases reproduce both training snapshots (1e-10, the
    solver's tolerance), and every test point converges."""
    scene = rope_variant(tmp_path, "two", [("n_train = 10", "n_train = 2")])
    p, d = run(tmp_path, scene)
    assert p.returncode == 0, p.stderr
    e = pd.read_parquet(d / "rom_errors.parquet")
    train = e[(e.set == "train") & (e.dual_basis == "full") & (e.algorithm == "exact")]
    assert len(train) == 2 and (train.primal_error <= 1e-10).all() and (train.dual_error <= 1e-10).all()
    assert (e.outcome == "converged").all()
    assert_all_finite(d)


def test_truncation_tolerance_one_keeps_no_generator(tmp_path):
    """Tolerance 1 is met by the empty cone (||lambda - 0|| / ||lambda|| = 1), so the truncated
    dual basis is empty: the reduced pressure is zero (dual error exactly 1 wherever there is
    contact), and the answer is the contact-free solution, which the indicator flags: it
    penetrates the obstacle at every such point."""
    scene = rope_variant(tmp_path, "tol-one", [("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = 1.0")])
    p, d = run(tmp_path, scene)
    assert p.returncode == 0, p.stderr
    e = pd.read_parquet(d / "rom_errors.parquet")
    t = e[(e.dual_basis == "truncated") & e.dual_error.notna()]
    assert len(t) > 0 and (t.r_dual == 0).all()
    assert np.allclose(t.dual_error, 1.0, rtol=0, atol=1e-15)
    assert (t.penetration > 0).all()
    assert_all_finite(d)


def test_rank_request_beyond_the_snapshots(tmp_path):
    """study.max_rank = 1000 with 10 snapshots: the curves stop at m = 10."""
    scene = rope_variant(tmp_path, "rank-1000", [("[study]", "[study]\nmax_rank = 1000")])
    p, d = run(tmp_path, scene)
    assert p.returncode == 0, p.stderr
    c = pd.read_parquet(d / "compactness.parquet")
    assert c.m.max() == 10
    assert_all_finite(d)


@pytest.mark.parametrize("edits, field", [
    ([("n_train = 10", "n_train = 1")], "parameter.n_train"),
    ([("min = -0.5", "min = 0.25"), ("max = 0.5", "max = 0.25")], "parameter.max"),
    ([("[study]", "[study]\nmax_rank = 0")], "study.max_rank"),
    ([("dual_cone_tol_truncated = 0.2", "dual_cone_tol_truncated = -0.1")], "study.dual_cone_tol_truncated"),
    ([("rel_tol = 1e-10", "rel_tol = 0.0")], "solver.rel_tol"),
])
def test_settings_that_cannot_work_are_refused(tmp_path, edits, field):
    """Exit 2, the field named, and nothing written to the store."""
    scene = rope_variant(tmp_path, "refused", edits)
    p, _ = run(tmp_path, scene)
    assert p.returncode == 2, p.stdout + p.stderr
    assert re.search(rf"field `{re.escape(field)}`", p.stderr), p.stderr
    assert not (tmp_path / "store").exists() or not any((tmp_path / "store").rglob("manifest.json"))
