"""Above 1 025 training snapshots the primal metrics read the training set block by block from the
store (the primal matrix is never held whole). Checked here against NumPy on the whole matrix (an
independent implementation: LAPACK's SVD, direct projections), on the rope at nested level 11
(2 049 training snapshots), and for the same bytes on one thread and on two.
"""
import hashlib
import os
import pathlib
import subprocess

import h5py
import numpy as np
import pandas as pd
import pytest

from conftest import REPO, crom_bin

LEVEL = 11


def scene_file(tmp: pathlib.Path) -> pathlib.Path:
    text = (REPO / "data" / "scenes" / "rope.toml").read_text()
    text = text.replace('name = "rope"', 'name = "rope-streamed"', 1)
    text = text.replace("n_train = 10", f"train_level = {LEVEL}", 1)
    text = text.replace("specificity_samples = 1000", "specificity_samples = 40\nloo_folds = 16", 1)
    path = tmp / "rope-streamed.toml"
    path.write_text(text)
    return path


def run(scene: pathlib.Path, store: pathlib.Path, threads: int) -> pathlib.Path:
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", str(scene), "--offline"], cwd=REPO,
                   check=True, capture_output=True, env=env)
    return store / "scenes" / "rope-streamed"


@pytest.fixture(scope="module")
def studies(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("streamed")
    scene = scene_file(tmp)
    return run(scene, tmp / "two", 2), run(scene, tmp / "one", 1)


def test_the_keys_say_the_primal_is_streamed(studies):
    published, _ = studies
    # (compactness takes the basis' key as an input, so its key changes with it)
    for name in ["basis.h5", "generalization.parquet", "specificity.parquet"]:
        artifact = (published / name).resolve().parent
        spec = (artifact / "manifest.json").read_text()
        assert '"primal":"streamed"' in spec.replace(" ", ""), f"{name}: the key spec does not mark the streamed primal"


def test_pod_and_compactness_match_numpy_on_the_whole_matrix(studies):
    published, _ = studies
    with h5py.File(published / "train.h5", "r") as f:
        s = f["primal"][()]
    assert s.shape[1] == 2 ** LEVEL + 1
    with h5py.File(published / "basis.h5", "r") as f:
        modes = f["primal_pod/modes"][()]
        sv = f["primal_pod/singular_values"][()]
    ref = np.linalg.svd(s, compute_uv=False)
    # Singular values: 1e-10 of the largest (LAPACK and crom's blockwise frame differ by rounding
    # of ||S|| sized quantities; the frame's stored bound is of the order eps ||S||_F).
    k = min(len(ref), len(sv))
    assert np.max(np.abs(sv[:k] - ref[:k])) <= 1e-10 * ref[0]
    # The modes are orthonormal and span what the leading singular vectors span.
    m = modes.shape[1]
    assert np.max(np.abs(modes.T @ modes - np.eye(m))) <= 1e-10
    c = pd.read_parquet(published / "compactness.parquet")
    c = c[(c.field == "primal") & (c.basis == "orth")].set_index("m")["value"]
    total = np.linalg.norm(s)
    coords = modes.T @ s
    for mm in [1, 2, 5, 10, m // 2, m]:
        direct = np.linalg.norm(s - modes[:, :mm] @ coords[:mm]) / total
        # 1e-9 absolute: a difference of two O(||S||) matrices formed two ways, relative to ||S||.
        assert abs(c[mm] - direct) <= 1e-9, f"C({mm}) = {c[mm]} vs {direct}"


def test_leave_one_out_matches_numpy_folds(studies):
    published, _ = studies
    with h5py.File(published / "train.h5", "r") as f:
        s = f["primal"][()]
    n = s.shape[1]
    g = pd.read_parquet(published / "generalization.parquet")
    g = g[(g.field == "primal") & (g.basis == "orth")].set_index("m")
    folds = int(g["count"].iloc[0])
    assert folds == 16 < n, "the scene's sample of 16 folds"
    which = [(k * n) // folds for k in range(folds)]
    ms = [1, 2, 4, 8]
    errors = {m: [] for m in ms}
    for i in which:
        rest = np.delete(s, i, axis=1)
        u, _, _ = np.linalg.svd(rest, full_matrices=False)
        x = s[:, i]
        for m in ms:
            errors[m].append(np.linalg.norm(x - u[:, :m] @ (u[:, :m].T @ x)) / np.linalg.norm(x))
    for m in ms:
        # 1e-8 absolute on errors of order 1e-2..1: two SVDs of the same matrix whose m-th and
        # (m+1)-th singular values are well apart at these m.
        assert abs(g.loc[m, "mean"] - np.mean(errors[m])) <= 1e-8, f"G({m})"


def test_same_bytes_on_one_thread_and_two(studies):
    two, one = studies
    def digest(p):
        return hashlib.blake2b(p.read_bytes()).hexdigest()
    for name in ["basis.h5", "compactness.parquet", "generalization.parquet", "specificity.parquet"]:
        assert digest(two / name) == digest(one / name), name
