"""The recipes of docs/store-format.md, checked on real stores with nothing but the page: every
artifact's key recomputed from its manifest, every snapshot's and column family's key from the
mesh key, the solver settings and the parameter, every block's id from its snapshot keys, every
column's hash from its values, and every manifest's file hashes."""
import json
import tomllib

import blake3
import h5py
import numpy as np
import pandas as pd
import pytest

from conftest import REPO


def key(stage, algorithm_version, schema_version, params, inputs):
    """blake3 of the canonical JSON description (docs/store-format.md, "Content keys")."""

    def s(v):
        if isinstance(v, dict):
            return {k: s(v[k]) for k in sorted(v)}
        if isinstance(v, list):
            return [s(x) for x in v]
        return v

    spec = {"stage": stage, "algorithm_version": algorithm_version, "schema_version": schema_version,
            "params": s(params), "inputs": dict(sorted(inputs.items()))}
    return blake3.blake3(json.dumps(spec, separators=(",", ":")).encode()).hexdigest()


@pytest.fixture(params=["rope_store", "hertz_store"])
def store(request):
    return request.getfixturevalue(request.param)


def manifests(store):
    return [(p.parent, json.loads(p.read_text())) for p in sorted(store.glob("*/*/manifest.json"))]


def test_every_artifact_key_recomputes_from_its_manifest(store):
    found = manifests(store)
    assert len(found) > 10
    for directory, m in found:
        assert (directory.parent.name, directory.name) == (m["stage"], m["key"])
        assert key(m["stage"], m["algorithm_version"], m["schema_version"], m["parameters"], m["inputs"]) == m["key"], directory
        listed = {f["name"] for f in m["files"]}
        assert listed == {p.name for p in directory.iterdir()} - {"manifest.json"}
        for f in m["files"]:
            data = (directory / f["name"]).read_bytes()
            assert (len(data), blake3.blake3(data).hexdigest()) == (f["bytes"], f["blake3"])


def test_snapshot_family_block_and_column_recipes(store):
    (mesh,) = [m for _, m in manifests(store) if m["stage"] == "mesh"]
    families = sorted((store / "columns").iterdir())
    assert len(families) == 1
    family = json.loads((families[0] / "family.json").read_text())
    assert family["schema_version"] == 2
    scene = (store / "scenes" / family["scene"] / "study.json")
    study = json.loads(scene.read_text())
    assert study["layout_version"] == 1 and study["parameter_names"] == family["parameter_names"]
    # The solver settings as the scene file gives them (the algorithm versions are the ones
    # docs/store-format.md states; a bump of either changes these keys on purpose).
    with open(REPO / "data" / "scenes" / f"{family['scene']}.toml", "rb") as f:
        solver = tomllib.load(f)["solver"]
    index = pd.read_parquet(families[0] / "index.parquet")
    names = family["parameter_names"]
    assert len(names) == 1
    assert key("snapshot", 3, 2, {"family": "columns", "parameters": names, "solver": solver},
               {"mesh": mesh["key"]}) == family["family"]
    sets = [m for _, m in manifests(store) if m["stage"] == "trainset"]
    for row in index.itertuples():
        params = {"parameter": float(getattr(row, names[0])), "solver": solver}
        assert key("snapshot", 3, 1, params, {"mesh": mesh["key"]}) == row.snapshot_key
    snapshot_keys = {k for m in sets for r, k in m["inputs"].items() if r.startswith("snapshot")}
    assert snapshot_keys <= set(index.snapshot_key)
    for block, rows in index.groupby("block"):
        rows = rows.sort_values("column")
        assert list(rows.snapshot_key) == sorted(rows.snapshot_key)
        assert block.endswith("blk-" + blake3.blake3(",".join(rows.snapshot_key).encode()).hexdigest()[:24] + ".h5")
        with h5py.File(store / block, "r") as f:
            assert f["primal"].shape == (family["n_dof"], len(rows))
            assert f["dual"].shape == (family["n_contact"], len(rows))
            for r in rows.itertuples():
                column = np.concatenate([f["primal"][:, r.column], f["dual"][:, r.column]]).astype("<f8")
                assert blake3.blake3(column.tobytes()).hexdigest() == r.blake3
                assert f["parameters"][r.column, 0] == getattr(r, names[0])


def test_parquet_types_and_nulls_follow_the_conventions(store):
    import pyarrow.parquet as pq

    for path in sorted(store.glob("*/*/*.parquet")) + [store / "catalog.parquet"]:
        table = pq.read_table(path)
        for field in table.schema:
            assert str(field.type) in {"string", "large_string", "uint64", "double"}, (path, field)
            if str(field.type) != "double":
                assert table.column(field.name).null_count == 0, (path, field.name)
