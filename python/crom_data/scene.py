"""One published scene study: its entries, opened and verified against their manifests.

`study.json` maps each entry name (`train.h5`, `nested/level-3.h5`, `basis.h5`,
`tradeoff.parquet`, `report`, ...) to `{stage, key, target, schema_version}`; `target` is the
file (or, for `report`, the directory) relative to the store root, inside the artifact directory
`STORE/<stage>/<key>/`. Opening an entry checks, once per Scene object:

* the entry exists (else ArtifactMissing, saying why: no nested levels, an --offline run, or
  withdrawn because `crom verify` quarantined it) and its artifact directory is there
  (ArtifactMissing);
* `manifest.json` exists and names the same stage and key (CorruptArtifact);
* the manifest's `schema_version` is the one this reader knows (SchemaTooNew / StaleArtifact);
* the manifest lists the file and its size matches (CorruptArtifact), and, if the `blake3`
  module is importable, its blake3 too;
* when a set's matrices are read, every snapshot block its virtual datasets refer to exists
  (ArtifactMissing; h5py would silently read a missing block as zeros). Each column's own
  blake3 is `crom verify`'s job.

Orientation (as h5py returns it, C order): `primal` is n_dof x N and `dual` n_contact x N, one
snapshot per column, column j solved at `parameters[j]` (shape N, or N x p for a vector
parameter); dof `dofs_per_node * node + component` (nodes from `mesh.nodes`, n_nodes x 2); dual
row i is the pressure at node `mesh.contact_nodes[i]`. Basis `modes` are n x m, one mode per
column.
"""
from __future__ import annotations

import dataclasses
import functools
import json
import pathlib
import re

import h5py
import numpy as np
import pandas as pd

from .errors import ArtifactMissing, CorruptArtifact, SchemaTooNew, StaleArtifact

try:  # optional: content hashes are checked only when the module is installed
    import blake3 as _blake3
except ImportError:  # pragma: no cover - depends on the environment
    _blake3 = None

#: Layout version of `study.json` and its names this reader reads. The layout version of each
#: artifact's files is not copied here: `study.json` names it per entry (the writer's own
#: `schema_version`), and each artifact's manifest must agree with it.
LAYOUT_VERSION = 1
BASIS_GROUPS = ("primal_pod", "dual_pod", "dual_cpg", "dual_cpg_truncated")


def _check_version(what: str, found, known, fix: str) -> None:
    """The artifact's schema version `found` (its manifest's) against `known`, the one the study
    names for its entry (the version the crom that published the study writes)."""
    if not isinstance(found, int) or not isinstance(known, int):
        raise CorruptArtifact(f"{what}: schema version {found!r} (study: {known!r}) is not an integer; {fix}")
    if found > known:
        raise SchemaTooNew(f"{what}: schema version {found} is newer than the study names ({known}): a newer crom "
                           "wrote it; run that crom's study again and upgrade crom_data (`pip install -U ./python` "
                           "from the crom checkout that wrote the store)")
    if found < known:
        raise StaleArtifact(f"{what}: schema version {found} is older than the study names ({known}); {fix}")


@dataclasses.dataclass
class Basis:
    """One group of `basis.h5`; fields the group does not hold are None."""
    modes: np.ndarray                      # n x m, one basis vector per column
    singular_values: np.ndarray | None     # POD groups: all singular values, descending
    selected: np.ndarray | None            # CPG groups: selected snapshot (column) indices, in order
    compactness: np.ndarray | None         # CPG groups: C(0..m) of the greedy
    attrs: dict                            # rank, tolerance, ...


@dataclasses.dataclass
class Mesh:
    """`mesh.h5`."""
    nodes: np.ndarray          # n_nodes x 2 (x 3: an external scene's 3-D mesh)
    cells: np.ndarray          # n_cells x nodes_per_cell (node indices)
    contact_nodes: np.ndarray  # potential-contact nodes, the order of the dual rows
    node_body: np.ndarray
    cell_body: np.ndarray
    dofs_per_node: int
    path: pathlib.Path         # mesh.h5 (mesh.xdmf beside it opens in ParaView)


