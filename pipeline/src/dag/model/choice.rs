//! Which reduced model the model stage stores: the candidates the study measured, and the rule.
//!
//! **Candidates.** The rows of the online stage's `tradeoff.parquet` with algorithm `exact` (or
//! `exact-sampled`, a sampled contact surface): the study's CPG basis at a rank pair
//! ([`exact_rows`]); and the rows of each registered CPG approximation's
//! `online_comparison.parquet` (the online comparison, at the full primal rank and `m`
//! generators, [`registered_rows`]). `study.model_dual` restricts them to one kind (`cpg`) or
//! one registered approximation.
//!
//! **The rule** ([`best`]): a registered row only if it converged at every test point; then the
//! fewest test points not converged (none, wherever some candidate converged everywhere), the
//! least median dual (pressure) error, the least median primal error, the fewest modes
//! (`r_primal + r_dual`, with `r_dual = m` for a registered row), and finally the order in
//! which the candidates are listed (the trade-off's rows first, in table order; a defined
//! error beats an undefined one). The rule reads results only, never timings, so the choice is
//! the same run to run.

use crom_schemas::artifact::rom as rom_names;
use crom_stages::rom::Algorithm;

use crate::io::model::Measured;
use crate::io::table::Table;

/// Where a candidate comes from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Source {
    /// The study's CPG basis: a row of the trade-off (`exact` or `exact-sampled`; `full` or
    /// `truncated`).
    Exact { algorithm: String, dual_basis: String },
    /// Registered approximation number `0` of the stage's list, rebuilt at each query point.
    Registered(usize),
}

/// A model the study measured (or one a scene asks for).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Candidate {
    pub source: Source,
    pub r_primal: usize,
    /// The dual rank; for a registered basis the most generators per query, `m`.
    pub r_dual: usize,
    pub measured: Measured,
    /// Median online seconds, median full-order seconds, speed-up (NaN where not measured): a
    /// timing, never read by the rule.
    pub speed: [f64; 3],
}

impl Candidate {
    /// Nothing measured: the full CPG basis and primal basis (`usize::MAX` ranks are clipped to
    /// the bases').
    pub(crate) fn full_bases() -> Self {
        Self {
            source: Source::Exact { algorithm: Algorithm::Exact.name().into(), dual_basis: "full".into() },
            r_primal: usize::MAX,
            r_dual: usize::MAX,
            measured: Measured::none(),
            speed: [f64::NAN; 3],
        }
    }

    /// Whether it is a row of the sampled contact surface (`exact-sampled`).
    pub(crate) fn sampled(&self) -> bool {
        matches!(&self.source, Source::Exact { algorithm, .. } if algorithm == rom_names::SAMPLED)
    }

    /// Test points not converged.
    fn missed(&self) -> u64 {
        self.measured.points.saturating_sub(self.measured.converged)
    }
}

/// The trade-off's rows of the exact solve (full or sampled surface), with the timings of
/// `tradeoff_timings.parquet` (same rows).
pub(crate) fn exact_rows(trade: &Table, times: &Table) -> Vec<Candidate> {
    let (Some(alg), Some(basis), Some(ru), Some(rl)) =
        (trade.strs("algorithm"), trade.strs("dual_basis"), trade.u64s("r_primal"), trade.u64s("r_dual"))
    else {
        return Vec::new();
    };
    let t = |c: &str, i: usize| times.f64s(c).and_then(|v| v.get(i).copied()).unwrap_or(f64::NAN);
    (0..trade.rows())
        .filter(|&i| alg[i] == Algorithm::Exact.name() || alg[i] == rom_names::SAMPLED)
        .map(|i| Candidate {
            source: Source::Exact { algorithm: alg[i].clone(), dual_basis: basis[i].clone() },
            r_primal: ru[i] as usize,
            r_dual: rl[i] as usize,
            measured: measured(trade, i),
            speed: [t("median_online_seconds", i), t("median_fom_seconds", i), t("speedup", i)],
        })
        .collect()
}

/// The online comparison's rows of registered approximation `which` named `name` (its
/// `online_comparison.parquet` and `online_comparison_timings.parquet`, same rows; the table
/// also holds the rows of the basis on a sampled surface, named with a suffix).
pub(crate) fn registered_rows(online: &Table, times: &Table, which: usize, name: &str) -> Vec<Candidate> {
    let (Some(m), Some(ru), Some(names)) = (online.u64s("m"), online.u64s("r_primal"), online.strs("approximation"))
    else {
        return Vec::new();
    };
    let t = |c: &str, i: usize| times.f64s(c).and_then(|v| v.get(i).copied()).unwrap_or(f64::NAN);
    (0..online.rows())
        .filter(|&i| names[i] == name)
        .map(|i| Candidate {
            source: Source::Registered(which),
            r_primal: ru[i] as usize,
            r_dual: m[i] as usize,
            measured: measured(online, i),
            speed: [1e-3 * t("median_online_ms", i), 1e-3 * t("median_full_order_ms", i), t("speedup", i)],
        })
        .collect()
}

/// What a table's row `i` measured (the trade-off's and the online comparison's share these
/// columns).
fn measured(t: &Table, i: usize) -> Measured {
    let u = |c: &str| t.u64s(c).map_or(0, |v| v[i]);
    let f = |c: &str| t.f64s(c).map_or(f64::NAN, |v| v[i]);
    Measured {
        points: u("points"),
        converged: u("converged"),
        median_primal_error: f("median_primal_error"),
        p95_primal_error: f("p95_primal_error"),
        median_dual_error: f("median_dual_error"),
    }
}

