"""Non-finite values in a store's artifacts, read with pyarrow and h5py (not with the code that
wrote them): shared by the stress matrix and `tests/python/test_no_nonfinite.py`."""
import pathlib

import h5py
import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.parquet as pq


def artifact_files(store: pathlib.Path, suffix: str):
    """Files ending in `suffix`, without the stable names under `scenes/` (links to the same)."""
    return [p for p in store.rglob(f"*{suffix}") if "scenes" not in p.relative_to(store).parts]


def nonfinite(store: pathlib.Path):
    """`file:column` of every Parquet float column and every real HDF5 float dataset holding a
    NaN or an infinity (nulls are the documented way to say "undefined")."""
    bad = []
    for path in artifact_files(store, ".parquet"):
        t = pq.read_table(path)
        for name in t.column_names:
            col = t.column(name)
            if pa.types.is_floating(col.type) and len(col.drop_null()):
                if pc.any(pc.invert(pc.is_finite(col.drop_null()))).as_py():
                    bad.append(f"{path.relative_to(store)}:{name}")
    for path in artifact_files(store, ".h5"):
        with h5py.File(path, "r") as f:
            def visit(name, obj):
                if isinstance(obj, h5py.Dataset) and obj.dtype.kind == "f" and obj.size:
                    if not np.isfinite(obj[()]).all():
                        bad.append(f"{path.relative_to(store)}:{name}")
            f.visititems(visit)
    return bad
