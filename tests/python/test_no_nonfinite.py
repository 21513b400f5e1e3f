"""No NaN or infinity in any artifact: an undefined value is a Parquet null,
documented with its column (crom_schemas::artifact). Scans every Parquet table and every HDF5
float dataset of the rope, hertz and ironing-fine stores, read with pyarrow and h5py (not with
the code that wrote them)."""
import pathlib
import sys

import pyarrow.parquet as pq
import pytest

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[2] / "scripts"))
from artifact_scan import artifact_files, nonfinite  # noqa: E402


@pytest.mark.parametrize("fixture", ["rope_store", "hertz_store", "ironing_fine_store"])
def test_no_artifact_holds_nan_or_infinity(fixture, request):
    store = request.getfixturevalue(fixture)
    assert artifact_files(store, ".parquet"), "no Parquet files found"
    assert artifact_files(store, ".h5"), "no HDF5 files found"
    bad = nonfinite(store)
    assert not bad, f"non-finite values in {bad}"


def test_training_rows_have_no_full_order_time(hertz_store):
    """The documented null: the full-order solve is timed at test points only."""
    (path,) = [p for p in artifact_files(hertz_store, "rom_timings.parquet")]
    t = pq.read_table(path).to_pandas()
    assert t.loc[t.set == "train", "fom_seconds"].isna().all()
    assert (t.loc[t.set == "test", "fom_seconds"] > 0).all()
