"""The stored reduced model of a scene, solved from Python.

    rom = crom_data.open_store("data/store").scene("ironing-fine").rom()
    r = rom.solve(d_x=1.2345)
    r.pressure, r.coefficients, r.indicator, r.converged, r.outcome, r.iterations
    r.displacement                    # n_dof, reconstructed on first access
    b = rom.solve_many(points)        # points: (n, p) array, columns in rom.names order
    b.pressure                        # (n, n_contact); b.indicator, b.converged, ... (n,)

`Scene.rom()` opens the `model` artifact the published study names (`model.h5`; its manifest
and schema version checked as for every entry) with the native extension `crom_native`: the
cdylib of `python/native`, which `just build` (and so `just run` and `just test`) compiles with
the rest of the workspace and puts beside this file as `crom_native.abi3.so`; a `crom_native`
installed on its own (a wheel built with maturin) is used when that file is absent. Solving is the Rust code of
`crom query`: the exact online solve with the settings stored with the model, then the
a-posteriori indicator and the pressure `Theta λ̂` — so an answer here is the query's (and the
pipeline's online stage's) at the same point, bit for bit. The GIL is released while solving;
`solve_many` solves its points in parallel on rayon's global pool (as `crom`: one thread per
core, or `RAYON_NUM_THREADS`) or on a pool of `threads`.

Points are refused before anything is solved, with an exception of `crom_data.errors`:
`InvalidPoint` for a missing or extra component, a value that is not a finite number or an
array of the wrong shape; `OutsideDomain` (a subclass) for a component outside the training
domain `[min, max]`, unless `allow_extrapolation=True` (then the answer's `extrapolated` is
True). A point that is solved but does not converge is answered with its outcome
(`converged` False); its values are not an answer.

Orientation: `pressure[i]` is the pressure at contact node `mesh.contact_nodes[i]` (the order
of a training set's dual rows); `displacement[k]` is dof `dofs_per_node * node + component`
(the order of the primal rows); `coefficients` are the primal coefficients û (the displacement
is `lift(μ) + Φ û`), `dual_coefficients` the pressure's λ̂ (`pressure = Θ λ̂`).
"""
from __future__ import annotations

import functools
import numbers
import os

import numpy as np

from .errors import InvalidPoint, InvalidSetting, NativeMissing

try:  # the native part; its absence is reported when a model is opened
    from . import crom_native as _native  # the checkout's build, put here by `just build`
except ImportError:
    try:
        import crom_native as _native  # a wheel installed on its own
    except ImportError as _err:  # pragma: no cover - depends on the environment
        _native, _native_error = None, _err
    else:
        _native_error = None
else:
    _native_error = None


def _require_native():
    if _native is None:
        raise NativeMissing(f"the native extension crom_native is not installed ({_native_error}); run "
                            "`just build` in the crom checkout (it compiles the extension and puts it beside "
                            "crom_data), or `pip install ./python/native` (a wheel, built with maturin)")
    return _native


