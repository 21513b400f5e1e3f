//! A fitted registered basis as plain arrays ([`RegisteredArrays`]): what a stored reduced model
//! keeps of it, and the basis rebuilt from them ([`Registered::from_arrays`]) with the same bits
//! in every value the push-forward reads, so the rebuilt basis gives the same `Θ(μ)` at every
//! parameter point as the one it was taken from.
//!
//! Kept: the map's kind (and reference refinement), the contact surface's abscissae in
//! dual-entry order (the node order and tributary widths are derived from them by the code that
//! derived them at the fit), the moments map's table `(μ_j, c_j, a_j)` (over several
//! parameter components, `(μ_j1, …, μ_jd, c_j, a_j)` in the fit's order: the level-by-level
//! interpolation reads the rows in that order), the reference grid
//! (start, step, length) and the reference generators (`len x k`, column-major); for a
//! neighbours basis also each column's travel and the weight of the order. The offline
//! round-trip errors are facts of the build and are not kept.

use faer::Mat;

use super::{Inner, Interpolation, Map, MapKind, Neighbours, Registered, Surface};
use crate::dual::DualError;

/// A registered CPG or neighbours basis as arrays (see the module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct RegisteredArrays {
    /// The map.
    pub kind: MapKind,
    /// Abscissa of each contact node in the reference configuration, dual-entry order.
    pub surface: Vec<f64>,
    /// Coordinate across the travel of each contact node (a 3-D contact area: y), dual-entry
    /// order; empty for a contact curve.
    pub across: Vec<f64>,
    /// Moments map: `(μ_j, c_j, a_j)` of the training snapshots with contact, sorted by μ,
    /// flattened (`3 · count`); over a parameter of [`Self::dims`] components, the rows
    /// `(μ_j1, …, μ_jd, c_j, a_j)` in the training points' order (`(d + 2) · count`); empty
    /// for a translation.
    pub table: Vec<f64>,
    /// Components of the moments map's parameter points (1 for a translation).
    pub dims: usize,
    /// Reference grid: `[start, step]` (whole-node shifts: `[largest training shift, h]`).
    pub grid: [f64; 2],
    /// Reference grid length.
    pub len: usize,
    /// Reference generators, `len x generators`, column-major.
    pub modes: Vec<f64>,
    /// Number of generators.
    pub generators: usize,
    /// Neighbours: the travel of each generator (its training snapshot's); empty for CPG.
    pub travels: Vec<f64>,
    /// Neighbours: the weight `w` of the order (0 for CPG).
    pub weight: f64,
    /// Neighbours over a vector parameter: the second component of each generator's training
    /// point; empty otherwise.
    pub seconds: Vec<f64>,
    /// Neighbours over a vector parameter: the scale `s` of the second component's distances
    /// (0 otherwise).
    pub second_scale: f64,
}

/// A refused array: what is wrong.
fn bad(what: String) -> DualError {
    DualError::NotApplicable(format!("stored registered basis: {what}"))
}

impl Registered {
    /// The basis as arrays; `None` for a registered POD (only non-negative generators make a
    /// dual basis of the online solve).
    pub fn arrays(&self) -> Option<RegisteredArrays> {
        // a registered POD has no online solve
        if matches!(self.inner, Inner::Pod | Inner::LevelPod) {
            return None;
        }
        let m = &self.map;
        let (len, k) = (self.modes.nrows(), self.modes.ncols());
        // the surface's abscissae back in dual-entry order
        let mut surface = vec![0.0; m.surface.x.len()];
        for (x, &i) in m.surface.x.iter().zip(&m.surface.order) {
            surface[i] = *x;
        }
        Some(RegisteredArrays {
            kind: m.kind,
            surface,
            across: m.across.clone(),
            table: if m.points.is_empty() {
                m.table.iter().flat_map(|&(t, c, a)| [t, c, a]).collect()
            } else {
                m.points.iter().flat_map(|(mu, c, a)| mu.iter().copied().chain([*c, *a])).collect()
            },
            dims: m.points.first().map_or(1, |p| p.0.len()),
            grid: [m.grid_start, m.grid_step],
            len,
            modes: (0..k).flat_map(|j| self.modes.col(j).iter().copied().collect::<Vec<_>>()).collect(),
            generators: k,
            travels: self.neighbours().map(|nb| nb.centres().to_vec()).unwrap_or_default(),
            weight: self.neighbours().map_or(0.0, |nb| nb.weight()),
            seconds: self.neighbours().and_then(|nb| nb.second()).map(|s| s.values.clone()).unwrap_or_default(),
            second_scale: self.neighbours().and_then(|nb| nb.second()).map_or(0.0, |s| s.scale),
        })
    }

