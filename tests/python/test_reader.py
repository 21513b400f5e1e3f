"""crom_data (python/) against stores written by the real `crom` binary.

Everything the reader returns is compared with an independent reading of the same store: the
catalog's `path` column opened with h5py / pandas, the manifests, and the scene files. Error
cases are produced by real conditions on copies of a store (files moved, truncated, manifests
edited, `crom verify`), never on the session stores the other tests share.
"""
import json
import os
import pathlib
import shutil
import subprocess
import tomllib

import h5py
import numpy as np
import pandas as pd
import pytest

import crom_data
from conftest import REPO, crom_bin

SCENE = "ironing-fine"
# Parquet tables and the stage that writes each (schemas/src/artifact.rs).
TABLE_STAGE = {"compactness": "compactness", "generalization": "generalization", "specificity": "specificity",
               "nested": "nested", "rom_errors": "rom", "tradeoff": "rom"}


def scene_file(name: str) -> dict:
    return tomllib.loads((REPO / "data" / "scenes" / f"{name}.toml").read_text())


def catalog_row(store: pathlib.Path, stage: str, scene: str, set_name: str = "") -> pd.Series:
    cat = pd.read_parquet(store / "catalog.parquet")
    rows = cat[(cat["stage"] == stage) & (cat["scene"] == scene) & (cat["set"] == set_name)]
    assert len(rows) == 1, f"expected one {stage} {set_name!r} row of {scene} in the catalog, found {len(rows)}"
    return rows.iloc[0]


def manifest(artifact: pathlib.Path) -> dict:
    return json.loads((artifact / "manifest.json").read_text())


def copy_store(store: pathlib.Path, tmp_path: pathlib.Path) -> pathlib.Path:
    """A private copy (relative links kept as links, so they point into the copy)."""
    copy = tmp_path / "store"
    shutil.copytree(store, copy, symlinks=True)
    return copy


def study_file(store: pathlib.Path, scene: str) -> pathlib.Path:
    path = (store / "scenes" / scene / "study.json").resolve()
    assert store.resolve() in path.parents, f"{path} is outside {store}"
    return path


# --- reading -------------------------------------------------------------------------------------


def test_published_scenes_and_sets(ironing_fine_store):
    store = crom_data.open_store(ironing_fine_store)
    links = sorted(p.name for p in (ironing_fine_store / "scenes").iterdir() if not p.name.startswith("."))
    assert links == [SCENE]
    assert store.scenes() == links
    sc = store.scene(SCENE)
    assert sc.study["scene"] == SCENE and sc.study["online"] is True
    levels = scene_file(SCENE)["parameter"]["nested_levels"]
    assert sc.sets() == ["train", "test"] + [f"nested-{k}" for k in range(1, levels + 1)]
    cat = store.catalog()
    assert set(sc.sets()) == set(cat.loc[cat["stage"] == "trainset", "set"])


@pytest.mark.parametrize("set_name", ["train", "test", "nested-3"])
def test_snapshot_set_equals_the_artifact_read_directly(ironing_fine_store, set_name):
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    ts = sc.trainset(set_name)
    row = catalog_row(ironing_fine_store, "trainset", SCENE, set_name)
    artifact = ironing_fine_store / row["path"]
    m = manifest(artifact)
    assert ts.key == row["key"] == m["key"] == artifact.name
    assert ts.path.samefile(artifact / "snapshots.h5")
    assert ts.primal.shape == tuple(m["summary"]["primal_shape"])
    assert ts.dual.shape == tuple(m["summary"]["dual_shape"])
    with h5py.File(artifact / "snapshots.h5", "r") as f:
        assert f.attrs["set"] == set_name
        np.testing.assert_array_equal(ts.primal, f["primal"][()])
        np.testing.assert_array_equal(ts.dual, f["dual"][()])
        np.testing.assert_array_equal(ts.parameters, f["parameters"][()])
        assert ts.parameter_names == f.attrs["parameter_names"].split(",")
    assert ts.parameter_names == [scene_file(SCENE)["parameter"]["name"]]
    # The published name resolves to the same file.
    entry = f"nested/level-{set_name[7:]}.h5" if set_name.startswith("nested-") else f"{set_name}.h5"
    assert (ironing_fine_store / "scenes" / SCENE / entry).resolve() == (artifact / "snapshots.h5").resolve()


