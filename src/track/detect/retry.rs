//! The photometric test (Note S13's region confirmation) retried with the motion the frames
//! confirm: where an estimated flow falls short on a small mover (MMS gives a 16-px disc that
//! moves 5 px/frame 1–2 px/frame), warping frame 2 with it explains little of the change and
//! the region fails, frame after frame, though the frames show the object moving. Such a
//! region is retried with its aligned motion (`track::detect::align`) and, where that explains the
//! change, accepted as a *weak* detection: as ByteTrack's low-score detections, it continues a
//! track (`track::tracker::associate`; a tentative one too, by default) but starts none
//! (`track::tracker::multi`), so the spurious blobs a search over shifts can explain by chance make no
//! tracks.

use super::align::align;
use super::photometric::GreyPair;
use super::roi::Region;
use super::still_background::crowded;

/// The aligned motion must lie within this cosine of the flow's direction (about 45°) ...
const MIN_COSINE: f64 = 0.7;
/// ... and, as the disc's region must not border another (a mixture of two objects' motions),
/// no region of a quarter of its area or more may lie within this many times the sum of their
/// equivalent radii (the placement's crowd rule).
pub const CROWD: f64 = 2.5;

/// The motion that passes the test where the region's flow failed it: the aligned motion,
/// when it explains the region better than the mean flow, points the flow's way, is longer
/// than the flow (the flow underestimates; a blob that the search merely fits is not
/// longer), and its warp residual over `pixels` is at most `max_ratio` × `background` (the
/// residual with the background's motion, as in the test). Returns the motion and its ratio.
pub fn aligned_retry(
    pair: &GreyPair,
    pixels: &[usize],
    region: &Region,
    background: f64,
    max_ratio: f64,
    reach: usize,
    weights: [f64; 3],
) -> Option<((f64, f64), f64)> {
    if !(background.is_finite() && background > 0.0) {
        return None;
    }
    let f = region.mean_flow;
    let a = align(
        pair.first_colour(),
        pair.second_colour(),
        pixels,
        f,
        reach,
        weights,
    )?;
    let m = a.motion;
    let (lm, lf) = (m.0.hypot(m.1), f.0.hypot(f.1));
    let cosine = (m.0 * f.0 + m.1 * f.1) / (lm * lf).max(1e-12);
    if !(a.residual < a.start_residual && cosine >= MIN_COSINE && lm > lf) {
        return None;
    }
    let ratio = pair.residual_of(pixels, m)? / background;
    (ratio <= max_ratio).then_some((m, ratio))
}

/// The region after a retry passed: its flow is the aligned motion (the association's
/// velocity gate and the trajectory fits take it), and it is weak.
pub fn weak(region: &Region, motion: (f64, f64)) -> Region {
    let speed = motion.0.hypot(motion.1);
    Region {
        mean_flow: motion,
        speed,
        direction: (speed > 1e-9).then(|| motion.1.atan2(motion.0)),
        aligned: Some(motion),
        weak: true,
        ..region.clone()
    }
}

