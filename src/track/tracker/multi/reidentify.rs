//! Re-identification at confirmation (DeepSORT's, with the region's mean colour as the
//! descriptor): a track just confirmed takes back the ID of an ended or coasting track whose
//! object it may be (`reid_cost`), the likeliest in colour and distance.

use super::Tracker;
use crate::track::tracker::reid::{Candidate, reid_cost};

impl Tracker {
    /// The ID that track `i`, confirmed in `frame`, takes back: that of the ended or coasting
    /// track whose object it may be at the least cost (`reid_cost`: colour and distance). A coasting
    /// track that gives up its ID ends; an ended one leaves the memory.
    pub(super) fn reidentify(&mut self, i: usize, frame: usize) -> Option<(usize, bool)> {
        if self.config.reid_frames == 0 {
            return None;
        }
        let t = &self.tracks[i];
        // The new track's mean colour is the query, however few colours it has: the distance
        // is measured in the old track's spread, which needs its own (`reid_cost`). A track
        // confirmed on a partial region has had only four whole ones (seen on a spiral lost for
        // 17 frames and found again with a new ID).
        let colour = t.appearance.as_ref()?.mean();
        let born = t.born;
        let config = &self.config;
        let (floor, k) = (config.appearance_floor, config.reid_k);
        let coasting = self.tracks.iter().enumerate().filter_map(|(j, o)| {
            let c = Candidate {
                last_seen: o.last_seen,
                top_speed: o.top_speed,
                gate: o.gate(config),
                appearance: o.appearance.as_ref()?,
            };
            let fresh = o.id == 0 || j == i || !o.confirmed || o.misses == 0;
            let k = (!fresh && frame.saturating_sub(o.last_seen.0) <= config.reid_frames)
                .then(|| reid_cost(&c, born, colour, floor, k))??;
            Some((k, Ok(j)))
        });
        let ended = self.lost.iter().enumerate().filter_map(|(j, l)| {
            let c = Candidate {
                last_seen: l.last_seen,
                top_speed: l.top_speed,
                gate: l.gate,
                appearance: &l.appearance,
            };
            Some((reid_cost(&c, born, colour, floor, k)?, Err(j)))
        });
        let best = coasting.chain(ended).min_by(|a, b| a.0.total_cmp(&b.0))?;
        Some(match best.1 {
            Ok(j) => {
                let o = &mut self.tracks[j];
                let id = o.id;
                // It gives its ID up and ends (not remembered: its object is found).
                o.id = 0;
                o.misses = usize::MAX;
                (id, true)
            }
            Err(j) => (self.lost.swap_remove(j).id, false),
        })
    }
}
