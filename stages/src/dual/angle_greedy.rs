//! Angle-Greedy snapshot selection (Burkovska, Haasdonk, Salomon and Wohlmuth 2015, the
//! paper's ref. \[10\]).
//!
//! With `V_0 = {0}` and `V_t = span(s_{j_1}, .., s_{j_t})`, step t picks the snapshot at the
//! largest angle to the span of those already chosen:
//!
//! ```text
//! j_t = argmax_j sin angle(s_j, V_{t-1}) = argmax_j ||s_j - P_{V_{t-1}} s_j|| / ||s_j||
//! ```
//!
//! (ties, within a relative `TIE_REL`, to the lowest index: at the first step every non-zero
//! snapshot has angle 1 to `{0}`, so the first one is chosen), and stops once every angle is below `SPAN_REL` (every snapshot in
//! the span) or `max_m` are chosen. CPG (Sec. 2.3.1) is the same loop with the cone projection
//! in place of `P_V`. The residual of each normalised snapshot is kept explicitly and
//! orthogonalised against each new direction twice, so the angles are accurate down to
//! round-off. Zero snapshots are never chosen.

use faer::{Mat, MatRef};

use crate::cone::norm2;

/// Every snapshot whose sine to the span is at most this is in it (round-off of two
/// Gram–Schmidt passes is ~1e-15; 1e-10 stops before the selection picks noise).
pub const SPAN_REL: f64 = 1e-10;

/// Two sines within this relative difference are a tie (their round-off is ~1e-16).
const TIE_REL: f64 = 1e-12;

/// Whether a candidate's sine beats the running best's.
fn beats(candidate: f64, best: f64) -> bool {
    candidate > best * (1.0 + TIE_REL)
}

/// The selection.
#[derive(Debug, Clone, PartialEq)]
pub struct AngleGreedy {
    /// Chosen snapshot indices, in order.
    pub selected: Vec<usize>,
    /// Sine of the chosen snapshot's angle to the previous span, per step.
    pub angles: Vec<f64>,
}

/// Angle-Greedy selection of at most `max_m` columns of `s` (n x N).
pub fn select(s: MatRef<'_, f64>, max_m: usize) -> AngleGreedy {
    let (n, count) = (s.nrows(), s.ncols());
    let mut residual: Vec<Vec<f64>> = (0..count)
        .map(|j| {
            let col: Vec<f64> = (0..n).map(|i| s[(i, j)]).collect();
            let norm = norm2(&col);
            if norm > 0.0 {
                col.iter().map(|x| x / norm).collect()
            } else {
                vec![0.0; n]
            }
        })
        .collect();
    let mut err: Vec<f64> = residual.iter().map(|r| if norm2(r) > 0.0 { 1.0 } else { 0.0 }).collect();
    let mut chosen = vec![false; count];
    let mut out = AngleGreedy { selected: Vec::new(), angles: Vec::new() };
    let mut q = vec![0.0; n];
    while out.selected.len() < max_m {
        let mut best: Option<usize> = None;
        for j in 0..count {
            if !chosen[j] && best.is_none_or(|b| beats(err[j], err[b])) {
                best = Some(j);
            }
        }
        let Some(b) = best.filter(|&b| err[b] > SPAN_REL) else { break };
        chosen[b] = true;
        out.selected.push(b);
        out.angles.push(err[b]);
        let norm = norm2(&residual[b]);
        q.iter_mut().zip(&residual[b]).for_each(|(qi, r)| *qi = r / norm);
        for (j, r) in residual.iter_mut().enumerate() {
            if chosen[j] {
                continue;
            }
            for _pass in 0..2 {
                let c: f64 = q.iter().zip(r.iter()).map(|(a, b)| a * b).sum();
                r.iter_mut().zip(&q).for_each(|(x, qi)| *x -= c * qi);
            }
            err[j] = norm2(r);
        }
    }
    out
}

/// The chosen columns of `s`, each scaled to unit norm (the non-negative basis).
pub fn unit_columns(s: MatRef<'_, f64>, selected: &[usize]) -> Mat<f64> {
    let n = s.nrows();
    let norms: Vec<f64> = selected.iter().map(|&j| (0..n).map(|i| s[(i, j)] * s[(i, j)]).sum::<f64>().sqrt()).collect();
    Mat::from_fn(n, selected.len(), |i, c| s[(i, selected[c])] / norms[c])
}

/// The definition, by brute force: every step solves a least-squares problem for every
/// candidate from scratch (thin SVD of the chosen columns). For the tests only.
pub fn select_reference(s: MatRef<'_, f64>, max_m: usize) -> Vec<usize> {
    let (n, count) = (s.nrows(), s.ncols());
    let mut selected: Vec<usize> = Vec::new();
    while selected.len() < max_m {
        let basis = Mat::from_fn(n, selected.len(), |i, c| s[(i, selected[c])]);
        let u = if selected.is_empty() {
            None
        } else {
            let svd = basis.thin_svd().expect("svd");
            let sv: Vec<f64> = svd.S().column_vector().iter().copied().collect();
            let rank = sv.iter().filter(|&&x| x > 1e-12 * sv[0]).count();
            Some(svd.U().subcols(0, rank).to_owned())
        };
        let mut best: Option<(usize, f64)> = None;
        for j in (0..count).filter(|j| !selected.contains(j)) {
            let col: Vec<f64> = (0..n).map(|i| s[(i, j)]).collect();
            let norm = norm2(&col);
            if norm == 0.0 {
                continue;
            }
            let mut r = col.clone();
            if let Some(u) = &u {
                for l in 0..u.ncols() {
                    let c: f64 = (0..n).map(|i| u[(i, l)] * col[i]).sum();
                    (0..n).for_each(|i| r[i] -= c * u[(i, l)]);
                }
            }
            let angle = if selected.is_empty() { 1.0 } else { norm2(&r) / norm };
            if best.is_none_or(|(_, a)| beats(angle, a)) {
                best = Some((j, angle));
            }
        }
        match best {
            Some((j, a)) if a > SPAN_REL => selected.push(j),
            _ => break,
        }
    }
    selected
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// The selection equals the brute-force definition on ten random non-negative snapshots
    /// of dimension 12 (generic: no ties), through every step.
    #[test]
    fn selection_matches_brute_force() {
        for seed in 0..5 {
            let mut rng = Rng::new(100 + seed);
            let s = Mat::from_fn(12, 10, |_, _| rng.uniform());
            assert_eq!(select(s.as_ref(), 10).selected, select_reference(s.as_ref(), 10), "seed {seed}");
        }
    }

    /// Dependent snapshots stop the selection at the rank; zero ones are never chosen.
    #[test]
    fn it_stops_at_the_span_and_skips_zeros() {
        let mut rng = Rng::new(7);
        let a = Mat::from_fn(15, 3, |_, _| rng.uniform());
        let mut s = Mat::zeros(15, 8);
        for j in 0..7 {
            let w = [rng.uniform(), rng.uniform(), rng.uniform()];
            for i in 0..15 {
                s[(i, j)] = (0..3).map(|l| w[l] * a[(i, l)]).sum::<f64>();
            }
        }
        let out = select(s.as_ref(), 8);
        assert_eq!(out.selected.len(), 3);
        assert!(!out.selected.contains(&7));
        assert_eq!(out.selected, select_reference(s.as_ref(), 8));
    }
}
