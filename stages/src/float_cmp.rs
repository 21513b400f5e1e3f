//! The one float-comparison helper of crom.
//!
//! Floats are never compared with bare `==`. Every comparison goes through [`close`] (or the
//! [`assert_close!`](crate::assert_close) macro in tests) with a tolerance that the call site
//! states and justifies.

/// Tolerances for [`close`]: `|a - b| <= abs + rel * max(|a|, |b|)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tol {
    /// Absolute part, for values that should be zero.
    pub abs: f64,
    /// Relative part, scaled by the larger magnitude.
    pub rel: f64,
}

impl Tol {
    /// A purely relative tolerance.
    pub const fn rel(rel: f64) -> Self {
        Self { abs: 0.0, rel }
    }
    /// A purely absolute tolerance.
    pub const fn abs(abs: f64) -> Self {
        Self { abs, rel: 0.0 }
    }
}

/// True when `a` and `b` agree within `tol` (false if either is NaN).
pub fn close(a: f64, b: f64, tol: Tol) -> bool {
    (a - b).abs() <= tol.abs + tol.rel * a.abs().max(b.abs())
}

/// True when `x` is zero within the absolute tolerance `abs`.
pub fn is_zero(x: f64, abs: f64) -> bool {
    x.abs() <= abs
}

/// Assert that two floats (or two slices of floats) agree within a [`Tol`].
///
/// `assert_close!(a, b, Tol::rel(1e-12))`; on failure prints both values, the index for slices,
/// and the tolerance.
#[macro_export]
macro_rules! assert_close {
    ($a:expr, $b:expr, $tol:expr $(,)?) => {{
        let (a, b, tol): (f64, f64, $crate::float_cmp::Tol) = ($a, $b, $tol);
        assert!(
            $crate::float_cmp::close(a, b, tol),
            "assert_close failed: {} = {a:e} vs {} = {b:e} (diff {:e}, {tol:?})",
            stringify!($a),
            stringify!($b),
            (a - b).abs()
        );
    }};
}

/// Assert that two float slices agree element-wise within a [`Tol`].
#[macro_export]
macro_rules! assert_all_close {
    ($a:expr, $b:expr, $tol:expr $(,)?) => {{
        let (a, b, tol): (&[f64], &[f64], $crate::float_cmp::Tol) = (&$a[..], &$b[..], $tol);
        assert_eq!(a.len(), b.len(), "assert_all_close: length mismatch");
        for (i, (x, y)) in a.iter().zip(b.iter()).enumerate() {
            assert!(
                $crate::float_cmp::close(*x, *y, tol),
                "assert_all_close failed at index {i}: {x:e} vs {y:e} (diff {:e}, {tol:?})",
                (x - y).abs()
            );
        }
    }};
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn close_respects_both_parts() {
        assert!(close(1.0, 1.0 + 1e-13, Tol::rel(1e-12)));
        assert!(!close(1.0, 1.0 + 1e-11, Tol::rel(1e-12)));
        assert!(close(0.0, 1e-15, Tol::abs(1e-14)));
        assert!(!close(0.0, 1e-13, Tol::abs(1e-14)));
        assert!(!close(f64::NAN, f64::NAN, Tol::abs(1.0)));
    }
}
