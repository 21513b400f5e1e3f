//! Test-only switches of the linearisation: search every slave instead of proving pairings
//! unchanged, check every proof against a search, or take plain re-pairing steps without the
//! Newton correction. Outside tests [`Switches`] is an empty type whose answers are constants
//! and whose checks do nothing, so production builds compute exactly what they would without
//! it. Every test-only switch of the reduced solve lives in this file.

/// Test switches of the linearisation (empty outside tests).
#[cfg(not(test))]
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Switches;

#[cfg(not(test))]
impl Switches {
    /// Re-pairing steps are Newton-corrected.
    #[inline]
    pub(super) fn newton(&self) -> bool {
        true
    }

    /// Pairings may be proved unchanged instead of searched.
    #[inline]
    pub(super) fn proofs(&self) -> bool {
        true
    }

    /// Nothing to check outside tests.
    #[inline]
    pub(super) fn check_master_path(&self, _s: usize, _xm: &[[f64; 2]], _master_path: f64, _at: f64) {}

    /// Proved pairings are not checked against searches outside tests.
    #[inline]
    pub(super) fn verifies(&self) -> bool {
        false
    }

    /// Nothing to record outside tests.
    #[inline]
    pub(super) fn record_search(&mut self, _s: usize, _ns: usize, _xm: &[[f64; 2]]) {}
}

/// Test switches of the linearisation.
#[cfg(test)]
#[derive(Debug, Clone, Default)]
pub(super) struct Switches {
    /// Search every slave at every linearisation (no proofs).
    search_all: bool,
    /// Check every proved pairing against a search, and the masters at each search.
    verify: bool,
    /// Plain re-pairing steps, without the Newton correction.
    plain: bool,
    /// With `verify`: every master's position at each slave's last search.
    cert_xm: Vec<Vec<[f64; 2]>>,
}

#[cfg(test)]
impl Switches {
    /// Whether re-pairing steps are Newton-corrected (always, but in tests that compare
    /// against plain steps).
    pub(super) fn newton(&self) -> bool {
        !self.plain
    }

    /// Whether pairings may be proved unchanged instead of searched (always, but in tests that
    /// compare against searching every slave).
    pub(super) fn proofs(&self) -> bool {
        !self.search_all
    }

    /// With `verify`: the bookkeeping bounds the masters' actual displacement since slave
    /// `s`'s search (`master_path` now, `at` then).
    pub(super) fn check_master_path(&self, s: usize, xm: &[[f64; 2]], master_path: f64, at: f64) {
        if self.verify {
            // The Euclidean distance of each master from its place at the search.
            let distance = |a: [f64; 2], b: [f64; 2]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2)).sqrt();
            let actual = xm.iter().zip(&self.cert_xm[s]).map(|(&a, &b)| distance(a, b)).fold(0.0f64, f64::max);
            assert!(actual <= (master_path - at) * (1.0 + 1e-12) + 1e-15, "slave {s}: {actual} moved");
        }
    }

    /// Whether every proved pairing is checked against a search at the same positions.
    pub(super) fn verifies(&self) -> bool {
        self.verify
    }

    /// With `verify`: record the masters `xm` at slave `s`'s search (`ns` slaves).
    pub(super) fn record_search(&mut self, s: usize, ns: usize, xm: &[[f64; 2]]) {
        if self.verify {
            self.cert_xm.resize(ns, Vec::new());
            self.cert_xm[s] = xm.to_vec();
        }
    }
}

#[cfg(test)]
impl super::RomWork {
    /// Buffers whose queries search every slave at every linearisation (tests).
    pub(crate) fn searching_always() -> Self {
        let mut w = Self::default();
        w.lin.switches.search_all = true;
        w
    }

    /// Buffers whose queries check every proved pairing against a search, and panic if they
    /// differ (tests).
    pub(crate) fn verifying_proofs() -> Self {
        let mut w = Self::default();
        w.lin.switches.verify = true;
        w
    }

    /// Buffers whose queries take plain re-pairing steps, without the Newton correction
    /// (tests).
    pub(crate) fn plain_steps() -> Self {
        let mut w = Self::default();
        w.lin.switches.plain = true;
        w
    }
}
