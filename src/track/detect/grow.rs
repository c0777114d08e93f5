//! Growing a detection seed (pixels that changed and move, Note S13's region of interest) to
//! the object's extent in frame n: the connected pixels whose flow, relative to the
//! background, lies within half of the seed's motion m of it (|f − m| < |m|/2), near a
//! changed pixel, inside the seed's box widened by |m| plus a margin. An estimated flow
//! spreads an object's motion into a halo that fades outwards; the rule cuts the halo where
//! it is half way to the background, and on an exact flow the region is the object. The
//! seed's motion is the flow vector on it that the frames confirm best.

use super::background::GlobalMotion;
use super::photometric::GreyPair;
use super::roi::padded_bbox;
use crate::track::robust;
use crate::types::Flow;

/// The grown region of `seed` (flat indices into `rel`, the flow relative to the
/// background, `[H, W]`) with the seed's `motion`: every pixel passes |f| > `threshold` and
/// |f − motion| < |motion|/2, is `allowed` (near a changed pixel), is not yet `claimed` by an
/// earlier region, and connects to a seed pixel that passes too. The pixels taken are marked
/// in `claimed`. Empty when no seed pixel passes.
#[allow(clippy::too_many_arguments)]
pub fn grow(
    seed: &[usize],
    motion: (f64, f64),
    rel: &Flow,
    threshold: f64,
    margin: usize,
    allowed: &[bool],
    claimed: &mut [bool],
) -> Vec<usize> {
    let (w, h) = (rel.width(), rel.height());
    let (u, v) = (rel.u(), rel.v());
    let (mu, mv) = motion;
    let mm = mu * mu + mv * mv;
    let passes = |p: usize, claimed: &[bool]| {
        let (fu, fv) = (u[p] as f64, v[p] as f64);
        fu.is_finite()
            && fv.is_finite()
            && fu.hypot(fv) > threshold
            && (fu - mu).powi(2) + (fv - mv).powi(2) < mm / 4.0
            && allowed[p]
            && !claimed[p]
    };
    let pad = mm.sqrt().ceil() as usize + margin;
    let Some([x0, y0, x1, y1]) = padded_bbox(seed, w, h, pad) else {
        return Vec::new();
    };
    let mut stack: Vec<usize> = seed
        .iter()
        .copied()
        .filter(|&p| passes(p, claimed))
        .collect();
    for &p in &stack {
        claimed[p] = true;
    }
    let mut out = Vec::new();
    while let Some(p) = stack.pop() {
        out.push(p);
        let (x, y) = (p % w, p / w);
        for ny in y.saturating_sub(1).max(y0)..=(y + 1).min(y1) {
            for nx in x.saturating_sub(1).max(x0)..=(x + 1).min(x1) {
                let q = ny * w + nx;
                if passes(q, claimed) {
                    claimed[q] = true;
                    stack.push(q);
                }
            }
        }
    }
    out.sort_unstable();
    out
}

/// The seed's motion relative to the background: of the flow vectors on the seed (up to
/// `candidates` of them, evenly spread, and their component-wise median), the one whose
/// constant shift best explains the change over the seed (least mean warp residual of
/// frame 2 against frame 1). A seed mixes the mover's pixels with the spurious flow of the
/// changed margin around it; the mover's motion is the one the frames confirm.
pub fn seed_motion(
    seed: &[usize],
    flow: &Flow,
    background: &GlobalMotion,
    pair: &GreyPair,
    candidates: usize,
) -> Option<(f64, f64)> {
    let w = flow.width();
    let (u, v) = (flow.u(), flow.v());
    let step = (seed.len() / candidates.max(1)).max(1);
    let mut tried: Vec<(f64, f64)> = seed
        .iter()
        .step_by(step)
        .filter(|&&p| u[p].is_finite() && v[p].is_finite())
        .map(|&p| (u[p] as f64, v[p] as f64))
        .collect();
    tried.extend(median_motion(seed, flow));
    let (sx, sy) = seed.iter().fold((0.0, 0.0), |(a, b), &p| {
        (a + (p % w) as f64, b + (p / w) as f64)
    });
    let n = seed.len().max(1) as f64;
    let (bu, bv) = background.at(sx / n, sy / n);
    tried
        .into_iter()
        .filter_map(|m| pair.residual_of(seed, m).map(|r| (r, m)))
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, (mu, mv))| (mu - bu, mv - bv))
}

