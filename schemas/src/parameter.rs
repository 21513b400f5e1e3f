//! The parameter μ of a scene (a scalar, or a vector on a tensor grid) and the point sets drawn
//! from it.

use serde::{Deserialize, Serialize};

/// A scalar parameter range with its training grid.
///
/// Training points: `n_train` equidistant points from `min` to `max` inclusive. Test points: the
/// midpoints between consecutive training points. Nested level `n` (paper Sec. 5.2): `2^n + 1`
/// equidistant points from `min` to `max`, so level `n` is a subset of level `n + 1`.
///
/// **Growing studies.** Snapshots are keyed by parameter value, so a grid reuses every point it
/// shares bit-for-bit with another. `train_level = k` (instead of `n_train`) makes the training
/// set nested level k and the test set the points that level k + 1 adds (the midpoints, computed
/// by the nested levels' own formula so that they are bit-identical): a study grown from k to
/// k + 1 solves only the `2^(k+1)` new test points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParameterSpec {
    /// Name of the parameter (`gamma`, `d`, `d_x`).
    pub name: String,
    /// Physical meaning, for tables and figures.
    pub description: String,
    /// Lower end of the range (inclusive).
    pub min: f64,
    /// Upper end of the range (inclusive).
    pub max: f64,
    /// Number of equidistant training points, both ends included (>= 2). Exactly one of
    /// `n_train` and `train_level` is given.
    #[serde(default)]
    pub n_train: Option<usize>,
    /// Training points as nested level k: `2^k + 1` points (see the type's docs).
    #[serde(default)]
    pub train_level: Option<u32>,
    /// Nested training levels `1..=nested_levels` (0: none).
    #[serde(default)]
    pub nested_levels: u32,
    /// Further axes of a vector parameter `μ = (this, axes[0], …)` (`[[parameter.axes]]` in the
    /// scene file). Every point set is the tensor product of the axes' own grids (training,
    /// test midpoints, nested levels), the first axis varying fastest.
    #[serde(default)]
    pub axes: Vec<AxisSpec>,
    /// Points read from files rather than drawn from grids (an external scene's, filled by the
    /// pipeline when it loads the scene; never in the scene file). When set, the training and
    /// test points are these, and there are no nested levels.
    #[serde(skip)]
    pub explicit: Option<ExplicitPoints>,
}

/// The training and test points of an external scene, one value per component each.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ExplicitPoints {
    /// Training points, in the training set's order.
    pub train: Vec<Vec<f64>>,
    /// Test points, in the test set's order.
    pub test: Vec<Vec<f64>>,
}

/// One further axis of a vector parameter: the same grid rules as the first axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisSpec {
    /// Name of the parameter component (e.g. `d_y`).
    pub name: String,
    /// Physical meaning.
    pub description: String,
    /// Lower end (inclusive).
    pub min: f64,
    /// Upper end (inclusive).
    pub max: f64,
    /// Equidistant training points (exactly one of `n_train`, `train_level`).
    #[serde(default)]
    pub n_train: Option<usize>,
    /// Training points as nested level k (`2^k + 1`).
    #[serde(default)]
    pub train_level: Option<u32>,
}

impl AxisSpec {
    fn grid(&self) -> Grid {
        Grid { min: self.min, max: self.max, n_train: self.n_train, train_level: self.train_level }
    }
}

/// The 1-D grid rules of one axis.
#[derive(Debug, Clone, Copy)]
struct Grid {
    min: f64,
    max: f64,
    n_train: Option<usize>,
    train_level: Option<u32>,
}

impl Grid {
    fn train_count(&self) -> usize {
        match (self.n_train, self.train_level) {
            (_, Some(k)) => (1usize << k) + 1,
            (Some(n), None) => n,
            (None, None) => 0,
        }
    }

    fn nested(&self, level: u32) -> Vec<f64> {
        linspace(self.min, self.max, (1usize << level) + 1)
    }

    fn train(&self) -> Vec<f64> {
        match self.train_level {
            Some(k) => self.nested(k),
            None => linspace(self.min, self.max, self.train_count()),
        }
    }

    fn test(&self) -> Vec<f64> {
        match self.train_level {
            Some(k) => self.nested(k + 1).into_iter().skip(1).step_by(2).collect(),
            None => self.train().windows(2).map(|w| 0.5 * (w[0] + w[1])).collect(),
        }
    }
}