    /// The registered CPG basis stored as `a`; every length and value the push-forward relies
    /// on is checked, so damaged arrays are refused ([`DualError::NotApplicable`], saying
    /// which) instead of making a basis that panics in a query.
    pub fn from_arrays(a: &RegisteredArrays) -> Result<Self, DualError> {
        let n = a.surface.len();
        if n == 0 || a.surface.iter().any(|x| !x.is_finite()) {
            return Err(bad(format!("{n} surface abscissae, not all finite or none")));
        }
        if a.len == 0 || a.len > 1 << 32 {
            return Err(bad(format!("reference grid of {} points", a.len)));
        }
        if a.modes.len() != a.len * a.generators || a.modes.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!(
                "{} generator values for {} generators of {} points, or a non-finite one",
                a.modes.len(),
                a.generators,
                a.len
            )));
        }
        let [start, step] = a.grid;
        if !(start.is_finite() && step.is_finite() && step > 0.0) {
            return Err(bad(format!("reference grid start {start}, step {step}")));
        }
        if a.dims == 0 || a.dims > 64 {
            return Err(bad(format!("{} parameter components of the moments table", a.dims)));
        }
        // rows of `dims` components, then c and a
        let row = a.dims + 2;
        let rows = || a.table.chunks(row);
        let (mut table, mut points) = (Vec::new(), Vec::new());
        match a.kind {
            MapKind::Moments { .. } => {
                if a.table.is_empty()
                    || !a.table.len().is_multiple_of(row)
                    || a.table.iter().any(|v| !v.is_finite())
                    || rows().any(|r| r[row - 1] <= 0.0)
                {
                    return Err(bad(format!(
                        "the moments table is not rows of {} parameter components, c and a > 0",
                        a.dims
                    )));
                }
                if a.dims == 1 {
                    table = rows().map(|r| (r[0], r[1], r[2])).collect();
                    if table.windows(2).any(|p| p[0].0 > p[1].0) {
                        return Err(bad("the moments table is not sorted by mu".into()));
                    }
                } else {
                    points = rows().map(|r| (r[..a.dims].to_vec(), r[a.dims], r[a.dims + 1])).collect();
                }
            }
            MapKind::Translate { interpolation } => {
                if !a.table.is_empty() || a.dims != 1 {
                    return Err(bad("a translation has no moments table".into()));
                }
                if interpolation == Interpolation::Nodes && (start.fract() != 0.0 || start.abs() > (1u64 << 52) as f64)
                {
                    return Err(bad(format!("whole-node shifts with a fractional grid start {start}")));
                }
            }
        }
        if !a.across.is_empty() && (a.across.len() != n || a.across.iter().any(|y| !y.is_finite())) {
            return Err(bad(format!(
                "{} coordinates across the travel for {n} surface nodes, or a non-finite one",
                a.across.len()
            )));
        }
        let surface = Surface::new(&a.surface, &a.across);
        if !a.len.is_multiple_of(surface.lines()) {
            return Err(bad(format!(
                "reference grid of {} points for {} lines of the surface",
                a.len,
                surface.lines()
            )));
        }
        let line_len = a.len / surface.lines();
        let map = Map {
            kind: a.kind,
            surface,
            table,
            points,
            grid_start: start,
            grid_step: step,
            len: a.len,
            line_len,
            across: a.across.clone(),
        };
        let modes = Mat::from_fn(a.len, a.generators, |i, j| a.modes[i + j * a.len]);
        let neighbours = if a.travels.is_empty() {
            None
        } else {
            if a.kind != (MapKind::Translate { interpolation: Interpolation::Nodes }) {
                return Err(bad("a neighbours basis needs whole-node shifts".into()));
            }
            if a.travels.len() != a.generators || a.travels.iter().any(|t| !t.is_finite()) {
                return Err(bad(format!(
                    "{} neighbour travels for {} generators, or a non-finite one",
                    a.travels.len(),
                    a.generators
                )));
            }
            if !(a.weight.is_finite() && a.weight >= 0.0) {
                return Err(bad(format!("neighbour weight {}", a.weight)));
            }
            let nb = Neighbours::with_weight(a.travels.clone(), step, a.weight);
            let nb = if a.seconds.is_empty() {
                nb
            } else {
                if a.seconds.len() != a.generators || a.seconds.iter().any(|t| !t.is_finite()) {
                    return Err(bad(format!(
                        "{} neighbour second components for {} generators, or a non-finite one",
                        a.seconds.len(),
                        a.generators
                    )));
                }
                if !(a.second_scale.is_finite() && a.second_scale > 0.0) {
                    return Err(bad(format!("neighbour second scale {}", a.second_scale)));
                }
                nb.with_second(super::neighbours::Second { values: a.seconds.clone(), scale: a.second_scale })
            };
            Some((nb, a.generators))
        };
        let inner = if neighbours.is_some() { Inner::Neighbours } else { Inner::Cpg };
        Ok(Self { map, inner, modes, round_trip: (f64::NAN, f64::NAN), neighbours, levels: None })
    }
}