class Result:
    """The answer at one point (see the module doc). Arrays are read-only NumPy views of the
    bytes the solve returned; `displacement` is reconstructed on first access."""

    __slots__ = ("_rom", "_kw", "_t", "_displacement")

    def __init__(self, rom: "ReducedModel", kw: dict, t: tuple):
        self._rom, self._kw, self._t, self._displacement = rom, kw, t, None

    @property
    def point(self) -> list:
        """The point's components, in `rom.names` order."""
        return [self._kw[n] for n in self._rom.names]

    def __repr__(self) -> str:
        at = ", ".join(f"{n}={v!r}" for n, v in zip(self._rom.names, self.point))
        return (f"Result({at}: {self.outcome}, {self.iterations} iterations, indicator {self.indicator:.3e}"
                f"{', extrapolated' if self.extrapolated else ''})")

    @property
    def pressure(self) -> np.ndarray:
        """Pressure at each contact node (n_contact)."""
        return np.frombuffer(self._t[0])

    @property
    def coefficients(self) -> np.ndarray:
        """Primal coefficients û (r_primal)."""
        return np.frombuffer(self._t[1])

    @property
    def dual_coefficients(self) -> np.ndarray:
        """Dual coefficients λ̂ (r_dual): pressure = Θ λ̂. With a registered dual basis
        (`info["dual_basis"]` names it) Θ = Θ(μ) is rebuilt at each point and λ̂ has one
        coefficient per generator used there (at most r_dual; `solve_many` pads with zeros)."""
        return np.frombuffer(self._t[2])

    @property
    def outcome(self) -> str:
        """`converged`, `infeasible`, `cycled` or `not_converged`."""
        return self._t[3]

    @property
    def converged(self) -> bool:
        return self._t[3] == "converged"

    @property
    def iterations(self) -> int:
        return self._t[4]

    @property
    def linearizations(self) -> int:
        return self._t[5]

    @property
    def nonzero_dual(self) -> int:
        """Dual coefficients above 1e-9 of the largest."""
        return self._t[6]

    @property
    def indicator(self) -> float:
        """The a-posteriori indicator: the relative equilibrium residual in the energy norm
        (`crom query`'s `indicator` column)."""
        return self._t[7]

    @property
    def indicator_terms(self) -> dict:
        """The indicator's other terms: penetration, complementarity, unpaired_force."""
        return {"penetration": self._t[8], "complementarity": self._t[9], "unpaired_force": self._t[10]}

    @property
    def extrapolated(self) -> bool:
        """True when a component lies outside the training domain (allow_extrapolation=True)."""
        return self._t[11]

    @property
    def seconds(self) -> float:
        """Time of the online solve in Rust (the query's `online_seconds`)."""
        return self._t[12]

    @property
    def indicator_seconds(self) -> float:
        return self._t[13]

    @property
    def answer_seconds(self) -> float:
        """Time of the whole Rust answer (solve, indicator and pressure): what a call costs
        without the binding."""
        return self._t[14]

    @property
    def displacement(self) -> np.ndarray:
        """Displacement on every dof (n_dof): `lift(μ) + Φ û` from `reconstruction.h5`."""
        if self._displacement is None:
            self._displacement = np.frombuffer(self._rom._native.displacement(self.point, self._t[1]))
        return self._displacement


class Batch:
    """The answers at n points (`ReducedModel.solve_many`): one row per point, in input order."""

    def __init__(self, rom: "ReducedModel", points: np.ndarray, t: tuple):
        n, (ru, rl), nc = len(points), rom.ranks, rom.n_contact
        f = lambda b, *shape: np.frombuffer(b).reshape(shape)  # noqa: E731
        u = lambda b: np.frombuffer(b, dtype=np.uint64).astype(np.int64)  # noqa: E731
        self._rom = rom
        self.points = points
        self.pressure = f(t[0], n, nc)
        self.coefficients = f(t[1], n, ru)
        self.dual_coefficients = f(t[2], n, rl)
        codes = np.frombuffer(t[3], dtype=np.uint8)
        self.outcome = np.asarray(_native.OUTCOMES, dtype=object)[codes] if n else np.array([], dtype=object)
        self.converged = codes == _native.OUTCOMES.index("converged")
        self.iterations, self.linearizations, self.nonzero_dual = u(t[4]), u(t[5]), u(t[6])
        self.indicator = f(t[7], n)
        self.penetration, self.complementarity, self.unpaired_force = f(t[8], n), f(t[9], n), f(t[10], n)
        self.extrapolated = np.frombuffer(t[11], dtype=np.uint8).astype(bool)
        self.seconds, self.indicator_seconds = f(t[12], n), f(t[13], n)

    def __len__(self) -> int:
        return len(self.points)

    def __repr__(self) -> str:
        return (f"Batch({len(self)} points, {int(self.converged.sum())} converged, "
                f"{int(self.extrapolated.sum())} extrapolated)")

    def displacement(self, j: int) -> np.ndarray:
        """Displacement on every dof (n_dof) of point j."""
        return np.frombuffer(self._rom._native.displacement(self.points[j].tolist(), self.coefficients[j].tobytes()))

    def to_frame(self):
        """One row per point: the components, outcome, iterations, indicator terms, extrapolated,
        seconds (the pressure and the coefficients stay arrays)."""
        import pandas as pd
        cols = {n: self.points[:, c] for c, n in enumerate(self._rom.names)}
        cols.update(outcome=self.outcome, converged=self.converged, iterations=self.iterations,
                    linearizations=self.linearizations, indicator=self.indicator, penetration=self.penetration,
                    complementarity=self.complementarity, unpaired_force=self.unpaired_force,
                    extrapolated=self.extrapolated, online_seconds=self.seconds,
                    indicator_seconds=self.indicator_seconds)
        return pd.DataFrame(cols)