def test_training_set_columns_and_parameters_match_the_solver_statistics(ironing_fine_store):
    ts = crom_data.open_store(ironing_fine_store).scene(SCENE).trainset("train")
    artifact = ironing_fine_store / catalog_row(ironing_fine_store, "trainset", SCENE, "train")["path"]
    stats = pd.read_parquet(artifact / "solver_stats.parquet")
    pd.testing.assert_frame_equal(ts.stats, stats)
    p = scene_file(SCENE)["parameter"]
    assert ts.primal.shape[1] == ts.dual.shape[1] == len(ts.parameters) == p["n_train"] == len(stats)
    np.testing.assert_array_equal(stats["index"].to_numpy(), np.arange(len(stats)))
    np.testing.assert_array_equal(ts.parameters, stats["parameter"].to_numpy())
    # The training grid spans the scene file's range (1e-12: linspace rounding of values of order 1).
    np.testing.assert_allclose(ts.parameters, np.linspace(p["min"], p["max"], p["n_train"]), rtol=0, atol=1e-12)


def test_mesh_matches_h5py_and_the_snapshot_rows(ironing_fine_store):
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    mesh, ts = sc.mesh(), sc.trainset("train")
    artifact = ironing_fine_store / catalog_row(ironing_fine_store, "mesh", SCENE)["path"]
    with h5py.File(artifact / "mesh.h5", "r") as f:
        for name in ("nodes", "cells", "contact_nodes", "node_body", "cell_body"):
            np.testing.assert_array_equal(getattr(mesh, name), f[name][()])
        assert mesh.dofs_per_node == f.attrs["dofs_per_node"]
    assert mesh.nodes.shape[0] * mesh.dofs_per_node == ts.primal.shape[0]
    assert len(mesh.contact_nodes) == ts.dual.shape[0]
    assert sc.file("mesh.xdmf").samefile(artifact / "mesh.xdmf")


def test_basis_groups_match_h5py(ironing_fine_store):
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    bases, ts = sc.basis(), sc.trainset("train")
    row = catalog_row(ironing_fine_store, "basis", SCENE)
    assert set(bases) == set(row["bases"].split(","))
    with h5py.File(ironing_fine_store / row["path"] / "basis.h5", "r") as f:
        for group, basis in bases.items():
            for field in ("modes", "singular_values", "selected", "compactness"):
                if field in f[group]:
                    np.testing.assert_array_equal(getattr(basis, field), f[group][field][()])
                else:
                    assert getattr(basis, field) is None, (group, field)
            assert basis.attrs["rank"] == f[group].attrs["rank"] == basis.modes.shape[1]
    assert bases["primal_pod"].modes.shape[0] == ts.primal.shape[0]
    for group in ("dual_pod", "dual_cpg", "dual_cpg_truncated"):
        assert bases[group].modes.shape[0] == ts.dual.shape[0]
    assert bases["dual_cpg"].selected.max() < ts.dual.shape[1]


@pytest.mark.parametrize("table", TABLE_STAGE)
def test_tables_equal_the_catalog_artifacts(ironing_fine_store, table):
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    row = catalog_row(ironing_fine_store, TABLE_STAGE[table], SCENE)
    expected = pd.read_parquet(ironing_fine_store / row["path"] / f"{table}.parquet")
    assert len(expected) > 0
    timed = table in ("rom_errors", "tradeoff")
    pd.testing.assert_frame_equal(getattr(sc, table)(**({"timings": False} if timed else {})), expected)
    pd.testing.assert_frame_equal(sc.table(table), expected)
    assert (expected["scene"] == SCENE).all()
    if timed:
        # By default the timings (a separate file, same rows) are joined beside the results.
        name = {"rom_errors": "rom_timings", "tradeoff": "tradeoff_timings"}[table]
        times = pd.read_parquet(ironing_fine_store / row["path"] / f"{name}.parquet")
        joined = getattr(sc, table)()
        pd.testing.assert_frame_equal(joined[expected.columns], expected)
        extra = [c for c in times.columns if c not in expected.columns]
        assert extra and all(c.endswith("seconds") or c == "speedup" for c in extra), extra
        pd.testing.assert_frame_equal(joined[extra], times[extra])


def test_comparison_tables_are_published(ironing_fine_store):
    """The comparison's tables are published names, equal to the artifact read directly,
    with one block of rows per approximation in the scene file's order (a `local` entry gives
    one per cell count)."""
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    for stage, table in [("comparison", "comparison"), ("online-comparison", "online_comparison")]:
        row = catalog_row(ironing_fine_store, stage, SCENE)
        expected = pd.read_parquet(ironing_fine_store / row["path"] / f"{table}.parquet")
        pd.testing.assert_frame_equal(sc.comparison(table), expected)
    names = []
    for a in scene_file(SCENE)["comparison"]["approximations"]:
        kind = a["kind"]
        if kind == "local":
            names += [f"local-{k}" for k in a["cells"]]
        elif kind == "registered":
            interp = a.get("interpolation", "linear") if a["map"] == "translate" else None
            names.append(f"registered-{a['map']}{'-' + interp if interp else ''}-{a['basis']}")
        else:
            names.append(kind)
    curves = sc.comparison()
    assert list(dict.fromkeys(curves["approximation"])) == names
    online = sc.comparison("online_comparison")
    assert set(online["approximation"]) == {n for n in names if n != "pod" and not n.endswith("-pod")}


