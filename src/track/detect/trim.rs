//! Trimming a grown region to its object (Note S13's region of interest, whose centroid is
//! Eq. S17's): an estimated flow smears a mover's motion over the background around it, most
//! where the object uncovers background, and that halo drags the centroid behind the object.
//! A pixel of the region whose neighbourhood the background's motion explains clearly better
//! than the region's own motion (the box-averaged warp residual lower by more than `margin`)
//! is background and leaves the region. Pixels that neither motion explains better, such as
//! the uniform inside of an object, look the same under either warp and stay.

use super::background::GlobalMotion;
use super::photometric::GreyPair;
use super::roi::padded_bbox;
use crate::imaging::box_filter::box_mean;

/// The pixels of `region` (flat indices, sorted or not) that the region's `motion`
/// (relative to `background`) explains at least as well as the background's motion, their
/// warp residuals averaged over the `(2·radius + 1)²` box around each pixel. When fewer than a
/// quarter of the pixels would stay, the region is returned whole: the test then disagrees
/// with the detection too much to be trusted over it.
pub fn trim(
    region: &[usize],
    motion: (f64, f64),
    background: &GlobalMotion,
    pair: &GreyPair,
    radius: usize,
    margin: f64,
) -> Vec<usize> {
    let (w, h) = (pair.width, pair.height);
    // The residual planes over the region's box, padded by the filter's radius.
    let Some([x0, y0, x1, y1]) = padded_bbox(region, w, h, radius) else {
        return region.to_vec();
    };
    let (bw, bh) = (x1 - x0 + 1, y1 - y0 + 1);
    let mut still = vec![f32::NAN; bw * bh]; // [bh, bw]: the background's motion
    let mut moved = vec![f32::NAN; bw * bh]; // [bh, bw]: the background's plus the region's
    for by in 0..bh {
        for bx in 0..bw {
            let (x, y) = (x0 + bx, y0 + by);
            let p = y * w + x;
            let (bu, bv) = background.at(x as f64, y as f64);
            let q = by * bw + bx;
            if let Some(r) = pair.residual_at(p, (bu, bv)) {
                still[q] = r as f32;
            }
            if let Some(r) = pair.residual_at(p, (bu + motion.0, bv + motion.1)) {
                moved[q] = r as f32;
            }
        }
    }
    let (still, _) = box_mean(&still, bw, bh, radius);
    let (moved, _) = box_mean(&moved, bw, bh, radius);
    let kept: Vec<usize> = region
        .iter()
        .copied()
        .filter(|&p| {
            let q = (p / w - y0) * bw + (p % w - x0);
            let (s, m) = (still[q] as f64, moved[q] as f64);
            // Unknown residuals (a warp out of the frame) decide nothing.
            !(s.is_finite() && m.is_finite() && s + margin < m)
        })
        .collect();
    if kept.len() * 4 < region.len() {
        region.to_vec()
    } else {
        kept
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Image;

    /// A textured 12×12 square at x = 20 moved 4 px right over a textured still background,
    /// and the region an estimated flow would give: the square with a 10 px halo behind it
    /// and a 4 px halo ahead.
    fn scene() -> (GreyPair, Vec<usize>, usize) {
        let (w, h) = (72, 40);
        let tex = |x: f32, y: f32| 0.4 + 0.15 * (x * 0.9).sin() * (y * 0.7).cos();
        let obj = |x: f32, y: f32| 0.6 + 0.2 * (x * 1.3 + 0.5).cos() * (y * 0.8).sin();
        let inside =
            |x: f32, y: f32, x0: f32| (x0..x0 + 12.0).contains(&x) && (14.0..26.0).contains(&y);
        let (mut a, mut b) = (Image::zeros(1, h, w), Image::zeros(1, h, w));
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32, y as f32);
                a.set(
                    0,
                    y,
                    x,
                    if inside(xf, yf, 20.0) {
                        obj(xf, yf)
                    } else {
                        tex(xf, yf)
                    },
                );
                b.set(
                    0,
                    y,
                    x,
                    if inside(xf, yf, 24.0) {
                        obj(xf - 4.0, yf)
                    } else {
                        tex(xf, yf)
                    },
                );
            }
        }
        let region = (14..26)
            .flat_map(|y| (10..36).map(move |x| y * w + x))
            .collect();
        (GreyPair::new(&a, &b).expect("frames"), region, w)
    }

    fn centre_x(pixels: &[usize], w: usize) -> f64 {
        pixels.iter().map(|&p| (p % w) as f64).sum::<f64>() / pixels.len() as f64
    }

    #[test]
    fn the_halo_leaves_and_the_object_stays() {
        let (pair, region, w) = scene();
        let kept = trim(&region, (4.0, 0.0), &GlobalMotion::zero(), &pair, 1, 0.005);
        // The square's own pixels stay, apart from the filter's reach at its edges.
        let square: Vec<usize> = region
            .iter()
            .copied()
            .filter(|&p| (22..30).contains(&(p % w)) && (15..25).contains(&(p / w)))
            .collect();
        let lost: Vec<(usize, usize)> = square
            .iter()
            .filter(|p| !kept.contains(p))
            .map(|p| (p % w, p / w))
            .collect();
        assert!(lost.is_empty(), "the square lost {lost:?}");
        // The halo behind the square (the background it uncovers) leaves.
        let behind = kept.iter().filter(|&&p| p % w < 18).count();
        assert_eq!(behind, 0, "{behind} halo pixels behind the square stay");
        // The halo drags the region's centroid 3 px behind the square's (25.5); the trimmed
        // region's is within 2 px of it.
        assert!((centre_x(&region, w) - 25.5).abs() > 2.5);
        let c = centre_x(&kept, w);
        assert!((c - 25.5).abs() < 2.0, "centroid {c}");
    }

    #[test]
    fn a_region_the_test_would_mostly_remove_stays_whole() {
        let (pair, region, _) = scene();
        // A wrong motion explains nothing: most pixels fail, so the region is kept whole.
        let kept = trim(&region, (-9.0, 5.0), &GlobalMotion::zero(), &pair, 1, 0.005);
        assert_eq!(kept, region);
        assert!(trim(&[], (1.0, 0.0), &GlobalMotion::zero(), &pair, 1, 0.0).is_empty());
    }
}