class ReducedModel:
    """A scene's stored reduced model (see `Scene.rom` and the module doc)."""

    def __init__(self, scene, directory: os.PathLike, native):
        self.scene, self.directory, self._native = scene, directory, native
        self.names: list[str] = native.names
        self.domain: dict[str, tuple[float, float]] = {n: (a, b) for n, a, b in zip(native.names, native.min,
                                                                                     native.max)}
        self.ranks: tuple[int, int] = native.ranks
        self.n_contact: int = native.n_contact
        self.info: dict = native.info()
        # the re-pairing's stopping distance of the solves (`info["u_tol"]` unless opened with one)
        self.u_tol: float = native.u_tol
        self._set = frozenset(self.names)

    def __repr__(self) -> str:
        dom = ", ".join(f"{n} in [{a}, {b}]" for n, (a, b) in self.domain.items())
        return (f"ReducedModel({self.scene.name!r}, ranks={self.ranks}, {dom}, algorithm={self.info['algorithm']!r}, "
                f"dual_basis={self.info['dual_basis']!r})")

    @functools.cached_property
    def weights(self) -> np.ndarray:
        """Tributary weight of each contact node (the contact force is `weights @ pressure`)."""
        return np.frombuffer(self._native.weights())

    def _components(self, given) -> InvalidPoint:
        missing = [n for n in self.names if n not in given]
        extra = [n for n in given if n not in self._set]
        what = "; ".join(filter(None, [f"no value for {', '.join(missing)}" if missing else "",
                                       f"the model has no parameter {', '.join(map(repr, extra))}" if extra else ""]))
        example = ", ".join(f"{n}={(a + b) / 2!r}" for n, (a, b) in self.domain.items())
        dom = ", ".join(f"{n} in [{a}, {b}]" for n, (a, b) in self.domain.items())
        return InvalidPoint(f"scene {self.scene.name!r}: {what} (its parameters: {dom}); give every component once "
                            f"by name, e.g. rom.solve({example})")

    def solve(self, allow_extrapolation: bool = False, **point) -> Result:
        """Solve at one point given by name, e.g. `rom.solve(d_x=1.2345)`."""
        # the native call checks that every component is given once by name (None if not): one
        # crossing of the boundary per call, which the hot loop of an optimisation pays
        t = self._native.solve(point, allow_extrapolation)
        if t is None:
            raise self._components(point)
        return Result(self, point, t)

    def solve_many(self, points, allow_extrapolation: bool = False, threads: int | None = None) -> Batch:
        """Solve at every row of `points`, an (n, p) array of the components in `self.names`
        order (an (n,) array for a one-component parameter), in parallel with the GIL released:
        on rayon's global pool, or on a pool of `threads` threads."""
        p = len(self.names)
        try:
            a = np.asarray(points, dtype=np.float64)
        except (TypeError, ValueError) as err:
            raise InvalidPoint(f"scene {self.scene.name!r}: points are not an array of numbers ({err}); pass an "
                               f"(n, {p}) float array, columns {', '.join(self.names)}") from None
        if a.ndim == 1 and p == 1:
            a = a[:, None]
        if a.ndim != 2 or a.shape[1] != p:
            raise InvalidPoint(f"scene {self.scene.name!r}: points of shape {a.shape}, the model has {p} "
                               f"component{'s' if p != 1 else ''} ({', '.join(self.names)}); pass an (n, {p}) array, "
                               "one row per point, columns in rom.names order")
        if threads is not None and (not isinstance(threads, int) or threads < 1):
            raise InvalidPoint(f"threads={threads!r}: give a positive number of threads, or None for rayon's pool")
        a = np.ascontiguousarray(a)
        return Batch(self, a, self._native.solve_many(a.tobytes(), len(a), allow_extrapolation, threads))


def open_model(scene, entry: str = "model.h5", u_tol: float | None = None) -> ReducedModel:
    """The model of a published study (used by `Scene.rom`): the entry is verified against its
    manifest (schema version included) before the native code loads and verifies it again.
    `u_tol`: the re-pairing's stopping distance instead of the model's."""
    if u_tol is not None and (isinstance(u_tol, bool) or not isinstance(u_tol, numbers.Real)
                              or not 0.0 < u_tol < 1.0):
        raise InvalidSetting(f"scene {scene.name!r}: u_tol={u_tol!r} is not a tolerance in (0, 1); give the "
                             "re-pairing's relative stopping distance, e.g. u_tol=1e-6, or None for the model's own")
    native = _require_native()
    path = scene.file(entry)
    e = scene.entries[entry]
    fix = (f"run `crom --store {scene.store.root} verify` (it quarantines a damaged artifact), then "
           f"`crom --store {scene.store.root} run {scene.name}`")
    return ReducedModel(scene, path.parent, native.Model.open(str(scene.store.root), str(e["key"]), fix,
                                                              None if u_tol is None else float(u_tol)))