def test_report_dir_is_the_report_artifact(ironing_fine_store):
    sc = crom_data.open_store(ironing_fine_store).scene(SCENE)
    row = catalog_row(ironing_fine_store, "report", SCENE)
    assert sc.report_dir.resolve() == (ironing_fine_store / row["path"]).resolve()
    assert (sc.report_dir / "index.html").is_file()


def test_catalog_published_names_match_the_study(ironing_fine_store):
    store = crom_data.open_store(ironing_fine_store)
    sc = store.scene(SCENE)
    cat = store.catalog()
    named = {}
    for _, row in cat[cat["published"] != ""].iterrows():
        for name in row["published"].split(","):
            scene, entry = name.split("/", 1)
            assert scene == SCENE
            named[entry] = (row["stage"], row["key"])
    assert named == {name: (e["stage"], e["key"]) for name, e in sc.entries.items()}


def test_crom_ls_parquet_agrees_with_the_catalog(ironing_fine_store, tmp_path):
    catalog = crom_data.open_store(ironing_fine_store).catalog()
    out = tmp_path / "ls.parquet"
    subprocess.run([str(crom_bin()), "--store", str(ironing_fine_store), "ls", "--format", "parquet", "--output",
                    str(out)], cwd=REPO, check=True, capture_output=True)
    pd.testing.assert_frame_equal(pd.read_parquet(out), catalog)
    out = tmp_path / "ls-basis.parquet"
    subprocess.run([str(crom_bin()), "--store", str(ironing_fine_store), "ls", "--stage", "basis", "--format",
                    "parquet", "--output", str(out)], cwd=REPO, check=True, capture_output=True)
    pd.testing.assert_frame_equal(pd.read_parquet(out),
                                  catalog[catalog["stage"] == "basis"].reset_index(drop=True))


