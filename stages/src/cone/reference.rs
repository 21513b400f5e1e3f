//! A plain, obviously-correct NNLS used to cross-check [`Nnls`](super::Nnls) in tests and
//! benchmarks: textbook Lawson–Hanson (Lawson & Hanson 1974, ch. 23, algorithm NNLS) working
//! on `A` and `b` directly, solving every passive least-squares problem from scratch with a
//! truncated-SVD pseudo-inverse (minimum-norm solution, so dependent columns cannot produce
//! NaN). Slow — O(k) SVDs per solve — and never used by the pipeline.

use faer::{Mat, MatRef};

use super::nnls::{norm2, residual_into, ConeError, NnlsParams, NnlsSolution};

/// Reference Lawson–Hanson NNLS, `min ||A x - b||, x >= 0` (`a` n x k, `b` length n).
///
/// Stops when `max_{j not in P} w_j <= tol * ||A||_max-col * ||b||` with `w = A^T (b - A x)`;
/// `NnlsParams::pivot_tol` is unused. `kkt_residual` in the result uses that same scale.
pub fn nnls_reference(a: MatRef<'_, f64>, b: &[f64], params: NnlsParams) -> Result<NnlsSolution, ConeError> {
    assert_eq!(a.nrows(), b.len(), "nnls_reference: A rows and b length differ");
    let k = a.ncols();
    let amax = (0..k).map(|j| a.col(j).norm_l2()).fold(0.0, f64::max);
    let scale = amax * norm2(b);
    let tol = params.tol * scale;
    let mut x = vec![0.0; k];
    let mut passive = vec![false; k];
    let mut iterations = 0;
    loop {
        let w = dual(a, b, &x);
        let entering = (0..k).filter(|&j| !passive[j] && w[j] > tol).max_by(|&i, &j| w[i].total_cmp(&w[j]));
        let Some(t) = entering else {
            let kkt = kkt_residual(&w, &passive, scale);
            return Ok(solution(a, b, x, iterations, kkt));
        };
        if iterations >= params.max_iter_for(k) {
            let kkt_residual = kkt_residual(&w, &passive, scale);
            return Err(ConeError::NotConverged { iterations, kkt_residual });
        }
        iterations += 1;
        passive[t] = true;
        loop {
            let z = passive_lstsq(a, b, &passive);
            // Step length to the first passive coefficient that would turn non-positive.
            let blocking = (0..k)
                .filter(|&j| passive[j] && z[j] <= 0.0)
                .map(|j| (if x[j] > z[j] { x[j] / (x[j] - z[j]) } else { 0.0 }, j))
                .min_by(|p, q| p.0.total_cmp(&q.0));
            let Some((alpha, jmin)) = blocking else {
                x = z;
                break;
            };
            for j in 0..k {
                x[j] += alpha * (z[j] - x[j]);
            }
            x[jmin] = 0.0;
            for j in 0..k {
                if passive[j] && x[j] <= 0.0 {
                    x[j] = 0.0;
                    passive[j] = false;
                }
            }
        }
    }
}

/// `w = A^T (b - A x)`.
fn dual(a: MatRef<'_, f64>, b: &[f64], x: &[f64]) -> Vec<f64> {
    let mut r = vec![0.0; b.len()];
    residual_into(a, x, b, &mut r);
    (0..a.ncols()).map(|j| (0..b.len()).map(|i| a[(i, j)] * r[i]).sum()).collect()
}

/// Minimum-norm least-squares solution on the passive columns (zeros elsewhere), from the thin
/// SVD of `A_P` with singular values below `max(n, p) eps s_max` dropped.
fn passive_lstsq(a: MatRef<'_, f64>, b: &[f64], passive: &[bool]) -> Vec<f64> {
    let cols: Vec<usize> = (0..a.ncols()).filter(|&j| passive[j]).collect();
    let ap = Mat::from_fn(a.nrows(), cols.len(), |i, q| a[(i, cols[q])]);
    let mut x = vec![0.0; a.ncols()];
    let Ok(svd) = ap.thin_svd() else { return x };
    let s = svd.S().column_vector();
    let smax = if s.nrows() > 0 { s[0] } else { 0.0 };
    let cut = a.nrows().max(cols.len()) as f64 * f64::EPSILON * smax;
    for r in 0..s.nrows() {
        if s[r] > cut {
            let u = svd.U().col(r);
            let coef = (0..b.len()).map(|i| u[i] * b[i]).sum::<f64>() / s[r];
            for (q, &j) in cols.iter().enumerate() {
                x[j] += coef * svd.V()[(q, r)];
            }
        }
    }
    x
}

fn kkt_residual(w: &[f64], passive: &[bool], scale: f64) -> f64 {
    if scale <= 0.0 {
        return 0.0;
    }
    let worst = w.iter().zip(passive).map(|(&wj, &p)| if p { wj.abs() } else { wj.max(0.0) }).fold(0.0, f64::max);
    worst / scale
}

fn solution(a: MatRef<'_, f64>, b: &[f64], x: Vec<f64>, iterations: usize, kkt_residual: f64) -> NnlsSolution {
    let mut r = vec![0.0; b.len()];
    residual_into(a, &x, b, &mut r);
    NnlsSolution { x, residual_norm: norm2(&r), iterations, kkt_residual }
}