/// Tensor product of 1-D grids, the first varying fastest; each point has one value per grid.
pub fn tensor(grids: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let n: Vec<usize> = grids.iter().map(Vec::len).collect();
    let total: usize = n.iter().product();
    (0..total)
        .map(|idx| {
            let mut rest = idx;
            grids
                .iter()
                .zip(&n)
                .map(|(g, len)| {
                    let x = g[rest % len];
                    rest /= len;
                    x
                })
                .collect()
        })
        .collect()
}

/// `n` equidistant points from `a` to `b` inclusive (exact ends).
pub fn linspace(a: f64, b: f64, n: usize) -> Vec<f64> {
    match n {
        0 => Vec::new(),
        1 => vec![a],
        _ => (0..n).map(|i| if i == n - 1 { b } else { a + (b - a) * i as f64 / (n - 1) as f64 }).collect(),
    }
}

impl ParameterSpec {
    fn grid(&self) -> Grid {
        Grid { min: self.min, max: self.max, n_train: self.n_train, train_level: self.train_level }
    }

    fn grids(&self) -> Vec<Grid> {
        std::iter::once(self.grid()).chain(self.axes.iter().map(AxisSpec::grid)).collect()
    }

    /// Number of parameter components (1 for a scalar parameter).
    pub fn dim(&self) -> usize {
        1 + self.axes.len()
    }

    /// Names of the components, in order.
    pub fn names(&self) -> Vec<&str> {
        std::iter::once(self.name.as_str()).chain(self.axes.iter().map(|a| a.name.as_str())).collect()
    }

    /// Number of training points along the first axis (explicit points: all of them).
    pub fn train_count(&self) -> usize {
        match &self.explicit {
            Some(e) => e.train.len(),
            None => self.grid().train_count(),
        }
    }

    /// Training points of every axis (tensor grid), or the explicit ones.
    pub fn train_points(&self) -> Vec<Vec<f64>> {
        match &self.explicit {
            Some(e) => e.train.clone(),
            None => tensor(&self.grids().iter().map(Grid::train).collect::<Vec<_>>()),
        }
    }

    /// Test points: the tensor grid of every axis' midpoints, or the explicit ones.
    pub fn test_points(&self) -> Vec<Vec<f64>> {
        match &self.explicit {
            Some(e) => e.test.clone(),
            None => tensor(&self.grids().iter().map(Grid::test).collect::<Vec<_>>()),
        }
    }

    /// Nested level `level` of every axis (tensor grid of `2^level + 1` points per axis; none
    /// for explicit points).
    pub fn nested_points(&self, level: u32) -> Vec<Vec<f64>> {
        if self.explicit.is_some() {
            return Vec::new();
        }
        tensor(&self.grids().iter().map(|g| g.nested(level)).collect::<Vec<_>>())
    }

    /// The training points of the first axis.
    pub fn train(&self) -> Vec<f64> {
        match &self.explicit {
            Some(e) => e.train.iter().map(|p| p[0]).collect(),
            None => self.grid().train(),
        }
    }

    /// The test points of the first axis: midpoints of consecutive training points (with
    /// `train_level = k`, the odd points of level k + 1, the same values bit for bit).
    pub fn test(&self) -> Vec<f64> {
        match &self.explicit {
            Some(e) => e.test.iter().map(|p| p[0]).collect(),
            None => self.grid().test(),
        }
    }

    /// The points of nested level `level` of the first axis (`2^level + 1` points).
    pub fn nested(&self, level: u32) -> Vec<f64> {
        if self.explicit.is_some() {
            return Vec::new();
        }
        self.grid().nested(level)
    }

    /// The stand-in of an external scene, which has no `[parameter]` table (its names and
    /// points come from its files): empty name, no grid. A native scene without `[parameter]`
    /// is refused by validation ([`Self::is_unset`]).
    pub fn unset() -> Self {
        ParameterSpec {
            name: String::new(),
            description: String::new(),
            min: 0.0,
            max: 0.0,
            n_train: None,
            train_level: None,
            nested_levels: 0,
            axes: Vec::new(),
            explicit: None,
        }
    }