def test_a_copy_without_symbolic_links_still_reads(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    links = [p for p in (copy / "scenes").rglob("*") if p.is_symlink()]
    assert links, "the published names are symbolic links"
    for p in links:
        p.unlink()
    sc = crom_data.open_store(copy).scene("rope")
    original = crom_data.open_store(rope_store).scene("rope")
    np.testing.assert_array_equal(sc.trainset("train").dual, original.trainset("train").dual)
    pd.testing.assert_frame_equal(sc.generalization(), original.generalization())


# --- errors, each on a real condition -----------------------------------------------------------


def test_missing_or_foreign_store(tmp_path):
    with pytest.raises(crom_data.StoreNotFound, match="no such directory") as err:
        crom_data.open_store(tmp_path / "nowhere")
    assert str(tmp_path / "nowhere") in str(err.value)
    (tmp_path / "other").mkdir()
    (tmp_path / "other" / "notes.txt").write_text("not a store")
    with pytest.raises(crom_data.StoreNotFound, match="not a crom store"):
        crom_data.open_store(tmp_path / "other")
    assert issubclass(crom_data.StoreNotFound, crom_data.CromDataError)


def test_unknown_scene_names_the_published_ones_and_the_fix(ironing_fine_store):
    store = crom_data.open_store(ironing_fine_store)
    with pytest.raises(crom_data.SceneNotFound) as err:
        store.scene("hertz-fine")
    message = str(err.value)
    assert "'hertz-fine'" in message and "run hertz-fine`" in message
    for name in os.listdir(ironing_fine_store / "scenes"):
        if not name.startswith("."):
            assert name in message


def test_nested_of_a_scene_without_nested_levels_is_missing(rope_store):
    assert "nested_levels" not in scene_file("rope")["parameter"]
    sc = crom_data.open_store(rope_store).scene("rope")
    with pytest.raises(crom_data.ArtifactMissing, match="no nested levels") as err:
        sc.nested()
    assert "'rope'" in str(err.value) and "nested.parquet" in str(err.value)
    with pytest.raises(crom_data.ArtifactMissing, match="nested-1"):
        sc.trainset("nested-1")


def test_moved_artifact_directory_is_missing(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    row = catalog_row(copy, "basis", "rope")
    assert crom_data.open_store(copy).scene("rope").basis()  # readable before
    shutil.move(copy / row["path"], tmp_path / "moved-away")
    with pytest.raises(crom_data.ArtifactMissing, match="is gone") as err:
        crom_data.open_store(copy).scene("rope").basis()
    assert row["key"] in str(err.value) and "basis.h5" in str(err.value) and "run rope`" in str(err.value)


def test_artifact_quarantined_by_crom_verify_is_missing(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    row = catalog_row(copy, "compactness", "rope")
    path = copy / row["path"] / "compactness.parquet"
    path.write_bytes(path.read_bytes()[:-1] + bytes([path.read_bytes()[-1] ^ 0xFF]))  # same size, other bytes
    verify = subprocess.run([str(crom_bin()), "--store", str(copy), "--quiet", "verify"], cwd=REPO,
                            capture_output=True, text=True)
    assert verify.returncode == 1, verify.stdout + verify.stderr
    assert not (copy / row["path"]).exists(), "crom verify quarantines the damaged artifact"
    sc = crom_data.open_store(copy).scene("rope")
    with pytest.raises(crom_data.ArtifactMissing, match="withdrawn"):
        sc.compactness()
    assert len(sc.specificity()) > 0  # the rest of the study still reads


def test_schema_version_newer_than_the_reader(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    artifact = copy / catalog_row(copy, "trainset", "rope", "train")["path"]
    m = manifest(artifact)
    m["schema_version"] += 1
    (artifact / "manifest.json").write_text(json.dumps(m))
    sc = crom_data.open_store(copy).scene("rope")
    with pytest.raises(crom_data.SchemaTooNew, match="upgrade crom_data") as err:
        sc.trainset("train")
    assert "'rope'" in str(err.value) and "train.h5" in str(err.value)
    assert sc.trainset("test").primal.shape[1] > 0  # other sets are untouched
    study = study_file(copy, "rope")
    s = json.loads(study.read_text())
    s["layout_version"] += 1
    study.write_text(json.dumps(s))
    with pytest.raises(crom_data.SchemaTooNew, match="upgrade crom_data"):
        crom_data.open_store(copy).scene("rope")


def test_schema_version_older_than_the_reader(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    artifact = copy / catalog_row(copy, "basis", "rope")["path"]
    m = manifest(artifact)
    assert m["schema_version"] >= 1
    m["schema_version"] -= 1
    (artifact / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(crom_data.StaleArtifact, match="run rope`") as err:
        crom_data.open_store(copy).scene("rope").basis()
    assert "basis.h5" in str(err.value)


@pytest.mark.parametrize("stage,set_name,file,read", [
    ("compactness", "", "compactness.parquet", lambda sc: sc.compactness()),
    ("trainset", "train", "snapshots.h5", lambda sc: sc.trainset("train").primal),
])
def test_truncated_file_is_corrupt(rope_store, tmp_path, stage, set_name, file, read):
    copy = copy_store(rope_store, tmp_path)
    path = copy / catalog_row(copy, stage, "rope", set_name)["path"] / file
    data = path.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    with pytest.raises(crom_data.CorruptArtifact, match=f"{len(data) // 2} bytes") as err:
        read(crom_data.open_store(copy).scene("rope"))
    assert str(path) in str(err.value) and "crom" in str(err.value) and "verify" in str(err.value)


def test_file_the_manifest_does_not_list_is_corrupt(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    artifact = copy / catalog_row(copy, "specificity", "rope")["path"]
    m = manifest(artifact)
    m["files"] = [f for f in m["files"] if f["name"] != "specificity.parquet"]
    (artifact / "manifest.json").write_text(json.dumps(m))
    with pytest.raises(crom_data.CorruptArtifact, match="does not list specificity.parquet"):
        crom_data.open_store(copy).scene("rope").specificity()


def test_same_size_modification_is_caught_by_blake3_when_available(rope_store, tmp_path):
    pytest.importorskip("blake3")
    copy = copy_store(rope_store, tmp_path)
    path = copy / catalog_row(copy, "generalization", "rope")["path"] / "generalization.parquet"
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    path.write_bytes(bytes(data))
    with pytest.raises(crom_data.CorruptArtifact, match="blake3"):
        crom_data.open_store(copy).scene("rope").generalization()


def test_missing_snapshot_block_is_refused_not_read_as_fill_values(rope_store, tmp_path):
    copy = copy_store(rope_store, tmp_path)
    blocks = sorted(copy.glob("columns/*/blocks/*.h5"))
    assert blocks
    for b in blocks:
        shutil.move(b, tmp_path / b.name)
    ts = crom_data.open_store(copy).scene("rope").trainset("train")
    with pytest.raises(crom_data.ArtifactMissing, match="snapshot block"):
        ts.dual


def test_offline_run_has_no_online_entries(tmp_path):
    store = tmp_path / "offline"
    subprocess.run([str(crom_bin()), "--store", str(store), "--quiet", "run", "rope", "--offline"], cwd=REPO,
                   check=True, capture_output=True)
    sc = crom_data.open_store(store).scene("rope")
    assert sc.study["online"] is False
    assert len(sc.generalization()) > 0  # the offline stages are published
    for read in (lambda: sc.tradeoff(), lambda: sc.rom_errors(), lambda: sc.report_dir):
        with pytest.raises(crom_data.ArtifactMissing, match="--offline"):
            read()