class SnapshotSet:
    """A training, test or nested set (`trainset` artifact); matrices are read on first use."""

    def __init__(self, scene: "Scene", name: str, entry: str):
        self.scene, self.name, self.entry = scene, name, entry
        self.path = scene.file(entry)
        self.manifest = scene._manifest(entry)
        self.key = self.manifest["key"]
        self.summary = self.manifest.get("summary", {})

    def __repr__(self) -> str:
        return f"SnapshotSet({self.scene.name!r}, {self.name!r}, key={self.key[:12]}, {self.summary})"

    def _read(self, dataset: str) -> np.ndarray:
        with h5py.File(self.path, "r") as f:
            d = f[dataset]
            if d.is_virtual:  # a missing block would read as fill values: refuse instead
                for src in d.virtual_sources():
                    if not (self.path.parent / src.file_name).is_file():
                        raise ArtifactMissing(
                            f"{self.scene._where(self.entry)} (set {self.name!r}): its snapshot block "
                            f"{src.file_name} (relative to {self.path.parent}) is missing (quarantined by "
                            f"`crom verify`?); {self.scene._rerun()}")
            return d[()]

    @functools.cached_property
    def primal(self) -> np.ndarray:
        """n_dof x N."""
        return self._read("primal")

    @functools.cached_property
    def dual(self) -> np.ndarray:
        """n_contact x N (contact pressure)."""
        return self._read("dual")

    @functools.cached_property
    def parameters(self) -> np.ndarray:
        """N, or N x p for a vector parameter."""
        return self._read("parameters")

    @functools.cached_property
    def parameter_names(self) -> list[str]:
        with h5py.File(self.path, "r") as f:
            names = f.attrs.get("parameter_names")
        if names is None:
            return list(self.scene.study.get("parameter_names", []))
        return [n for n in str(names).split(",") if n]

    @functools.cached_property
    def stats(self) -> pd.DataFrame:
        """`solver_stats.parquet`: per snapshot (column) its key, block, blake3 and solver evidence."""
        return pd.read_parquet(self.scene._artifact_file(self.entry, "solver_stats.parquet"))

    @functools.cached_property
    def timings(self) -> pd.DataFrame:
        """`solver_timings.parquet`: per snapshot (same rows as `stats`) its solve time in
        seconds, kept apart from the results because it differs from run to run."""
        return pd.read_parquet(self.scene._artifact_file(self.entry, "solver_timings.parquet"))


