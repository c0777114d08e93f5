//! The tracker's appearance cue (Note S13's many objects; as DeepSORT's, with the simplest
//! descriptor): each track
//! keeps the running mean and variance of its object's colour in the frame
//! (`Region::colour`), and a detection whose colour lies too many standard deviations from
//! it is not the track's object. Two small discs that cross have the same speed and place for
//! a few frames; a coasting track whose flow underestimates its object then takes the other
//! one's detection unless their colours tell them apart.

/// A track's colour: exponentially weighted mean and variance per channel (8-bit levels).
#[derive(Clone, Debug, PartialEq)]
pub struct Appearance {
    mean: [f64; 3],
    var: [f64; 3],
    samples: usize,
}

/// Samples before the cue is used (the variance needs a few).
const MIN_SAMPLES: usize = 5;
/// The weight of a new sample once the mean has seen 1/`MIN_WEIGHT` of them (a colour drifts
/// as the object crosses a varying background).
const MIN_WEIGHT: f64 = 0.1;

impl Appearance {
    pub fn new(colour: [f64; 3]) -> Self {
        Self {
            mean: colour,
            var: [0.0; 3],
            samples: 1,
        }
    }

    /// Adds one observation of the object's colour.
    pub fn update(&mut self, colour: [f64; 3]) {
        if colour.iter().any(|c| !c.is_finite()) {
            return;
        }
        self.samples += 1;
        let a = (1.0 / self.samples as f64).max(MIN_WEIGHT);
        for ((m, v), x) in self.mean.iter_mut().zip(self.var.iter_mut()).zip(colour) {
            let d = x - *m;
            *m += a * d;
            *v = (1.0 - a) * (*v + a * d * d);
        }
    }

    /// The running mean colour (8-bit levels per channel).
    pub fn mean(&self) -> [f64; 3] {
        self.mean
    }

    /// Whether enough colours have been seen for the cue to be used.
    pub fn is_mature(&self) -> bool {
        self.samples >= MIN_SAMPLES
    }

    /// √Σ_c (colour_c − mean_c)² / (var_c + floor²): the colour's distance in standard
    /// deviations, each at least `floor` levels (sensor noise, the disc's placement).
    pub fn distance(&self, colour: [f64; 3], floor: f64) -> f64 {
        (0..3)
            .map(|c| (colour[c] - self.mean[c]).powi(2) / (self.var[c] + floor * floor))
            .sum::<f64>()
            .sqrt()
    }

    /// The colour's `distance`, or 0 before `MIN_SAMPLES` observations or without a colour.
    pub fn cost(&self, colour: Option<[f64; 3]>, floor: f64) -> f64 {
        match colour {
            Some(c) if self.samples >= MIN_SAMPLES => self.distance(c, floor),
            _ => 0.0,
        }
    }

    /// Whether `colour` may be this object's: always, until `MIN_SAMPLES` observations, or
    /// without a colour; otherwise within `k` of `distance`.
    pub fn admits(&self, colour: Option<[f64; 3]>, k: f64, floor: f64) -> bool {
        self.cost(colour, floor) <= k
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_different_colour_is_refused_and_the_same_one_with_its_drift_is_not() {
        let mut a = Appearance::new([90.0, 20.0, 95.0]);
        // Before five samples everything passes.
        assert!(a.admits(Some([90.0, 62.0, 109.0]), 4.0, 4.0));
        for k in 0..20 {
            let wobble = if k % 2 == 0 { 6.0 } else { -6.0 };
            a.update([90.0 + wobble, 20.0 + 0.5 * wobble, 95.0 + 2.0 * wobble]);
        }
        // The same object, a little off: admitted.
        assert!(a.admits(Some([96.0, 23.0, 110.0]), 4.0, 4.0));
        // Another disc (green 62 against 20, as two objects of the five-object clip): refused.
        assert!(!a.admits(Some([89.0, 62.0, 109.0]), 4.0, 4.0));
        assert!(a.distance([89.0, 62.0, 109.0], 4.0) > 8.0);
        // No colour, or an infinite gate: admitted.
        assert!(a.admits(None, 4.0, 4.0));
        assert!(a.admits(Some([0.0, 255.0, 0.0]), f64::INFINITY, 4.0));
        // A non-finite sample changes nothing.
        let before = a.clone();
        a.update([f64::NAN, 0.0, 0.0]);
        assert_eq!(a, before);
    }
}