/// The component-wise median of the known vectors of `rel` over `pixels`.
fn median_motion(pixels: &[usize], rel: &Flow) -> Option<(f64, f64)> {
    let (u, v) = (rel.u(), rel.v());
    let (mut us, mut vs): (Vec<f32>, Vec<f32>) = pixels
        .iter()
        .filter(|&&p| u[p].is_finite() && v[p].is_finite())
        .map(|&p| (u[p], v[p]))
        .unzip();
    let mu = robust::upper_median(&mut us)?;
    let mv = robust::upper_median(&mut vs)?;
    Some((mu as f64, mv as f64))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disc of radius 8 at (30, 20) moving (4, −2), with a halo that fades over 6 px
    /// (as an estimated flow smears a mover), and a separate still-background blob.
    fn halo_flow() -> Flow {
        let (w, h) = (64, 40);
        let mut f = Flow::zeros(h, w);
        for y in 0..h {
            for x in 0..w {
                let d = ((x as f64 - 30.0).powi(2) + (y as f64 - 20.0).powi(2)).sqrt();
                let s = if d <= 8.0 {
                    1.0
                } else {
                    (1.0 - (d - 8.0) / 12.0).max(0.0)
                };
                f.set(y, x, (4.0 * s) as f32, (-2.0 * s) as f32);
            }
        }
        for y in 2..8 {
            for x in 55..62 {
                f.set(y, x, -3.0, 0.0);
            }
        }
        f
    }

    #[test]
    fn the_halo_is_cut_at_the_midpoint_and_the_other_blob_stays_out() {
        let f = halo_flow();
        let w = 64;
        let seed: Vec<usize> = (17..23)
            .flat_map(|y| (28..33).map(move |x| y * w + x))
            .collect();
        let mut claimed = vec![false; w * 40];
        let all = vec![true; w * 40];
        let r = grow(&seed, (4.0, -2.0), &f, 0.5, 24, &all, &mut claimed);
        // The midpoint (half of the motion) lies 6 px outside the disc: radius 14.
        let area = std::f64::consts::PI * 14.0 * 14.0;
        assert!(
            (r.len() as f64 - area).abs() < 0.08 * area,
            "{} px, expected about {area:.0}",
            r.len()
        );
        let (cx, cy) = r.iter().fold((0.0, 0.0), |(sx, sy), &p| {
            (sx + (p % w) as f64, sy + (p / w) as f64)
        });
        let n = r.len() as f64;
        assert!((cx / n - 30.0).abs() < 0.3 && (cy / n - 20.0).abs() < 0.3);
        assert!(r.iter().all(|&p| p % w < 50), "grew into the far blob");
        // Claimed pixels are not taken twice.
        assert!(grow(&seed, (4.0, -2.0), &f, 0.5, 24, &all, &mut claimed).is_empty());
    }

    #[test]
    fn an_exact_flow_gives_the_object_exactly_and_the_box_bounds_the_growth() {
        let (w, h) = (50, 30);
        let mut f = Flow::zeros(h, w);
        // A 10-px-wide bar moving right, 40 px long: the seed at its left end.
        for y in 10..20 {
            for x in 5..45 {
                f.set(y, x, 2.0, 0.0);
            }
        }
        let seed: Vec<usize> = (12..16)
            .flat_map(|y| (6..9).map(move |x| y * w + x))
            .collect();
        let mut claimed = vec![false; w * h];
        let all = vec![true; w * h];
        let r = grow(&seed, (2.0, 0.0), &f, 0.5, 3, &all, &mut claimed);
        // The box: seed x 6..=8 widened by |m| = 2 plus 3 → x 1..=13, clipped to the bar.
        let xs: Vec<usize> = r.iter().map(|p| p % w).collect();
        assert_eq!(*xs.iter().min().unwrap(), 5);
        assert_eq!(*xs.iter().max().unwrap(), 13);
        assert_eq!(r.len(), 9 * 10, "columns 5..=13 of the bar's ten rows");
        // Still and unknown seeds grow nothing.
        let mut claimed = vec![false; w * h];
        assert!(grow(&[0, 1, 2], (2.0, 0.0), &f, 0.5, 3, &all, &mut claimed).is_empty());
        let mut nan = f.clone();
        nan.set(0, 0, f32::NAN, f32::NAN);
        assert!(grow(&[0], (2.0, 0.0), &nan, 0.5, 3, &all, &mut claimed).is_empty());
    }
}