class Scene:
    """The latest published study of one scene (see `Store.scene`)."""

    def __init__(self, store, name: str, version: pathlib.Path, study: dict):
        self.store, self.name, self.version_dir, self.study = store, name, version, study
        where = f"store {store.root}: scene {name!r} ({version / 'study.json'})"
        rerun = f"rerun `crom --store {store.root} run {name}` to republish it"
        _check_version(where, study.get("layout_version"), LAYOUT_VERSION, rerun)
        self._opened: dict[str, dict] = {}   # entry -> verified manifest
        self._verified: set[pathlib.Path] = set()

    def __repr__(self) -> str:
        return f"Scene({self.name!r}, sets={self.sets()}, online={self.study.get('online')})"

    @property
    def entries(self) -> dict:
        """study.json's entries: name -> {stage, key, target, schema_version}."""
        return self.study.get("entries", {})

    # --- opening and verifying entries ---------------------------------------------------------

    def _where(self, entry: str) -> str:
        return f"store {self.store.root}: scene {self.name!r}, entry {entry!r}"

    def _rerun(self) -> str:
        return f"rerun `crom --store {self.store.root} run {self.name}` to recompute it"

    def _missing(self, entry: str, what: str | None = None) -> ArtifactMissing:
        withdrawn = self.study.get("withdrawn", {})
        nested = [s for s in self.sets() if s.startswith("nested-")]
        if entry in withdrawn:
            why = f"it was withdrawn ({withdrawn[entry]}); {self._rerun()}"
        elif entry.startswith("nested"):
            why = ("the scene has no nested levels; add `nested_levels = K` to the [parameter] table of its scene "
                   f"file and run `crom --store {self.store.root} run {self.name}`" if not nested else
                   f"its nested levels are {', '.join(nested)}; raise `nested_levels` in its scene file and rerun")
        elif (entry.split(".")[0] in ("rom_errors", "tradeoff", "report", "online", "model", "reconstruction",
                                      "model_speed")) and not self.study.get("online", True):
            why = ("its last run was --offline (no online reduced solve, no report); run "
                   f"`crom --store {self.store.root} run {self.name}` without --offline")
        else:
            why = f"its last run did not publish it; {self._rerun()}"
        listing = what or f"entries: {', '.join(sorted(self.entries))}"
        return ArtifactMissing(f"{self._where(entry)}: not in the study: {why} ({listing})")

    def _manifest(self, entry: str) -> dict:
        """The verified manifest of the artifact `entry` names (checks the artifact, not yet the file)."""
        if entry in self._opened:
            return self._opened[entry]
        e = self.entries.get(entry)
        if e is None:
            raise self._missing(entry)
        stage, key, root = e.get("stage"), e.get("key"), self.store.root
        where = f"{self._where(entry)} ({stage}/{key})"
        directory = root / str(stage) / str(key)
        if not directory.is_dir():
            raise ArtifactMissing(f"{where}: artifact directory {directory} is gone (moved, deleted, or quarantined "
                                  f"by `crom verify` to {root / '.quarantine'}); {self._rerun()}")
        fix = f"run `crom --store {root} verify` (it quarantines the artifact), then {self._rerun()}"
        try:
            manifest = json.loads((directory / "manifest.json").read_text())
        except FileNotFoundError:
            raise CorruptArtifact(f"{where}: {directory / 'manifest.json'} is missing; {fix}") from None
        except ValueError as err:
            raise CorruptArtifact(f"{where}: {directory / 'manifest.json'} is not JSON ({err}); {fix}") from None
        if manifest.get("stage") != stage or manifest.get("key") != key:
            raise CorruptArtifact(f"{where}: its manifest names {manifest.get('stage')}/{manifest.get('key')}; {fix}")
        _check_version(where, manifest.get("schema_version"), e.get("schema_version"), self._rerun())
        self._opened[entry] = manifest
        return manifest

    def _artifact_file(self, entry: str, name: str) -> pathlib.Path:
        """File `name` of the artifact `entry` names, checked against the manifest."""
        manifest = self._manifest(entry)
        e = self.entries[entry]
        path = self.store.root / e["stage"] / e["key"] / name
        if path in self._verified:
            return path
        where = f"{self._where(entry)} ({e['stage']}/{e['key']})"
        fix = f"run `crom --store {self.store.root} verify` (it quarantines the artifact), then {self._rerun()}"
        listed = {f.get("name"): f for f in manifest.get("files", [])}
        if name not in listed:
            raise CorruptArtifact(f"{where}: its manifest does not list {name}; {fix}")
        if not path.is_file():
            raise CorruptArtifact(f"{where}: {path} is missing; {fix}")
        size, expected = path.stat().st_size, listed[name].get("bytes")
        if size != expected:
            raise CorruptArtifact(f"{where}: {path} has {size} bytes, its manifest says {expected}; {fix}")
        if _blake3 is not None and listed[name].get("blake3"):
            h = _blake3.blake3()
            with open(path, "rb") as f:
                for chunk in iter(lambda: f.read(1 << 22), b""):
                    h.update(chunk)
            if h.hexdigest() != listed[name]["blake3"]:
                raise CorruptArtifact(f"{where}: {path} does not match its manifest's blake3; {fix}")
        self._verified.add(path)
        return path

    def file(self, entry: str) -> pathlib.Path:
        """Verified path of any entry's target: a file, or (report) a directory whose every file
        is checked."""
        manifest = self._manifest(entry)
        e = self.entries[entry]
        directory = self.store.root / e["stage"] / e["key"]
        target = self.store.root / e["target"]
        if target == directory:
            for f in manifest.get("files", []):
                self._artifact_file(entry, f["name"])
            return target
        if target.parent != directory:
            raise CorruptArtifact(f"{self._where(entry)}: its target {e['target']} is not in {directory}; "
                                  f"{self._rerun()}")
        return self._artifact_file(entry, target.name)

    # --- the study's contents ------------------------------------------------------------------

    def sets(self) -> list[str]:
        """Snapshot sets: "train", "test", then "nested-1" ... "nested-K"."""
        out = []
        for name, e in self.entries.items():
            m = re.fullmatch(r"(train|test)\.h5|nested/level-(\d+)\.h5", name)
            if m and e.get("stage") == "trainset":
                out.append(m.group(1) or f"nested-{m.group(2)}")
        return sorted(out, key=lambda s: (0, 0) if s == "train" else (1, 0) if s == "test" else (2, int(s[7:])))

    def trainset(self, name: str = "train") -> SnapshotSet:
        """Snapshot set `name` ("train", "test", "nested-k")."""
        m = re.fullmatch(r"nested-(\d+)", name)
        entry = f"nested/level-{m.group(1)}.h5" if m else f"{name}.h5"
        if entry not in self.entries:
            raise self._missing(entry, f"set {name!r}; sets: {', '.join(self.sets()) or 'none'}")
        return SnapshotSet(self, name, entry)

    def basis(self) -> dict[str, Basis]:
        """`basis.h5`: group name (primal_pod, dual_pod, dual_cpg, dual_cpg_truncated) -> Basis."""
        out = {}
        with h5py.File(self.file("basis.h5"), "r") as f:
            for g in BASIS_GROUPS:
                if g in f:
                    grp = f[g]
                    get = lambda d: grp[d][()] if d in grp else None  # noqa: E731
                    out[g] = Basis(get("modes"), get("singular_values"), get("selected"), get("compactness"),
                                   dict(grp.attrs))
        return out

    def mesh(self) -> Mesh:
        path = self.file("mesh.h5")
        with h5py.File(path, "r") as f:
            return Mesh(*(f[d][()] for d in ("nodes", "cells", "contact_nodes", "node_body", "cell_body")),
                        dofs_per_node=int(f.attrs.get("dofs_per_node", 1)), path=path)

    def table(self, name: str) -> pd.DataFrame:
        """A Parquet entry by name: compactness, generalization, specificity, nested, rom_errors,
        tradeoff (or any `*.parquet` entry, e.g. `train_solver_stats`)."""
        entry = name if name.endswith(".parquet") else f"{name}.parquet"
        return pd.read_parquet(self.file(entry))

    def compactness(self) -> pd.DataFrame:
        return self.table("compactness")

    def generalization(self) -> pd.DataFrame:
        return self.table("generalization")

    def specificity(self) -> pd.DataFrame:
        return self.table("specificity")

    def nested(self) -> pd.DataFrame:
        return self.table("nested")

    def rom_errors(self, timings: bool = True) -> pd.DataFrame:
        """One row per online query (`rom_errors.parquet`); with `timings`, the time columns of
        `rom_timings.parquet` (same rows) beside the results."""
        return self._with_timings("rom_errors", "rom_timings", timings)

    def tradeoff(self, timings: bool = True) -> pd.DataFrame:
        """One row per algorithm, dual basis and rank pair (`tradeoff.parquet`); with `timings`,
        the speed columns of `tradeoff_timings.parquet` (same rows: median online and
        full-order seconds, speed-up) beside the accuracy."""
        return self._with_timings("tradeoff", "tradeoff_timings", timings)

    def comparison(self, table: str = "comparison") -> pd.DataFrame:
        """The dual approximations side by side (scenes with `[comparison]`): `comparison`
        (C, G, T and S curves), `comparison_nested`, `comparison_cells`, `comparison_reached`,
        `comparison_facts`, `comparison_timings`, and after an online run `online_comparison` and
        `online_comparison_timings`. Every table has an `approximation` column, in the scene
        file's order."""
        return self.table(f"comparison/{table}")

    def _with_timings(self, results: str, timings: str, join: bool) -> pd.DataFrame:
        a = self.table(results)
        if not join:
            return a
        b = self.table(timings)
        keys = [c for c in b.columns if c in a.columns]
        if len(a) != len(b) or not a[keys].equals(b[keys]):
            raise CorruptArtifact(f"{self._where(timings + '.parquet')}: its rows do not match {results}.parquet; "
                                  f"{self._rerun()}")
        return pd.concat([a, b.drop(columns=keys)], axis=1)

    def rom(self, u_tol: float | None = None):
        """The study's stored reduced model (`model.h5`), loaded to be solved:
        `rom.solve(d_x=1.2345)`, `rom.solve_many(points)` (see `crom_data.rom`). Needs the native
        extension (`scripts/setup.sh` builds it) and an online run (not `--offline`). `u_tol`: the
        re-pairing's stopping distance, relative, in (0, 1), instead of the model's own
        (`rom.info["u_tol"]`), as `crom query --u-tol`: larger answers sooner."""
        from .rom import open_model
        return open_model(self, u_tol=u_tol)

    @property
    def report_dir(self) -> pathlib.Path:
        """The report directory (`index.html`, figures, tables); online runs only."""
        return self.file("report")

    # --- ParaView views ------------------------------------------------------------------------

    def xdmf(self, name: str = "train") -> pathlib.Path:
        """The XDMF time series of a snapshot set ("train", "test", "nested-k"), a basis
        ("primal_pod", "dual_pod", "dual_cpg") or the online solutions at the test points
        ("online"): open it in ParaView, or read it with
        `meshio.xdmf.TimeSeriesReader`. Checked before it is returned: the views artifact
        against its manifest, and every HDF5 reference of the file it returns (the published
        copy in the scene's directory, which is the one ParaView users open) against the
        dataset it names (it exists, with the dimensions the XDMF states); a malformed or stale
        XDMF raises CorruptArtifact."""
        m = re.fullmatch(r"nested-(\d+)", name)
        if m:
            entry = f"nested/level-{m.group(1)}.xdmf"
        elif name in ("primal_pod", "dual_pod", "dual_cpg"):
            entry = f"basis/{name}.xdmf"
        elif name == "online":
            entry = "online.xdmf"  # online solutions, their errors and the full-order fields
        else:
            entry = f"{name}.xdmf"
        if entry not in self.entries:
            views = sorted(e for e in self.entries if e.endswith(".xdmf"))
            raise self._missing(entry, f"XDMF views: {', '.join(views) or 'none'}")
        self.file(entry)  # the artifact's own copy, against the manifest
        published = self.version_dir / entry
        path = published if published.is_file() else self.store.root / self.entries[entry]["target"]
        _check_xdmf(path, f"{self._where(entry)} ({path})",
                    f"run `crom --store {self.store.root} verify`, then {self._rerun()}")
        return path