#[cfg(test)]
mod tests {
    use faer::Mat;

    use crate::dual::registration::{Interpolation, MapKind, Registered, RegisteredArrays};
    use crate::dual::{DualApprox, Inner, Training};

    /// `built`'s arrays, after checking that the basis rebuilt from them gives the same arrays
    /// and pushes the first `m` generators to the same bits at every point of `points` (`what`
    /// names the case in a failure).
    fn survives_its_arrays(built: &Registered, points: &[&[f64]], m: usize, what: &str) -> RegisteredArrays {
        let arrays = built.arrays().expect("a cone basis");
        let back = Registered::from_arrays(&arrays).expect("rebuilt");
        assert_eq!(back.arrays().as_ref(), Some(&arrays), "{what}");
        for &mu in points {
            let (a, b) = (built.cone_basis(mu, m).expect("a"), back.cone_basis(mu, m).expect("b"));
            assert_eq!((a.nrows(), a.ncols()), (b.nrows(), b.ncols()), "{what} at {mu:?}");
            for j in 0..a.ncols() {
                for i in 0..a.nrows() {
                    assert_eq!(a[(i, j)].to_bits(), b[(i, j)].to_bits(), "{what} at {mu:?}: ({i}, {j})");
                }
            }
        }
        arrays
    }

    /// Whether `arrays` with `edit` applied are refused.
    fn refused(arrays: &RegisteredArrays, edit: impl Fn(&mut RegisteredArrays)) -> bool {
        let mut a = arrays.clone();
        edit(&mut a);
        Registered::from_arrays(&a).is_err()
    }

    /// Every map kind: the basis rebuilt from its arrays pushes its generators to the same bits
    /// at training points, between them and beyond the training range (on a surface given in
    /// a shuffled node order, so the dual-order round trip of the abscissae is exercised), and
    /// damaged arrays are refused.
    #[test]
    fn a_registered_basis_survives_its_arrays_bit_for_bit() {
        let n = 50;
        // node i at abscissa 0.1 * perm(i): a shuffled surface order
        let perm: Vec<usize> = (0..n).map(|i| (i * 17) % n).collect();
        let x: Vec<f64> = perm.iter().map(|&p| 0.1 * p as f64).collect();
        let params: Vec<Vec<f64>> = (0..9).map(|j| vec![0.5 + 0.3 * j as f64]).collect();
        let bump = |t: f64, w: f64| (1.0 - (t / w).powi(2)).max(0.0);
        let s = Mat::from_fn(n, params.len(), |i, j| bump(x[i] - 1.0 - params[j][0], 0.2 + 0.05 * params[j][0]));
        let ms = [1usize, 2, 3, 4];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let nodes = MapKind::Translate { interpolation: Interpolation::Nodes };
        for (kind, inner) in [
            (nodes, Inner::Cpg),
            (nodes, Inner::Neighbours),
            (MapKind::Translate { interpolation: Interpolation::Linear { refine: 3 } }, Inner::Cpg),
            (MapKind::Moments { refine: 2 }, Inner::Cpg),
        ] {
            let built = Registered::build(&t, kind, inner).expect("build");
            let points: Vec<[f64; 1]> = [0.5, 0.77, 1.4, 3.2, -4.0, 40.0].map(|mu| [mu]).to_vec();
            let points: Vec<&[f64]> = points.iter().map(|p| p.as_slice()).collect();
            let arrays = survives_its_arrays(&built, &points, 3, &format!("{kind:?}"));
            assert!(
                refused(&arrays, |a| {
                    a.modes.pop();
                }),
                "{kind:?}: a short generator array"
            );
            assert!(refused(&arrays, |a| a.modes[0] = f64::NAN), "{kind:?}: a NaN generator");
            assert!(refused(&arrays, |a| a.grid[1] = 0.0), "{kind:?}: a zero grid step");
            if inner == Inner::Neighbours {
                assert!(
                    refused(&arrays, |a| {
                        a.travels.pop();
                    }),
                    "a travel missing"
                );
                assert!(refused(&arrays, |a| a.weight = -1.0), "a negative weight");
            }
        }
        let pod = Registered::build(&t, MapKind::Moments { refine: 2 }, Inner::Pod).expect("pod");
        assert!(pod.arrays().is_none(), "a registered POD is not a dual basis of the online solve");
    }

