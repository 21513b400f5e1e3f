"""No NaN or infinity in any artifact (issue 16, item 3): an undefined value is a Parquet null,
documented with its column (crom_schemas::artifact). Scans every Parquet table and every HDF5
float dataset of the rope, hertz and ironing-fine stores, read with pyarrow and h5py (not with
the code that wrote them)."""
import pathlib

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq
import pytest


def artifact_files(store: pathlib.Path, suffix: str):
    # the stable names under scenes/ are links to the same files
    return [p for p in store.rglob(f"*{suffix}") if "scenes" not in p.relative_to(store).parts]


@pytest.mark.parametrize("fixture", ["rope_store", "hertz_store", "ironing_fine_store"])
def test_no_artifact_holds_nan_or_infinity(fixture, request):
    store = request.getfixturevalue(fixture)
    bad = []
    tables = artifact_files(store, ".parquet")
    assert tables, "no Parquet files found"
    for path in tables:
        t = pq.read_table(path)
        for name in t.column_names:
            col = t.column(name)
            if pa.types.is_floating(col.type) and len(col.drop_null()):
                if pc.any(pc.invert(pc.is_finite(col.drop_null()))).as_py():
                    bad.append(f"{path.relative_to(store)}:{name}")
    arrays = artifact_files(store, ".h5")
    assert arrays, "no HDF5 files found"
    for path in arrays:
        with h5py.File(path, "r") as f:
            def visit(name, obj):
                if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and obj.size:
                    if not np.isfinite(obj[()]).all():
                        bad.append(f"{path.relative_to(store)}:{name}")
            f.visititems(visit)
    assert not bad, f"non-finite values in {bad}"


def test_training_rows_have_no_full_order_time(hertz_store):
    """The documented null: the full-order solve is timed at test points only."""
    (path,) = [p for p in artifact_files(hertz_store, "rom_timings.parquet")]
    t = pq.read_table(path).to_pandas()
    assert t.loc[t.set == "train", "fom_seconds"].isna().all()
    assert (t.loc[t.set == "test", "fom_seconds"] > 0).all()