def _check_xdmf(path: pathlib.Path, where: str, fix: str) -> None:
    """Every `Format="HDF"` DataItem of the XDMF at `path` names an existing dataset of the
    stated dimensions (relative files resolved against the XDMF's directory as ParaView does)."""
    import xml.etree.ElementTree as ET
    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError) as err:
        raise CorruptArtifact(f"{where}: not a readable XDMF file ({err}); {fix}") from None
    items = [d for d in root.iter("DataItem") if d.get("Format") == "HDF"]
    if root.tag != "Xdmf" or not items:
        raise CorruptArtifact(f"{where}: no XDMF document with HDF5 data items; {fix}")
    files: dict[str, h5py.File] = {}
    try:
        for d in items:
            ref = (d.text or "").strip()
            file, _, dataset = ref.partition(":")
            h5 = pathlib.Path(path.parent, file)  # not resolved: the path as ParaView forms it
            if not h5.is_file():
                raise CorruptArtifact(f"{where}: it refers to {file}, which does not exist; {fix}")
            f = files.get(file) or files.setdefault(file, h5py.File(h5, "r"))
            if dataset not in f:
                raise CorruptArtifact(f"{where}: it refers to {ref}, which is not in {file}; {fix}")
            dims = tuple(int(x) for x in d.get("Dimensions", "").split())
            if f[dataset].shape != dims:
                raise CorruptArtifact(f"{where}: {ref} has shape {f[dataset].shape}, the XDMF says {dims}; {fix}")
    finally:
        for f in files.values():
            f.close()
