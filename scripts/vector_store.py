"""What the vector-parameter scripts (vector_map_floor.py, vector_level_pod.py,
vector_neighbours.py) read from a finished `crom run` of a vector-parameter scene, with NumPy
and h5py only: the published training and test pressures and points, the contact nodes'
abscissae and lines (model.h5's `reg_surface` and, on a contact area, `reg_across`), the lines'
tributary weights, and each pressure's moments along x by crom's rule (centre, and twice the
standard deviation with each node's own spread).
"""
import h5py
import numpy as np


def tributary(xl):
    """Tributary lengths of the nodes at abscissae `xl` (increasing) along one line."""
    w = np.empty(len(xl))
    w[1:-1], w[0], w[-1] = 0.5 * (xl[2:] - xl[:-2]), 0.5 * (xl[1] - xl[0]), 0.5 * (xl[-1] - xl[-2])
    return w


class VectorStore:
    """A finished study's published sets of `scene` in `store` (see the module doc)."""

    def __init__(self, scene, store):
        d = f"{store}/scenes/{scene}"
        train, test, model = h5py.File(f"{d}/train.h5"), h5py.File(f"{d}/test.h5"), h5py.File(f"{d}/model.h5")
        self.dir, self.model = d, model
        self.S, self.P = train["dual"][:], train["parameters"][:]
        self.T, self.Q = test["dual"][:], test["parameters"][:]
        self.x = model["reg_surface"][:]
        y = model["reg_across"][:] if "reg_across" in model else np.zeros_like(self.x)
        # the lines of equal coordinate across the travel, each by increasing x (a curve is one line)
        lines = [np.flatnonzero(np.isclose(y, v, rtol=0, atol=1e-9 * max(np.ptp(y), 1.0))) for v in np.unique(y)]
        self.lines = [line[np.argsort(self.x[line], kind="stable")] for line in lines]
        self.W = [tributary(self.x[line]) for line in self.lines]
        self.has = self.S.sum(axis=0) > 0

    def moments(self, s):
        """(c, a): centre and twice the standard deviation along x, over every line (crom's rule)."""
        x, lines, W = self.x, self.lines, self.W
        m0 = sum((w * s[line]).sum() for line, w in zip(lines, W))
        c = sum((w * s[line] * x[line]).sum() for line, w in zip(lines, W)) / m0
        var = sum((w * s[line] * ((x[line] - c) ** 2 + w * w / 12)).sum() for line, w in zip(lines, W)) / m0
        return np.array([c, 2 * np.sqrt(var)])