    /// Whether this is [`Self::unset`] (the scene file has no `[parameter]`).
    pub fn is_unset(&self) -> bool {
        let u = Self::unset();
        self.name == u.name
            && self.description == u.description
            && self.min.to_bits() == u.min.to_bits()
            && self.max.to_bits() == u.max.to_bits()
            && self.n_train.is_none()
            && self.train_level.is_none()
            && self.nested_levels == 0
            && self.axes.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(n: usize) -> ParameterSpec {
        ParameterSpec {
            name: "g".into(),
            description: String::new(),
            min: -0.5,
            max: 0.5,
            n_train: Some(n),
            train_level: None,
            nested_levels: 3,
            axes: Vec::new(),
            explicit: None,
        }
    }

    #[test]
    fn a_second_axis_makes_tensor_grids_with_the_first_axis_fastest() {
        let mut s = spec(3);
        s.axes.push(AxisSpec {
            name: "h".into(),
            description: String::new(),
            min: 1.0,
            max: 2.0,
            n_train: None,
            train_level: Some(1),
        });
        assert_eq!((s.dim(), s.names()), (2, vec!["g", "h"]));
        let t = s.train_points();
        assert_eq!(t.len(), 3 * 3);
        // Exact grid values: -0.5, 0, 0.5 (first axis) and 1, 1.5, 2 (level 1 of [1, 2]).
        let first: Vec<[f64; 2]> = t.iter().take(4).map(|p| [p[0], p[1]]).collect();
        let want: [[f64; 2]; 4] = [[-0.5, 1.0], [0.0, 1.0], [0.5, 1.0], [-0.5, 1.5]];
        for (a, b) in first.iter().zip(want) {
            assert!(a[0].to_bits() == b[0].to_bits() && a[1].to_bits() == b[1].to_bits(), "{a:?} vs {b:?}");
        }
        // Test points: 2 midpoints on the first axis times the 2 level-2 odd points of the second.
        let m = s.test_points();
        assert_eq!(m.len(), 4);
        assert!(m.iter().all(|p| p.len() == 2));
        assert_eq!(s.nested_points(2).len(), 25);
    }

    #[test]
    fn train_includes_both_ends_and_test_are_midpoints() {
        let s = spec(10);
        let t = s.train();
        assert_eq!(t.len(), 10);
        assert_eq!(t[0].to_bits(), (-0.5f64).to_bits());
        assert_eq!(t[9].to_bits(), 0.5f64.to_bits());
        let m = s.test();
        assert_eq!(m.len(), 9);
        // Midpoint of the first interval: -0.5 + 1/18 (spacing 1/9), to rounding (1e-15).
        assert!((m[0] - (-0.5 + 1.0 / 18.0)).abs() < 1e-15);
    }

    #[test]
    fn a_level_study_grown_by_one_level_reuses_every_point() {
        let at = |k| ParameterSpec { n_train: None, train_level: Some(k), ..spec(0) };
        for k in 1..8 {
            let (lo, hi) = (at(k), at(k + 1));
            assert_eq!(lo.train().len(), (1 << k) + 1);
            assert_eq!(lo.test().len(), 1 << k);
            // Level k's train and test points together are level k + 1's training points,
            // bit for bit (so their snapshot keys coincide).
            let mut old: Vec<u64> = lo.train().iter().chain(&lo.test()).map(|x| x.to_bits()).collect();
            let mut new: Vec<u64> = hi.train().iter().map(|x| x.to_bits()).collect();
            old.sort_unstable();
            new.sort_unstable();
            assert_eq!(old, new, "level {k}");
            // And the test points are the midpoints (to rounding of one addition: 1e-15).
            for (m, w) in lo.test().iter().zip(lo.train().windows(2)) {
                assert!((m - 0.5 * (w[0] + w[1])).abs() <= 1e-15, "{m} vs {w:?}");
            }
        }
    }

    #[test]
    fn nested_levels_are_subsets() {
        let s = spec(10);
        for level in 1..3 {
            let lo = s.nested(level);
            let hi = s.nested(level + 1);
            assert_eq!(hi.len(), 2 * lo.len() - 1);
            for (i, x) in lo.iter().enumerate() {
                // Bit-identical, not merely close: (b-a)*2i/(2(n-1)) rounds exactly like
                // (b-a)*i/(n-1) (scaling by 2 is exact), so snapshot cache keys coincide.
                assert_eq!(hi[2 * i].to_bits(), x.to_bits(), "level {level} point {i}");
            }
        }
    }
}
