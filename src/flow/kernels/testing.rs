//! Test support: the one tolerance check of the flow tests (host kernels against each other,
//! operations against Burn's) and seeded random cases for the property tests.

use rand::RngExt;

use crate::rng;

/// How close two results must be.
#[derive(Clone, Copy, Debug)]
pub enum Tol {
    /// `|got − want| ≤ t` everywhere.
    Abs(f32),
    /// `|got − want| ≤ t · max(1, max |want|)` everywhere: for sums whose size grows with the
    /// operands.
    Scaled(f32),
}

/// Asserts that `got` and `want` have the same length and agree within `tol` everywhere; a NaN
/// on either side fails unless both are NaN. `what` names the compared quantity.
#[track_caller]
pub fn assert_close(got: &[f32], want: &[f32], tol: Tol, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: lengths differ");
    let bound = match tol {
        Tol::Abs(t) => t,
        Tol::Scaled(t) => t * want.iter().fold(1f32, |m, v| m.max(v.abs())),
    };
    for (i, (&g, &w)) in got.iter().zip(want).enumerate() {
        let same_nan = g.is_nan() && w.is_nan();
        assert!(
            same_nan || (g - w).abs() <= bound,
            "{what}: element {i} is {g}, expected {w} (tolerance {bound}; max difference {})",
            max_difference(got, want)
        );
    }
}

/// The largest `|got − want|`, NaN when either holds a NaN.
pub fn max_difference(got: &[f32], want: &[f32]) -> f32 {
    got.iter().zip(want).fold(0f32, |m, (&g, &w)| {
        let d = (g - w).abs();
        if d.is_nan() || m.is_nan() {
            f32::NAN
        } else {
            m.max(d)
        }
    })
}

/// A seeded generator for property test `name`, case `case`: the same cases on every run.
pub fn cases(name: &str, case: u64) -> rng::Rng {
    let key = name
        .bytes()
        .fold(0u64, |h, b| rng::splitmix(h ^ u64::from(b)));
    rng::stream(key, &[case])
}

/// `n` values from N(0, σ²)-like uniform noise in [−σ√3, σ√3] (the same variance).
pub fn values(r: &mut rng::Rng, n: usize, sigma: f32) -> Vec<f32> {
    let a = sigma * 3f32.sqrt();
    (0..n).map(|_| r.random_range(-a..a)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tolerances_and_nans() {
        assert_close(&[1.0, 2.0], &[1.0, 2.05], Tol::Abs(0.1), "abs");
        assert_close(&[100.0], &[100.5], Tol::Scaled(0.01), "scaled");
        assert_close(&[f32::NAN], &[f32::NAN], Tol::Abs(0.0), "both NaN");
        let nan = std::panic::catch_unwind(|| {
            assert_close(&[f32::NAN], &[0.0], Tol::Abs(1.0), "one NaN")
        });
        assert!(nan.is_err());
        let far = std::panic::catch_unwind(|| assert_close(&[0.0], &[1.0], Tol::Abs(0.5), "far"));
        assert!(far.is_err());
        assert!(max_difference(&[1.0, f32::NAN], &[1.0, 0.0]).is_nan());
        let mut a = cases("x", 1);
        let mut b = cases("x", 1);
        assert_eq!(values(&mut a, 4, 1.0), values(&mut b, 4, 1.0));
    }
}