    /// A moments map over two parameter components (a 5 x 4 grid with two points missing, as
    /// in a leave-one-out fold, on a shuffled surface): the basis rebuilt from its arrays, whose
    /// table keeps each point's two components in the fit's order, pushes its generators to the
    /// same bits at grid points, between them and beyond the grid; damaged tables are refused.
    #[test]
    fn a_moments_map_over_two_components_survives_its_arrays_bit_for_bit() {
        let n = 60;
        let perm: Vec<usize> = (0..n).map(|i| (i * 23) % n).collect();
        let x: Vec<f64> = perm.iter().map(|&p| 0.05 * p as f64).collect();
        let params: Vec<Vec<f64>> = (0..4)
            .flat_map(|k| (0..5).map(move |j| vec![0.3 * j as f64, 1.0 + 0.5 * k as f64]))
            .filter(|p| p != &vec![0.6, 1.5] && p != &vec![1.2, 2.5])
            .collect();
        let bump = |t: f64, w: f64| (1.0 - (t / w).powi(2)).max(0.0).sqrt();
        let s = Mat::from_fn(n, params.len(), |i, j| {
            let (c, w) = (0.8 + params[j][0], 0.1 * params[j][1]);
            params[j][1] * bump(x[i] - c, w)
        });
        let ms = [1usize, 2, 3];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let built = Registered::build(&t, MapKind::Moments { refine: 4 }, Inner::Cpg).expect("build");
        let arrays = built.arrays().expect("a cone basis over two components");
        assert_eq!(arrays.dims, 2);
        assert_eq!(arrays.table.len(), 4 * params.len(), "one row (mu_1, mu_2, c, a) per training point");
        for (row, mu) in arrays.table.chunks(4).zip(&params) {
            assert_eq!(&row[..2], mu.as_slice(), "the rows keep the fit's order");
        }
        let points = [[0.0, 1.0], [0.6, 1.5], [0.45, 1.75], [1.2, 2.5], [0.1, 2.9], [-1.0, 0.0], [3.0, 9.0]];
        let points: Vec<&[f64]> = points.iter().map(|p| p.as_slice()).collect();
        assert_eq!(survives_its_arrays(&built, &points, 3, "two components"), arrays);
        // a point with one component reads the lowest level instead of indexing past the row
        let back = Registered::from_arrays(&arrays).expect("rebuilt");
        assert!(back.cone_basis(&[0.3], 3).is_some());
        assert!(refused(&arrays, |a| {
            a.table.pop();
        }));
        assert!(refused(&arrays, |a| a.table[3] = 0.0), "a zero width");
        assert!(refused(&arrays, |a| a.table[0] = f64::INFINITY), "a non-finite component");
        assert!(refused(&arrays, |a| a.dims = 0));
        assert!(refused(&arrays, |a| a.dims = 3), "rows of the wrong length");
        let mut translate = arrays.clone();
        translate.kind = MapKind::Translate { interpolation: Interpolation::Linear { refine: 4 } };
        translate.table.clear();
        assert!(Registered::from_arrays(&translate).is_err(), "a translation over two components has no table");
    }

