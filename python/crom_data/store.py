"""The store: its catalog and its published scenes.

A scene is published by each successful `crom run SCENE` as `STORE/scenes/<scene>`, a relative
symbolic link to `STORE/scenes/.versions/<scene>@<stamp>/` (the link is swapped atomically, so
resolving it once gives one consistent study). The reader resolves the link, reads `study.json`
in it, and from then on uses only the `target` paths of `study.json` (relative to the store
root), never the per-file links: a copy of the store that lost its symbolic links still reads.
If the `scenes/<scene>` link itself is missing, the newest version directory whose `study.json`
names the scene is used.
"""
from __future__ import annotations

import json
import os
import pathlib

import pandas as pd

from .errors import ArtifactMissing, SceneNotFound, StoreNotFound
from .scene import Scene

CATALOG = "catalog.parquet"
SCENES = "scenes"
VERSIONS = ".versions"
STUDY = "study.json"
# Any of these at the root makes a directory a crom store.
MARKERS = (CATALOG, SCENES, "columns")


def open_store(path: str | os.PathLike | None = None) -> "Store":
    """Open the crom store at `path` (default: `$CROM_STORE`, else `data/store`, as the CLI).

    Raises StoreNotFound if the directory does not exist or is not a crom store."""
    root = pathlib.Path(path if path is not None else os.environ.get("CROM_STORE", "data/store"))
    if not root.is_dir():
        raise StoreNotFound(f"store {root}: no such directory; create it with `crom --store {root} run SCENE` "
                            "or pass the path of an existing store (CROM_STORE)")
    if not any((root / m).exists() for m in MARKERS):
        raise StoreNotFound(f"store {root}: not a crom store (it has none of {', '.join(MARKERS)}); "
                            f"create one with `crom --store {root} run SCENE`")
    return Store(root)


class Store:
    """A crom artifact store (see `open_store`)."""

    def __init__(self, root: pathlib.Path):
        self.root = pathlib.Path(root)

    def __repr__(self) -> str:
        return f"Store({str(self.root)!r}, scenes={self.scenes()})"

    def catalog(self) -> pd.DataFrame:
        """`catalog.parquet`: one row per artifact and snapshot column family (stage, scene, set,
        bases, key, inputs, schema_version, ..., path relative to the store, published)."""
        path = self.root / CATALOG
        if not path.is_file():
            raise ArtifactMissing(f"store {self.root}: no {CATALOG} (written by an older crom, or a killed run); "
                                  f"rebuild it with `crom --store {self.root} catalog`")
        return pd.read_parquet(path)

    def scenes(self) -> list[str]:
        """Names of the published scenes, sorted."""
        return sorted(self._published())

    def scene(self, name: str) -> Scene:
        """The latest published study of scene `name`."""
        version = self._published().get(name)
        if version is None:
            known = ", ".join(self.scenes()) or "none"
            raise SceneNotFound(f"store {self.root}: scene {name!r} is not published (published scenes: {known}); "
                                f"run `crom --store {self.root} run {name}` to compute and publish it")
        return Scene(self, name, version, json.loads((version / STUDY).read_text()))

    def _published(self) -> dict[str, pathlib.Path]:
        """Scene name -> its current version directory."""
        scenes = self.root / SCENES
        found: dict[str, tuple] = {}
        # Fallback for copies without symbolic links: the newest version naming each scene.
        for d in (scenes / VERSIONS).glob("*") if (scenes / VERSIONS).is_dir() else []:
            try:
                study = json.loads((d / STUDY).read_text())
            except (OSError, ValueError):
                continue  # a leftover of a killed publish, or not a version at all
            if d.name.startswith(".") or not isinstance(study, dict) or "scene" not in study:
                continue
            rank = (study.get("created_unix", 0), d.name, d)
            if study["scene"] not in found or rank > found[study["scene"]]:
                found[study["scene"]] = rank
        out = {name: rank[2] for name, rank in found.items()}
        for link in scenes.glob("*") if scenes.is_dir() else []:
            if not link.name.startswith(".") and (link / STUDY).is_file():
                out[link.name] = link.resolve()  # resolved once: one consistent version
        return out
