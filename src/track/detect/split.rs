//! Splitting a merged region between the tracks it hides (Note S13's many objects, Movie S2):
//! where two movers meet, an estimated flow joins them into one blob whose centre and flow
//! belong to neither. With a still camera the frame still shows both: from each hidden
//! track's prediction, the mean shift on the foreground (`track::detect::still_background`) finds its
//! object, and the region becomes one part per track, each placed on its object. Where the
//! foreground shows only one object near both predictions (one hides the other), the region
//! stays whole and the tracks on it coast (`track::tracker::associate`'s merge).

use super::roi::{Region, covers};

/// A confirmed track where it is expected in this frame: the seeds of a split.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seed {
    /// Its one-frame-ahead prediction (px).
    pub at: (f64, f64),
    /// Its object's radius (px): the equivalent radius of its recent regions.
    pub radius: f64,
    /// Its position filter's velocity (px/frame).
    pub velocity: (f64, f64),
}

/// The seeds whose prediction lies inside `region` (within its equivalent radius).
pub fn covered(region: &Region, seeds: &[Seed]) -> Vec<Seed> {
    seeds
        .iter()
        .filter(|s| covers(region, s.at))
        .copied()
        .collect()
}

/// One part of a region split between `n` tracks: placed at `at`, the object the mean shift
/// found from `seed`, with its share of the pixels. The part's motion is the seed's velocity
/// (the merged region's flow is the two objects' mixture), so the association's motion gate
/// keeps it from a track that moves otherwise; it carries no direction sample, so the track's
/// filter is not fed its own velocity back, and no aligned motion.
pub fn part(region: &Region, seed: &Seed, at: (f64, f64), n: usize) -> Region {
    let v = seed.velocity;
    Region {
        pixels: (region.pixels / n.max(1)).max(1),
        centroid: at,
        speed: v.0.hypot(v.1),
        direction: None,
        mean_flow: v,
        placed: Some(at),
        foreground: None,
        aligned: None,
        colour: None,
        ..region.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn region(centre: (f64, f64), pixels: usize) -> Region {
        Region {
            colour: Some([10.0, 20.0, 30.0]),
            pixels,
            centroid: centre,
            speed: 1.0,
            direction: Some(0.0),
            bbox: [10, 10, 90, 60],
            mean_flow: (1.0, 0.0),
            placed: None,
            foreground: Some((1.0, 1.0)),
            aligned: Some((2.0, 0.0)),
            weak: false,
        }
    }

    #[test]
    fn a_region_covers_the_predictions_within_its_radius() {
        // Equivalent radius √(1257/π) ≈ 20 px.
        let r = region((50.0, 35.0), 1257);
        let seed = |x: f64| Seed {
            at: (x, 35.0),
            radius: 12.0,
            velocity: (1.0, 0.0),
        };
        let got = covered(&r, &[seed(35.0), seed(69.0), seed(71.0), seed(29.0)]);
        assert_eq!(got, vec![seed(35.0), seed(69.0)]);
    }

    #[test]
    fn a_part_is_placed_on_its_object_and_moves_as_its_track() {
        let r = region((50.0, 35.0), 1001);
        let s = Seed {
            at: (40.0, 30.0),
            radius: 12.0,
            velocity: (-3.0, 4.0),
        };
        let p = part(&r, &s, (38.5, 31.0), 2);
        assert_eq!(p.centroid, (38.5, 31.0));
        assert_eq!(p.placed, Some((38.5, 31.0)));
        assert_eq!(p.pixels, 500);
        assert_eq!(p.mean_flow, (-3.0, 4.0));
        assert!((p.speed - 5.0).abs() < 1e-12);
        assert_eq!(
            (p.direction, p.aligned, p.foreground, p.colour),
            (None, None, None, None)
        );
        assert_eq!(p.bbox, r.bbox);
        assert_eq!(part(&region((0.0, 0.0), 1), &s, (0.0, 0.0), 3).pixels, 1);
    }
}