/// Which of `regions` (centroid, area) are retried ones (`retried`) beside another region.
pub fn crowded_retries(regions: &[((f64, f64), usize)], retried: &[bool]) -> Vec<bool> {
    (0..regions.len())
        .map(|i| retried[i] && crowded(regions, i, CROWD).is_some())
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::stream;
    use crate::types::Image;
    use rand_distr::{Distribution, StandardNormal};

    const W: usize = 128;
    const H: usize = 100;

    /// A still textured background and a textured disc of radius 12 at (60, 50) in frame 1,
    /// moved by `motion` in frame 2; noise of σ = 0.01.
    fn pair(motion: (f64, f64)) -> GreyPair {
        let bg = |x: f64, y: f64, c: usize| {
            0.35 + 0.12 * (x * 0.23 + c as f64).sin() * (y * 0.19 - c as f64).cos()
        };
        let obj = |x: f64, y: f64, c: usize| {
            0.55 + 0.2 * (x * 0.5 + 2.0 * c as f64).cos() * (y * 0.41).sin()
        };
        let mut rng = stream(5, &[3]);
        let mut draw = |centre: (f64, f64)| {
            let mut img = Image::zeros(3, H, W);
            for c in 0..3 {
                for y in 0..H {
                    for x in 0..W {
                        let (ox, oy) = (x as f64 - centre.0, y as f64 - centre.1);
                        let v = if ox.hypot(oy) <= 12.0 {
                            obj(ox, oy, c)
                        } else {
                            bg(x as f64, y as f64, c)
                        };
                        let n: f64 = StandardNormal.sample(&mut rng);
                        img.set(c, y, x, (v + 0.01 * n) as f32);
                    }
                }
            }
            img
        };
        let (a, b) = (draw((60.0, 50.0)), draw((60.0 + motion.0, 50.0 + motion.1)));
        GreyPair::new(&a, &b).expect("two frames of one size")
    }

    /// The pixels within `r` of `centre`, and a region there with the given mean flow.
    fn region(centre: (f64, f64), r: f64, flow: (f64, f64)) -> (Vec<usize>, Region) {
        let pixels: Vec<usize> = (0..W * H)
            .filter(|p| ((p % W) as f64 - centre.0).hypot((p / W) as f64 - centre.1) <= r)
            .collect();
        let speed = flow.0.hypot(flow.1);
        let region = Region {
            pixels: pixels.len(),
            centroid: centre,
            speed,
            direction: Some(flow.1.atan2(flow.0)),
            bbox: [0, 0, W - 1, H - 1],
            mean_flow: flow,
            placed: None,
            foreground: None,
            aligned: None,
            colour: None,
            weak: false,
        };
        (pixels, region)
    }

    /// The flow gives a sixth of a disc's motion, as MMS can on a small mover: its warp
    /// fails the photometric test; the aligned motion passes it, within a pixel of the true
    /// motion, and the weak region carries that motion.
    #[test]
    fn a_mover_whose_flow_falls_short_passes_with_the_frames_motion() {
        let motion = (5.0, 2.0);
        let p = pair(motion);
        let (pixels, r) = region((60.0, 50.0), 12.0, (0.8, 0.32));
        let still = p.residual_of(&pixels, (0.0, 0.0)).expect("inside");
        let with_flow = p.residual_of(&pixels, r.mean_flow).expect("inside") / still;
        assert!(with_flow > 0.8, "the flow's ratio {with_flow:.2}");
        let (m, ratio) = aligned_retry(&p, &pixels, &r, still, 0.8, 24, [0.25, 1.0, 0.25])
            .expect("the frames confirm the motion");
        assert!(
            ratio <= 0.8 && (m.0 - motion.0).hypot(m.1 - motion.1) < 1.0,
            "{m:?} {ratio}"
        );
        let w = weak(&r, m);
        assert!(w.weak && w.mean_flow == m && (w.speed - m.0.hypot(m.1)).abs() < 1e-12);
        assert_eq!(w.centroid, r.centroid);
    }

    /// No retry passes for a patch of the still background with spurious flow, nor for a
    /// mover whose flow points away from its motion.
    #[test]
    fn a_still_patch_and_a_contrary_flow_do_not_pass() {
        let p = pair((5.0, 2.0));
        let (pixels, r) = region((25.0, 25.0), 12.0, (1.5, 0.0));
        let still = p.residual_of(&pixels, (0.0, 0.0)).expect("inside");
        assert!(aligned_retry(&p, &pixels, &r, still, 0.8, 24, [0.25, 1.0, 0.25]).is_none());
        let (pixels, r) = region((60.0, 50.0), 12.0, (-1.25, -0.5));
        let still = p.residual_of(&pixels, (0.0, 0.0)).expect("inside");
        assert!(aligned_retry(&p, &pixels, &r, still, 0.8, 24, [0.25, 1.0, 0.25]).is_none());
        // No residual to compare with: nothing passes.
        assert!(aligned_retry(&p, &pixels, &r, 0.0, 0.8, 24, [0.25, 1.0, 0.25]).is_none());
    }

    /// A retried region beside another of a quarter of its area or more is crowded; a region
    /// that passed with its flow is never.
    #[test]
    fn a_retried_region_beside_another_is_crowded() {
        let regions = [
            ((100.0, 100.0), 800),
            ((130.0, 100.0), 300),
            ((400.0, 100.0), 800),
        ];
        assert_eq!(
            crowded_retries(&regions, &[true, false, true]),
            vec![true, false, false]
        );
        assert_eq!(
            crowded_retries(&regions, &[false, true, false]),
            vec![false, true, false]
        );
    }
}
