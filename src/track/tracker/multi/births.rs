//! Births (Movie S2): a detection no track took starts a tentative track, unless it lies on a
//! confirmed track's object (a fragment of it) or is weak (`track::detect::retry`: it continues a
//! track, never starts one).

use std::collections::VecDeque;

use super::{Assignment, Track, TrackEstimate, Tracker};
use crate::error::Result;
use crate::track::detect::roi::Region;
use crate::track::motion::mtp::Mtp;
use crate::track::motion::step::Step;
use crate::track::tracker::appearance::Appearance;
use crate::track::tracker::consistency::{hit, per_frame};

impl Tracker {
    /// Starts a tentative track on each detection of this frame that no track took (`used`);
    /// with a window of one frame (`confirm` 1) it is confirmed at once and reported in `out`.
    pub(super) fn births(
        &mut self,
        step: Step,
        detections: &[Region],
        used: &[bool],
        horizon: usize,
        out: &mut Vec<TrackEstimate>,
    ) -> Result<()> {
        let frame = step.frame();
        let exclusion = self.config.birth_exclusion_px;
        for (j, d) in detections.iter().enumerate() {
            // A weak detection (`track::detect::retry`) continues a track, never starts one.
            if used[j] || d.weak {
                continue;
            }
            if let Some(t) = self.tracks.iter().find(|t| {
                t.confirmed
                    && (t.centre.0 - d.centroid.0).hypot(t.centre.1 - d.centroid.1) <= exclusion
            }) {
                self.assignments[j] = Some(Assignment {
                    key: t.key,
                    id: Some(t.id),
                    state: "fragment",
                });
                continue;
            }
            let mut mtp = Mtp::new(self.config.mtp.clone())?;
            let e = mtp.step_at(step, Some(d), horizon)?;
            let mut t = Track {
                id: 0,
                born: (frame, d.centroid),
                last_seen: (frame, e.centroid),
                top_speed: 0.0,
                key: self.next_key,
                mtp,
                window: VecDeque::from([hit(d, step.span)]),
                last_motion: per_frame(d),
                hits: 1,
                misses: 0,
                confirmed: false,
                predicted: e.next,
                centre: e.centroid,
                areas: VecDeque::from([d.pixels]),
                appearance: d.colour.map(Appearance::new),
            };
            self.next_key += 1;
            // With a window of one frame there is nothing to compare: confirmed at once.
            if self.config.confirm <= 1 {
                t.confirmed = true;
                t.id = self.next_id;
                self.next_id += 1;
                out.push(TrackEstimate {
                    id: t.id,
                    estimate: e,
                    observed: true,
                });
            }
            self.assignments[j] = Some(Assignment {
                key: t.key,
                id: t.confirmed.then_some(t.id),
                state: "new",
            });
            self.tracks.push(t);
        }
        Ok(())
    }
}
