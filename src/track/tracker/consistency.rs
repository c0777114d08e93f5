//! The motion-consistency test of a tentative track (Note S13's flow *is* the displacement to
//! the next frame): over the confirmation window, the centre must move as the sum of the
//! regions' flows says, or further along it for a flow that underestimates small movers, or,
//! where the frames measured the regions' motion (`track::detect::align`), as that motion says and
//! clearly away from where it started. A blob of spurious flow stays where it is while its
//! flow says it moves, and fails both.

use std::collections::VecDeque;

use crate::track::detect::roi::Region;

/// One hit of a tentative track: the region's centre, its mean flow and the motion the frames
/// confirm (the aligned motion where the alignment ran, the mean flow otherwise), px to the
/// next processed frame.
pub type Hit = ((f64, f64), (f64, f64), (f64, f64));

/// A tentative track's hit on `d` for the consistency test: the object's centre and motion as
/// the frames measure them (the placed centre, the aligned motion) besides the flow's mean (a
/// flow that gives a small mover a third of its motion would otherwise hold it back for as long
/// as it is seen), the motions taken over `span` stream frames, to the next processed frame.
pub fn hit(d: &Region, span: f64) -> Hit {
    let ((fu, fv), (au, av)) = per_frame(d);
    (
        d.placed.unwrap_or(d.centroid),
        (fu * span, fv * span),
        (au * span, av * span),
    )
}

/// A detection's motions per stream frame: its mean flow and the motion the frames confirm.
pub fn per_frame(d: &Region) -> ((f64, f64), (f64, f64)) {
    (d.mean_flow, d.aligned.unwrap_or(d.mean_flow))
}

/// The motion-consistency test of a tentative track (see `TrackerConfig`).
pub struct Consistency {
    pub px: f64,
    pub rel: f64,
    pub max_ratio: f64,
}

/// The centre's displacement over a window against the sum of one motion's samples.
struct Offset {
    /// The centre's displacement, first to last hit.
    moved: (f64, f64),
    /// The sum of the motions of every hit but the last (each is the move to the next frame).
    said: (f64, f64),
    err: f64,
    tol: f64,
}

impl Consistency {
    fn offset(
        &self,
        window: &VecDeque<Hit>,
        motion: impl Fn(&Hit) -> (f64, f64),
    ) -> Option<Offset> {
        let (first, last) = (window.front()?, window.back()?);
        let said = window
            .iter()
            .take(window.len() - 1)
            .map(motion)
            .fold((0.0, 0.0), |a, m| (a.0 + m.0, a.1 + m.1));
        let moved = (last.0.0 - first.0.0, last.0.1 - first.0.1);
        let err = (moved.0 - said.0).hypot(moved.1 - said.1);
        let tol = self.px + self.rel * said.0.hypot(said.1);
        Some(Offset {
            moved,
            said,
            err,
            tol,
        })
    }

    /// Why a tentative track's window is not one moving object, or `None` when it is. The
    /// centre moved from the first to the last hit by the sum of the flows in between (the
    /// flow of frame n is the displacement to frame n + 1), within `px + rel × |sum|`, or
    /// further along the flows' direction (within 30°) by up to `max_ratio` times the sum; or
    /// it moved by the sum of the frames' motions within the same tolerance, and by more than
    /// that tolerance (a region the frames see standing still is no mover, whatever its
    /// flow).
    pub fn verdict(&self, window: &VecDeque<Hit>) -> Option<String> {
        let flow = self.offset(window, |h| h.1)?;
        let ((au, av), (pu, pv)) = (flow.moved, flow.said);
        let (np, na) = (pu.hypot(pv), au.hypot(av));
        let along = np > 0.0
            && na >= np
            && na <= self.max_ratio * np + self.px
            && au * pu + av * pv >= (30f64).to_radians().cos() * na * np;
        if flow.err <= flow.tol || along {
            return None;
        }
        let frames = self.offset(window, |h| h.2)?;
        if frames.err <= frames.tol && na > frames.tol {
            return None;
        }
        let k = window.len() - 1;
        let (fu, fv) = frames.said;
        let (fe, ft) = (frames.err, frames.tol);
        let by_frames = if fe > ft {
            format!("off by {fe:.1} > {ft:.1}")
        } else {
            format!("agreed, but it moved {na:.1} <= {ft:.1} px: standing still")
        };
        Some(format!(
            "inconsistent motion over {k} frames: the centre moved ({au:.1}, {av:.1}) px, the \
             flow says ({pu:.1}, {pv:.1}) px (off by {:.1} > {:.1}), the frames ({fu:.1}, \
             {fv:.1}) px ({by_frames})",
            flow.err, flow.tol
        ))
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
                    ((10.0 + moved.0 * t, 20.0 + moved.1 * t), flow, flow)
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

    #[test]
    fn the_frames_motion_confirms_a_mover_the_flow_underestimates_not_a_still_blob() {
        let window = |moved: f64, flow: f64, frames: f64| -> VecDeque<Hit> {
            (0..5)
                .map(|k| {
                    (
                        (10.0 + moved * k as f64 / 4.0, 20.0),
                        (flow, 0.0),
                        (frames, 0.0),
                    )
                })
                .collect()
        };
        let c = Consistency {
            px: 2.0,
            rel: 0.3,
            max_ratio: 1.0,
        };
        // 12 px/frame seen as 4 by the flow: held on the flow, confirmed on the frames.
        assert!(c.verdict(&window(48.0, 4.0, 4.0)).is_some());
        assert!(c.verdict(&window(48.0, 4.0, 12.0)).is_none());
        // The frames' motion must be right too: 12 px/frame measured as 6 is not.
        assert!(c.verdict(&window(48.0, 4.0, 6.0)).is_some());
        // A still blob whose flow says 4 px/frame and whose frames say 0.1: the frames agree
        // with its centre, but it did not move, so it is no mover.
        let reason = c.verdict(&window(0.0, 4.0, 0.1)).expect("held");
        assert!(reason.contains("the frames (0.4, 0.0)"), "{reason}");
        assert!(reason.contains("standing still"), "{reason}");
        let reason = c.verdict(&window(48.0, 4.0, 6.0)).expect("held");
        assert!(
            reason.contains("the frames (24.0, 0.0) px (off by 24.0"),
            "{reason}"
        );
        // A slow mover whose flow is right passes on the flow alone.
        assert!(c.verdict(&window(2.0, 0.5, 0.1)).is_none());
    }
}
