//! The motion-consistency test of a tentative track (Note S13's flow *is* the displacement to
//! the next frame): over the confirmation window, the centre must move as the sum of the
//! regions' flows says, or further along it for a flow that underestimates small movers. A
//! blob of spurious flow stays where it is while its flow says it moves, and fails.

use std::collections::VecDeque;

/// One hit of a tentative track: the region's centre and its mean flow (px/frame).
pub type Hit = ((f64, f64), (f64, f64));

/// The motion-consistency test of a tentative track (see `TrackerConfig`).
pub struct Consistency {
    pub px: f64,
    pub rel: f64,
    pub max_ratio: f64,
}

impl Consistency {
    /// Why a tentative track's window is not one moving object, or `None` when it is: the
    /// centre moved from the first to the last hit by the sum of the flows in between (the
    /// flow of frame n is the displacement to frame n + 1), within `px + rel × |sum|`, or
    /// further along the flows' direction (within 30°) by up to `max_ratio` times the sum.
    pub fn verdict(&self, window: &VecDeque<Hit>) -> Option<String> {
        let (first, last) = (window.front()?, window.back()?);
        let k = window.len() - 1;
        let (pu, pv) = window
            .iter()
            .take(k)
            .fold((0.0, 0.0), |a, w| (a.0 + w.1.0, a.1 + w.1.1));
        let (au, av) = (last.0.0 - first.0.0, last.0.1 - first.0.1);
        let err = (au - pu).hypot(av - pv);
        let (np, na) = (pu.hypot(pv), au.hypot(av));
        let tol = self.px + self.rel * np;
        let along = np > 0.0
            && na >= np
            && na <= self.max_ratio * np + self.px
            && au * pu + av * pv >= (30f64).to_radians().cos() * na * np;
        (err > tol && !along).then(|| {
            format!(
                "inconsistent motion over {k} frames: the centre moved ({au:.1}, {av:.1}) px, \
                 the flow says ({pu:.1}, {pv:.1}) px (off by {err:.1} > {tol:.1})"
            )
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mover_whose_flow_underestimates_it_is_confirmed_unless_it_goes_astray() {
        let window = |moved: (f64, f64), flow: (f64, f64)| -> VecDeque<Hit> {
            (0..5)
                .map(|k| {
                    let t = k as f64 / 4.0;
                    ((10.0 + moved.0 * t, 20.0 + moved.1 * t), flow)
                })
                .collect()
        };
        let c = Consistency {
            px: 2.0,
            rel: 0.3,
            max_ratio: 4.0,
        };
        // The flow says 2 px/frame (8 px over the window); the centre moved 20 px its way.
        assert!(c.verdict(&window((20.0, 0.0), (2.0, 0.0))).is_none());
        assert!(c.verdict(&window((17.0, 9.0), (2.0, 0.0))).is_none(), "28°");
        // Astray: the other way, at right angles, still, or far beyond the ratio.
        for moved in [(-20.0, 0.0), (0.0, 20.0), (0.3, 0.0), (60.0, 0.0)] {
            assert!(c.verdict(&window(moved, (2.0, 0.0))).is_some(), "{moved:?}");
        }
        // With the ratio at 1 the test is the symmetric one.
        let strict = Consistency {
            max_ratio: 1.0,
            ..c
        };
        assert!(strict.verdict(&window((20.0, 0.0), (2.0, 0.0))).is_some());
        assert!(strict.verdict(&window((9.0, 0.0), (2.0, 0.0))).is_none());
    }
}