    /// Registered neighbours over two parameter components (a 9 x 4 grid of a bump moved by the
    /// first and widened by the second, on a shuffled uniform surface): the first four columns
    /// at a point between the grid's points come one from each side (the part of a node the
    /// shift leaves below or above the point's, the second component below or above its); the
    /// basis rebuilt from its arrays, which keep each generator's second component and their
    /// scale, pushes the same columns to the same bits; damaged second components are refused.
    #[test]
    fn neighbours_over_two_components_survive_their_arrays_bit_for_bit() {
        let (n, h) = (60, 0.05);
        let perm: Vec<usize> = (0..n).map(|i| (i * 23) % n).collect();
        let x: Vec<f64> = perm.iter().map(|&p| h * p as f64).collect();
        let params: Vec<Vec<f64>> =
            (0..4).flat_map(|k| (0..9).map(move |j| vec![0.13 * j as f64, 1.0 + 0.5 * k as f64])).collect();
        let bump = |t: f64, w: f64| (1.0 - (t / w).powi(2)).max(0.0).sqrt();
        let s =
            Mat::from_fn(n, params.len(), |i, j| params[j][1] * bump(x[i] - 0.8 - params[j][0], 0.1 * params[j][1]));
        let ms = [1usize, 2, 3, 4, 5];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &[], ms: &ms };
        let kind = MapKind::Translate { interpolation: Interpolation::Nodes };
        let built = Registered::build(&t, kind, Inner::Neighbours).expect("build");
        let nb = built.neighbours().expect("a neighbours basis");
        let second = nb.second().expect("two components");
        // the grids' steps: 0.13 of travel against 0.5 of the second component
        assert!((second.scale - 0.26).abs() < 1e-12, "scale {}", second.scale);
        let mu = [0.52 + 0.3 * h, 1.75];
        let rho = |c: f64| c / h - (c / h).round();
        let wrap = |d: f64| {
            let d = d - d.round();
            if d <= -0.5 {
                d + 1.0
            } else {
                d
            }
        };
        let sides: std::collections::BTreeSet<(bool, bool)> = nb
            .order(mu[0], mu[1])
            .take(4)
            .map(|j| (wrap(rho(params[j][0]) - rho(mu[0])) > 0.0, params[j][1] > mu[1]))
            .collect();
        assert_eq!(sides.len(), 4, "the first four columns bracket both components");
        let arrays = built.arrays().expect("a cone basis");
        assert_eq!(arrays.seconds, params.iter().map(|p| p[1]).collect::<Vec<_>>());
        let points = [[0.0, 1.0], [0.52, 1.5], [0.6, 1.75], [0.99, 2.2], [1.04, 2.5]];
        let points: Vec<&[f64]> = points.iter().map(|p| p.as_slice()).collect();
        assert_eq!(survives_its_arrays(&built, &points, 5, "neighbours over two components"), arrays);
        assert!(refused(&arrays, |a| {
            a.seconds.pop();
        }));
        assert!(refused(&arrays, |a| a.seconds[0] = f64::NAN), "a non-finite component");
        assert!(refused(&arrays, |a| a.second_scale = 0.0), "a zero scale");
    }

    /// A contact area (4 lines across the travel, shuffled dual order): the basis rebuilt from
    /// its arrays, the lines' coordinates among them, pushes its generators to the same bits for
    /// every map kind; arrays whose across coordinates are short or whose grid does not split
    /// into the lines are refused.
    #[test]
    fn a_registered_basis_of_an_area_survives_its_arrays_bit_for_bit() {
        let (nx, lines) = (30usize, 4usize);
        let n = nx * lines;
        let perm: Vec<usize> = (0..n).map(|i| (i * 7) % n).collect();
        let x: Vec<f64> = perm.iter().map(|&p| 0.1 * (p % nx) as f64).collect();
        let y: Vec<f64> = perm.iter().map(|&p| 0.25 * (p / nx) as f64).collect();
        let params: Vec<Vec<f64>> = (0..7).map(|j| vec![0.2 * j as f64]).collect();
        let bump = |t: f64| (1.0 - ((t - 1.0) / 0.3).powi(2)).max(0.0);
        let s = Mat::from_fn(n, params.len(), |i, j| bump(x[i] - params[j][0]) * (1.0 + y[i]));
        let ms = [1usize, 2, 3];
        let t = Training { snapshots: s.as_ref(), params: &params, surface: &x, across: &y, ms: &ms };
        for kind in [
            MapKind::Translate { interpolation: Interpolation::Nodes },
            MapKind::Translate { interpolation: Interpolation::Linear { refine: 2 } },
            MapKind::Moments { refine: 2 },
        ] {
            let built = Registered::build(&t, kind, Inner::Cpg).expect("build");
            let points: Vec<[f64; 1]> = [0.0, 0.33, 0.9, 2.5].map(|mu| [mu]).to_vec();
            let points: Vec<&[f64]> = points.iter().map(|p| p.as_slice()).collect();
            let arrays = survives_its_arrays(&built, &points, 2, &format!("{kind:?}"));
            assert_eq!(arrays.across, y, "{kind:?}");
            assert!(
                refused(&arrays, |a| {
                    a.across.pop();
                }),
                "{kind:?}: across coordinates missing"
            );
            assert!(
                refused(&arrays, |a| {
                    a.len += 1;
                    a.modes.extend(std::iter::repeat_n(0.0, a.generators));
                }),
                "{kind:?}: a grid that does not split into the lines"
            );
        }
    }
}
