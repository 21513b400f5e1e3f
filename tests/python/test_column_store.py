"""The columnar snapshot store from h5py and pandas: the index table, the block files, and the
training sets as virtual datasets that read exactly the block columns they name.

Exact comparisons (`np.array_equal`) are intended: a virtual dataset and a direct read of its
source column return the same stored float64 bits.
"""
import time

import h5py
import numpy as np
import pandas as pd

from conftest import only_artifact


def family_dir(store):
    fams = sorted((store / "columns").iterdir())
    assert len(fams) == 1, fams
    return fams[0]


def test_index_opens_in_pandas_with_one_row_per_snapshot(hertz_store):
    start = time.perf_counter()
    index = pd.read_parquet(family_dir(hertz_store) / "index.parquet")
    assert time.perf_counter() - start < 2.0
    # hertz: 12 training + 11 test points, each solved once.
    assert len(index) == 23
    assert index["snapshot_key"].is_unique
    for col in ["d", "block", "column", "blake3", "iterations", "kkt_residual", "seconds"]:
        assert col in index.columns, col
    assert (index["kkt_residual"] <= 1e-8).all()
    # Every row names a block file that exists, with the recorded size.
    for block, size in index.groupby("block")["block_bytes"].first().items():
        assert (hertz_store / block).stat().st_size == size


def test_training_set_is_a_view_on_the_blocks(hertz_store):
    path = only_artifact(hertz_store, "trainset", "snapshots.h5", where=lambda p: h5py.File(p, "r").attrs["set"] == "train")
    stats = pd.read_parquet(path.parent / "solver_stats.parquet")
    with h5py.File(path, "r") as f:
        assert f["primal"].is_virtual and f["dual"].is_virtual
        primal, dual = f["primal"][:], f["dual"][:]
        np.testing.assert_array_equal(f["parameters"][:], stats["parameter"].to_numpy())
    assert primal.shape == (2080, 12) and dual.shape == (79, 12)
    for j, row in stats.iterrows():
        with h5py.File(hertz_store / row["block"], "r") as b:
            assert np.array_equal(b["primal"][:, row["column"]], primal[:, j])
            assert np.array_equal(b["dual"][:, row["column"]], dual[:, j])
    # A virtual dataset with a missing source reads as zeros in HDF5; these are real snapshots.
    assert (np.abs(primal).max(axis=0) > 0).all()


def test_block_columns_are_chunked_one_snapshot_per_chunk(hertz_store):
    blocks = sorted((family_dir(hertz_store) / "blocks").glob("*.h5"))
    assert blocks
    with h5py.File(blocks[0], "r") as b:
        n_dof, width = b["primal"].shape
        assert b["primal"].chunks == (n_dof, 1)
        assert b["parameters"].shape == (width, 1)
