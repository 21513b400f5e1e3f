"""Typed errors of the reader. Every message names the store, the scene and the entry (set,
table, ...) concerned, what is wrong, and the command that fixes it."""


class CromDataError(Exception):
    """Base class of every error raised by crom_data."""


class StoreNotFound(CromDataError):
    """The store directory is missing, or holds no crom store."""


class SceneNotFound(CromDataError):
    """No published study of that scene in the store (`crom run SCENE` publishes one)."""


class ArtifactMissing(CromDataError):
    """The study has no such entry (a scene without nested levels, an --offline run, an entry
    withdrawn by `crom verify`), or the entry's artifact directory is gone."""


class SchemaTooNew(CromDataError):
    """The artifact or study.json was written by a newer crom than this reader knows."""


class StaleArtifact(CromDataError):
    """The artifact's layout is older than this reader supports."""


class CorruptArtifact(CromDataError):
    """The artifact does not match its manifest (file not listed, size or blake3 differs,
    manifest missing or naming another artifact)."""


class InvalidPoint(CromDataError, ValueError):
    """A point given to a reduced model (`ReducedModel.solve`, `solve_many`) is malformed: a
    missing or extra component, a value that is not a finite number, an array of the wrong shape."""


class OutsideDomain(InvalidPoint):
    """A component of a point lies outside the model's training domain (and
    `allow_extrapolation=True` was not given)."""


class InvalidSetting(CromDataError, ValueError):
    """A setting given to open a reduced model is out of range (`Scene.rom(u_tol=...)` outside
    (0, 1))."""


class NativeMissing(CromDataError, ImportError):
    """The native extension `crom_native` that solves reduced models is not installed."""
