//! Robust statistics, one helper for every stage (Note S13's thresholds, made robust to an
//! estimated flow's jitter and to the movers themselves): the median, the median absolute
//! deviation (MAD), the robust standard deviation 1.4826 × MAD and the floor median + k σ.
//!
//! Two medians, as the stages have always computed them: `upper_median`, the element of rank
//! ⌊n/2⌋ (for an even count the higher of the two middle ones, no arithmetic), and `median`,
//! the two middle ones averaged for an even count. Values are ordered by `total_cmp`, so a NaN
//! never panics: a NaN sorts above +∞ (a negative NaN below −∞); callers drop the non-finite
//! values they do not want first. Empty input gives `None`.

use std::cmp::Ordering;
use std::ops::{Add, Div, Sub};

/// 1.4826 ≈ 1 / Φ⁻¹(3/4): the MAD of a normal sample times this is its standard deviation.
pub const MAD_TO_SIGMA: f64 = 1.4826;

/// A value with a total order (floats by `total_cmp`).
pub trait Sample: Copy {
    fn order(&self, other: &Self) -> Ordering;
}

macro_rules! ord_sample {
    ($($t:ty),*) => {$(
        impl Sample for $t {
            fn order(&self, other: &Self) -> Ordering {
                self.cmp(other)
            }
        }
    )*};
}
ord_sample!(u8, u16, u32, u64, usize);

/// A float: the MAD and the averaged median need its arithmetic.
pub trait Real: Sample + Add<Output = Self> + Sub<Output = Self> + Div<Output = Self> {
    const TWO: Self;
    fn abs(self) -> Self;
}

macro_rules! real_sample {
    ($($t:ty),*) => {$(
        impl Sample for $t {
            fn order(&self, other: &Self) -> Ordering {
                self.total_cmp(other)
            }
        }
        impl Real for $t {
            const TWO: Self = 2.0;
            fn abs(self) -> Self {
                <$t>::abs(self)
            }
        }
    )*};
}
real_sample!(f32, f64);

/// The upper median of `v`: its element of rank ⌊n/2⌋ in order (partly reorders `v`).
pub fn upper_median<T: Sample>(v: &mut [T]) -> Option<T> {
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    Some(*v.select_nth_unstable_by(mid, T::order).1)
}

/// The median of `v`, the two middle values averaged for an even count (sorts `v`).
pub fn median<T: Real>(v: &mut [T]) -> Option<T> {
    v.sort_unstable_by(T::order);
    sorted_median(v, |x| x)
}

/// The median of the already sorted `v`, each value taken as `to` gives it, the two middle
/// ones averaged for an even count.
pub fn sorted_median<T: Copy, R: Real>(v: &[T], to: impl Fn(T) -> R) -> Option<R> {
    let n = v.len();
    if n == 0 {
        None
    } else if n % 2 == 1 {
        Some(to(v[n / 2]))
    } else {
        Some((to(v[n / 2 - 1]) + to(v[n / 2])) / R::TWO)
    }
}

/// The upper median of `v` and the upper median of the absolute deviations from it (the MAD);
/// `v` is left holding the absolute deviations.
pub fn upper_median_mad<T: Real>(v: &mut [T]) -> Option<(T, T)> {
    let m = upper_median(v)?;
    v.iter_mut().for_each(|x| *x = (*x - m).abs());
    Some((m, upper_median(v)?))
}

/// The robust standard deviation of a sample whose MAD is `mad`: 1.4826 × MAD.
pub fn sigma(mad: f64) -> f64 {
    MAD_TO_SIGMA * mad
}

/// `sigma` in f32 (1.4826 rounded to f32, × MAD).
pub fn sigma_f32(mad: f32) -> f32 {
    MAD_TO_SIGMA as f32 * mad
}

/// The noise floor `median` + `k` robust standard deviations (evaluated as median + k · 1.4826
/// · MAD, left to right).
pub fn floor(median: f64, mad: f64, k: f64) -> f64 {
    median + k * MAD_TO_SIGMA * mad
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_input_has_no_median() {
        assert_eq!(upper_median::<f32>(&mut []), None);
        assert_eq!(median::<f64>(&mut []), None);
        assert_eq!(sorted_median::<u8, f32>(&[], |x| x as f32), None);
        assert_eq!(upper_median_mad::<f64>(&mut []), None);
    }

    #[test]
    fn odd_and_even_lengths() {
        assert_eq!(upper_median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        // Even: the upper median is the higher middle value, the median their mean.
        assert_eq!(upper_median(&mut [4.0f32, 1.0, 3.0, 2.0]), Some(3.0));
        assert_eq!(median(&mut [4.0f32, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(upper_median(&mut [5usize, 1, 9, 7]), Some(7));
        assert_eq!(sorted_median(&[1u8, 2, 4, 9], |x| x as f32), Some(3.0));
        assert_eq!(median(&mut [7.0f64]), Some(7.0));
    }

    #[test]
    fn nan_sorts_above_infinity_and_never_panics() {
        // In order 0 1 2 ∞ NaN: the NaN is the largest, rank 2 is 2.
        let mut v = [f32::NAN, 1.0, f32::INFINITY, 0.0, 2.0];
        assert_eq!(upper_median(&mut v), Some(2.0));
        let mut v = [f64::NAN, f64::NAN, 1.0];
        assert!(upper_median(&mut v).unwrap().is_nan());
        let mut v = [-f64::NAN, 1.0, 2.0];
        assert_eq!(median(&mut v), Some(1.0));
    }

    #[test]
    fn mad_and_the_floor() {
        // 1 2 4 9 20: median 4, deviations 3 2 0 5 16, MAD 3.
        let mut v = [20.0f32, 1.0, 9.0, 4.0, 2.0];
        assert_eq!(upper_median_mad(&mut v), Some((4.0, 3.0)));
        assert_eq!(upper_median_mad(&mut [7.0f64; 6]), Some((7.0, 0.0)));
        assert_eq!(sigma(2.0), 2.0 * 1.4826);
        assert_eq!(sigma_f32(2.0), 2.0 * 1.4826f32);
        assert_eq!(floor(2.0, 1.0, 2.0), 2.0 + 2.0 * 1.4826);
    }
}
