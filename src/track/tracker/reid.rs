//! Re-identification (Note S13's many objects; DeepSORT's, with the region's mean colour as
//! the descriptor): a confirmed track that ended, or that coasts, may be the object a new
//! track has found again. It is, where the new track was born after the old one was last
//! seen, within the distance its object could have gone since, and with its colour; of
//! several old tracks, the one whose colour and distance are nearer, each measured against
//! its own gate (DeepSORT's weighted sum of gated motion and appearance costs).

use super::appearance::Appearance;

/// How far past its top speed an object may have gone while unseen: the top speed is the
/// largest motion its detections showed (aligned by the frames where they were), so a quarter
/// more covers an object that sped up out of sight; twice the top speed let a track on one
/// object take the ID of another, slower one lost 8 frames before and 276 px away.
pub(crate) const REACH_SPEED_FACTOR: f64 = 1.25;

/// A confirmed track that ended, remembered so its object can take the ID back.
pub(crate) struct Lost {
    pub id: usize,
    /// The last frame with a whole detection and the filtered centre then.
    pub last_seen: (usize, (f64, f64)),
    /// The largest motion of its detections (px/frame).
    pub top_speed: f64,
    /// Its gate before coasting widened it (px): `TrackerConfig::gate_px`, or
    /// `associate::GATE_RADII` of its object's radius where that is less.
    pub gate: f64,
    pub appearance: Appearance,
}

/// What a re-identification compares of an old track: where and when it was last seen, how
/// fast its object went, its gate and what colour it had.
pub(crate) struct Candidate<'a> {
    pub last_seen: (usize, (f64, f64)),
    pub top_speed: f64,
    /// As `Lost::gate`.
    pub gate: f64,
    pub appearance: &'a Appearance,
}

/// The cost at which a new track, first detected at `born` (frame, centre) with mean colour
/// `colour`, may be the object of `c`: its colour distance (standard deviations of the old
/// track's colour, each at least `floor` levels) over `k`, plus its distance from where `c`
/// was last seen over the reach `c.gate` + `REACH_SPEED_FACTOR` × `c`'s top speed × the
/// frames between; each term is at most 1. The reach starts from the track's own gate, as
/// association's does: with `gate_px` whole, a 320×240 track whose disc (radius 8, 21.6 px
/// gate) was last seen a frame before took back its ID on another disc born 44 px away.
/// `None` where it cannot be: born before `c` was last seen, farther than the reach, or more
/// than `k` from its colour. The distance term tells two old tracks of one colour apart: on a
/// 320×240 clip a disc hidden for 30 frames came back 83 px from where its own track ended and
/// 254 px from where another disc's left the view, 1.3 and 1.2 of their spreads in colour. An
/// old track with too few colours is never re-identified.
pub(crate) fn reid_cost(
    c: &Candidate,
    born: (usize, (f64, f64)),
    colour: [f64; 3],
    floor: f64,
    k: f64,
) -> Option<f64> {
    let (then, at) = c.last_seen;
    if born.0 <= then || !c.appearance.is_mature() {
        return None;
    }
    let reach = c.gate + REACH_SPEED_FACTOR * c.top_speed * (born.0 - then) as f64;
    let dist = (born.1.0 - at.0).hypot(born.1.1 - at.1);
    let d = c.appearance.distance(colour, floor);
    (dist <= reach && d <= k).then_some(d / k + dist / reach)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn red() -> Appearance {
        let mut a = Appearance::new([200.0, 40.0, 40.0]);
        for n in 0..10 {
            a.update([200.0 + (n % 3) as f64, 40.0, 40.0 - (n % 2) as f64]);
        }
        a
    }

    #[test]
    fn a_new_track_is_the_old_object_only_if_it_could_have_got_there_in_its_colour() {
        let a = red();
        // Last seen at frame 20 at (100, 100), at most 3 px/frame: 40 + 3.75 px per frame.
        let c = Candidate {
            last_seen: (20, (100.0, 100.0)),
            top_speed: 3.0,
            gate: 40.0,
            appearance: &a,
        };
        let score = |born, colour| reid_cost(&c, born, colour, 8.0, 3.0);
        let same = [201.0, 41.0, 39.0];
        // Ten frames later, 75 px away (within 77.5): its colour, a small distance; nearer
        // where it was last seen, a smaller cost.
        let far = score((30, (175.0, 100.0)), same).expect("re-identified");
        let near = score((30, (120.0, 100.0)), same).expect("re-identified");
        assert!(far > 0.95 && far < 1.2, "{far}");
        assert!(near < far - 0.6, "{near} {far}");
        // 80 px away is farther than it could have gone (twice its top speed would reach 100
        // px); born before it was last seen, or in the frame it was, it is another object.
        assert_eq!(score((30, (180.0, 100.0)), same), None);
        assert_eq!(score((20, (101.0, 100.0)), same), None);
        assert_eq!(score((15, (101.0, 100.0)), same), None);
        // Green, where it could be: not it.
        assert_eq!(score((30, (120.0, 100.0)), [40.0, 190.0, 60.0]), None);
        // 30 levels off in red: 3.75 floors, over 3.
        assert_eq!(score((30, (120.0, 100.0)), [230.0, 40.0, 40.0]), None);
        // An old track with fewer than five colours is never re-identified.
        let young = Appearance::new([200.0, 40.0, 40.0]);
        let c = Candidate {
            appearance: &young,
            ..c
        };
        assert_eq!(reid_cost(&c, (30, (120.0, 100.0)), same, 8.0, 3.0), None);
        // A small object's gate (21.6 px for a disc of radius 8) starts the reach: a frame
        // after it was last seen, 44 px away is too far (40 + 3.75 would reach it).
        // (The old track's colour mature again.)
        let small = Candidate {
            gate: 21.6,
            appearance: &a,
            ..c
        };
        assert_eq!(
            reid_cost(&small, (21, (144.0, 100.0)), same, 8.0, 3.0),
            None
        );
        assert!(reid_cost(&small, (21, (124.0, 100.0)), same, 8.0, 3.0).is_some());
        let wide = Candidate {
            gate: 40.0,
            ..small
        };
        assert!(reid_cost(&wide, (21, (143.0, 100.0)), same, 8.0, 3.0).is_some());
    }
}