/// The candidate to store (see the module doc), if any is eligible.
pub(crate) fn best(candidates: &[Candidate]) -> Option<usize> {
    // an undefined error ranks after every defined one
    let rank = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
    let modes = |c: &Candidate| c.r_primal + c.r_dual;
    (0..candidates.len())
        .filter(|&i| {
            let c = &candidates[i];
            !matches!(c.source, Source::Registered(_)) || (c.measured.points > 0 && c.missed() == 0)
        })
        .min_by(|&a, &b| {
            let (x, y) = (&candidates[a], &candidates[b]);
            x.missed()
                .cmp(&y.missed())
                .then(rank(x.measured.median_dual_error).total_cmp(&rank(y.measured.median_dual_error)))
                .then(rank(x.measured.median_primal_error).total_cmp(&rank(y.measured.median_primal_error)))
                .then(modes(x).cmp(&modes(y)))
                .then(a.cmp(&b))
        })
}

/// The candidate at ranks `(r_primal, r_dual)` from `source`'s kind (the CPG basis's rows of
/// `algorithm`: the exact solve on the full surface, `exact`, or on the sampled one,
/// `exact-sampled`; registered approximation `k` at `m = r_dual`), if measured.
pub(crate) fn at_ranks(
    candidates: &[Candidate],
    registered: Option<usize>,
    algorithm: &str,
    ru: usize,
    rl: usize,
) -> Option<usize> {
    candidates.iter().position(|c| {
        let kind = match (&c.source, registered) {
            (Source::Exact { algorithm: a, .. }, None) => a == algorithm,
            (Source::Registered(k), Some(want)) => *k == want,
            _ => false,
        };
        kind && c.r_primal == ru && c.r_dual == rl
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// (source: `None` for an exact row, `Some(k)` registered k; r_primal, r_dual, converged of
    /// 10, median dual error, median primal error)
    type Row = (Option<usize>, usize, usize, u64, f64, f64);

    fn rows(rows: &[Row]) -> Vec<Candidate> {
        rows.iter()
            .map(|&(src, ru, rl, conv, dual, primal)| Candidate {
                source: src
                    .map_or(Source::Exact { algorithm: "exact".into(), dual_basis: "full".into() }, Source::Registered),
                r_primal: ru,
                r_dual: rl,
                measured: Measured {
                    points: 10,
                    converged: conv,
                    median_primal_error: primal,
                    p95_primal_error: primal,
                    median_dual_error: dual,
                },
                speed: [f64::NAN; 3],
            })
            .collect()
    }

    /// The rule: the fewest points not converged, then the least dual error, then the least
    /// primal error, then the fewest modes, undefined errors last; a registered row only where
    /// it converged everywhere, and it wins on its dual error like any other.
    #[test]
    fn best_prefers_converged_accurate_small_models() {
        let c = rows(&[
            (None, 8, 8, 9, 1e-8, 1e-8),      // a point failed
            (None, 8, 4, 10, 2e-3, 1e-3),     // candidate
            (None, 4, 4, 10, 2e-3, 1e-3),     // same errors, fewer modes: chosen
            (None, 2, 2, 10, f64::NAN, 1e-4), // undefined dual error: last
        ]);
        assert_eq!(best(&c), Some(2));
        let c = rows(&[(None, 2, 2, 8, 1e-4, 1e-4), (None, 2, 2, 9, 1e-3, 1e-3)]);
        assert_eq!(best(&c), Some(1), "the most converged when none converged everywhere");
        let c = rows(&[
            (None, 32, 128, 10, 2e-2, 1e-3),
            (Some(0), 128, 5, 10, 1e-2, 1e-3),
            (Some(0), 128, 10, 10, 9e-3, 1e-3),
        ]);
        assert_eq!(best(&c), Some(2), "the registered row with the least dual error");
        let c = rows(&[(None, 32, 128, 10, 2e-2, 1e-3), (Some(0), 128, 10, 9, 1e-3, 1e-3)]);
        assert_eq!(best(&c), Some(0), "a registered row that missed a point is not a candidate");
        let c = rows(&[(None, 32, 128, 8, 2e-2, 1e-3), (Some(1), 128, 10, 10, 5e-2, 1e-3)]);
        assert_eq!(best(&c), Some(1), "converged everywhere first");
        let c = rows(&[(None, 4, 4, 10, 1e-2, 1e-3), (Some(0), 4, 4, 10, 1e-2, 1e-3)]);
        assert_eq!(best(&c), Some(0), "a tie goes to the listed order");
        assert_eq!(best(&rows(&[(Some(0), 4, 4, 9, 1e-3, 1e-3)])), None);
        assert_eq!(best(&[]), None);
        assert_eq!(at_ranks(&c, Some(0), "exact", 4, 4), Some(1));
        assert_eq!(at_ranks(&c, None, "exact", 4, 4), Some(0));
        assert_eq!(at_ranks(&c, Some(1), "exact", 4, 4), None);
        // the sampled surface's row at the same ranks, asked for by its algorithm
        let mut c = rows(&[(None, 4, 4, 10, 1e-3, 1e-3), (None, 4, 4, 10, 2e-3, 1e-3)]);
        c[1].source = Source::Exact { algorithm: rom_names::SAMPLED.into(), dual_basis: "full".into() };
        assert_eq!(at_ranks(&c, None, rom_names::SAMPLED, 4, 4), Some(1));
        assert_eq!(at_ranks(&c, None, "exact", 4, 4), Some(0));
        assert!(c[1].sampled() && !c[0].sampled());
    }
}
