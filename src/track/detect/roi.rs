//! The region of interest of Note S13: pixels whose flow magnitude exceeds a threshold, grouped
//! into 8-connected components; per component its centroid (Eq. S17), mean speed (Eq. S18) and
//! direction. Eq. S19 averages atan2 values, which fails for motion near ±π (leftward: +179°
//! and −179° average to 0°); the direction here is the circular mean, the angle of the mean
//! unit vector, and undefined (None) when the vectors cancel or the object is still.

use crate::error::{Error, Result};
use crate::types::Flow;

/// One moving region.
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    pub pixels: usize,
    /// Eq. S17, pixels.
    pub centroid: (f64, f64),
    /// Eq. S18, pixels per frame.
    pub speed: f64,
    /// Circular mean of the flow directions, radians in (−π, π]; `None` when undefined.
    pub direction: Option<f64>,
    /// `[x_min, y_min, x_max, y_max]`.
    pub bbox: [usize; 4],
    /// Mean flow vector (px/frame): the region's displacement to the next frame.
    pub mean_flow: (f64, f64),
    /// The object's centre in the frame, when the still background found it
    /// (`track::detect::still_background`): the trajectory filter measures this instead of the
    /// flow's centroid, as does confirmation's consistency test; association keeps the
    /// flow's.
    pub placed: Option<(f64, f64)>,
    /// The foreground's centre when the still background found one too far from the flow's
    /// centroid to place the region there (`Placement::Far`): the tracker takes it for the
    /// object's centre where it lies nearer the track's prediction than the flow's centroid
    /// does, within `TrackerConfig::foreground_gate` of the region's radius of it.
    pub foreground: Option<(f64, f64)>,
    /// The region's motion (px/frame) that the frames confirm (`track::detect::align`), when the
    /// alignment ran and explained the frames better than the mean flow: the speed and
    /// direction samples of the trajectory fits (Eqs. S20–S21) take it for the flow's.
    pub aligned: Option<(f64, f64)>,
    /// The object's mean colour in frame n (8-bit levels, R, G, B; a grey frame's level three
    /// times) over a disc at its centre, when the frames were given (`FrameDetection::colour`):
    /// the tracker's appearance cue.
    pub colour: Option<[f64; 3]>,
    /// Accepted by the photometric test only with the motion the frames confirm, where the
    /// flow's own warp explained too little (`DetectConfig::retry_aligned`): as ByteTrack's
    /// low-score detections, it continues a confirmed track but starts none.
    pub weak: bool,
}

/// All regions with at least `min_area` pixels whose |flow| > `threshold`, largest first.
/// Unknown vectors (NaN, as readers return them) are not moving: they join no region.
pub fn regions(flow: &Flow, threshold: f64, min_area: usize) -> Result<Vec<Region>> {
    Ok(regions_of(flow, flow, threshold, min_area)?
        .into_iter()
        .map(|(r, _)| r)
        .collect())
}

/// Regions where |`test`| > `threshold`, each with its pixels (flat indices); the statistics
/// (speed, direction, mean flow) are those of `stats`, of the same size. With a background
/// model, `test` is the flow relative to the background and `stats` the flow in the image.
pub fn regions_of(
    test: &Flow,
    stats: &Flow,
    threshold: f64,
    min_area: usize,
) -> Result<Vec<(Region, Vec<usize>)>> {
    if !(threshold.is_finite() && threshold >= 0.0) {
        return Err(Error::invalid(
            "flow threshold",
            format!("must be finite and >= 0, got {threshold}"),
        ));
    }
    let (h, w) = (test.height(), test.width());
    if (stats.height(), stats.width()) != (h, w) {
        return Err(Error::shape(
            "region statistics flow",
            format!("{w}x{h}"),
            format!("{}x{}", stats.width(), stats.height()),
        ));
    }
    let moving: Vec<bool> = test
        .u()
        .iter()
        .zip(test.v())
        .zip(stats.u().iter().zip(stats.v()))
        .map(|((a, b), (c, d))| {
            let m = ((a * a + b * b) as f64).sqrt();
            m.is_finite() && m > threshold && c.is_finite() && d.is_finite()
        })
        .collect();
    Ok(regions_in(&moving, stats, min_area))
}

/// The 8-connected components of `moving` (`[H, W]` of `stats`) with at least `min_area`
/// pixels, each with its statistics from `stats` and its pixels, largest first.
fn regions_in(moving: &[bool], stats: &Flow, min_area: usize) -> Vec<(Region, Vec<usize>)> {
    let mut out: Vec<(Region, Vec<usize>)> = components(moving, stats.width(), stats.height())
        .into_iter()
        .filter(|m| m.len() >= min_area.max(1))
        .map(|m| (Region::of(&m, stats), m))
        .collect();
    out.sort_by_key(|r| std::cmp::Reverse(r.0.pixels));
    out
}

/// The 8-connected components of the `true` pixels of a `[h, w]` mask, as flat indices.
pub fn components(mask: &[bool], w: usize, h: usize) -> Vec<Vec<usize>> {
    let mut label = vec![false; h * w];
    let mut out = Vec::new();
    for start in 0..(h * w).min(mask.len()) {
        if !mask[start] || label[start] {
            continue;
        }
        label[start] = true;
        let mut stack = vec![start];
        let mut members = Vec::new();
        while let Some(p) = stack.pop() {
            members.push(p);
            let (x, y) = (p % w, p / w);
            for dy in -1i64..=1 {
                for dx in -1i64..=1 {
                    let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                    if nx >= 0 && ny >= 0 && (nx as usize) < w && (ny as usize) < h {
                        let q = ny as usize * w + nx as usize;
                        if mask[q] && !label[q] {
                            label[q] = true;
                            stack.push(q);
                        }
                    }
                }
            }
        }
        out.push(members);
    }
    out
}

/// The box `[x0, y0, x1, y1]` (inclusive) around `pixels` (flat indices into rows `w` wide),
/// widened by `pad` on every side and clipped to the `w × h` frame; `None` without pixels or
/// for an empty frame.
pub fn padded_bbox(pixels: &[usize], w: usize, h: usize, pad: usize) -> Option<[usize; 4]> {
    if pixels.is_empty() || w == 0 || h == 0 {
        return None;
    }
    let (mut x0, mut y0, mut x1, mut y1) = (usize::MAX, usize::MAX, 0, 0);
    for &p in pixels {
        let (x, y) = (p % w, p / w);
        (x0, y0, x1, y1) = (x0.min(x), y0.min(y), x1.max(x), y1.max(y));
    }
    Some([
        x0.saturating_sub(pad),
        y0.saturating_sub(pad),
        (x1 + pad).min(w - 1),
        (y1 + pad).min(h - 1),
    ])
}

impl Region {
    /// Its motion per frame when its flow spans `span` frames (a stream processed at uneven
    /// gaps): speed, mean flow and aligned motion divided by it; the direction stays.
    pub fn per_frame(mut self, span: f64) -> Region {
        self.speed /= span;
        self.mean_flow = (self.mean_flow.0 / span, self.mean_flow.1 / span);
        self.aligned = self.aligned.map(|(u, v)| (u / span, v / span));
        self
    }

    /// The statistics of `pixels` (flat indices into `stats`, none out of range, at least one).
    pub fn of(pixels: &[usize], stats: &Flow) -> Region {
        let w = stats.width();
        let (u, v) = (stats.u(), stats.v());
        let (mut sx, mut sy, mut ss, mut cx, mut cy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut su, mut sv) = (0.0, 0.0);
        let mut bbox = [usize::MAX, usize::MAX, 0, 0];
        for &p in pixels {
            let (x, y) = (p % w, p / w);
            let (fu, fv) = (u[p] as f64, v[p] as f64);
            let m = (fu * fu + fv * fv).sqrt();
            sx += x as f64;
            sy += y as f64;
            ss += m;
            su += fu;
            sv += fv;
            if m > 0.0 {
                cx += fu / m;
                cy += fv / m;
            }
            bbox = [
                bbox[0].min(x),
                bbox[1].min(y),
                bbox[2].max(x),
                bbox[3].max(y),
            ];
        }
        let nf = pixels.len().max(1) as f64;
        let resultant = (cx * cx + cy * cy).sqrt() / nf;
        Region {
            colour: None,
            weak: false,
            pixels: pixels.len(),
            centroid: (sx / nf, sy / nf),
            speed: ss / nf,
            direction: (resultant > 1e-9).then(|| cy.atan2(cx)),
            bbox,
            mean_flow: (su / nf, sv / nf),
            placed: None,
            foreground: None,
            aligned: None,
        }
    }
}

/// True when `point` lies within the equivalent radius √(area/π) of region `d`.
pub fn covers(d: &Region, point: (f64, f64)) -> bool {
    (d.centroid.0 - point.0).hypot(d.centroid.1 - point.1)
        <= (d.pixels as f64 / std::f64::consts::PI).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_vectors_belong_to_no_region() {
        let mut f = Flow::zeros(12, 12);
        for y in 0..12 {
            for x in 0..4 {
                f.set(y, x, f32::NAN, f32::NAN);
            }
            for x in 6..9 {
                f.set(y, x, 2.0, 0.0);
            }
            f.set(y, 10, f32::INFINITY, 0.0);
        }
        let r = regions(&f, 0.5, 5).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].pixels, 36);
        assert_eq!(r[0].bbox, [6, 0, 8, 11]);
        let all_unknown = Flow::from_vec(4, 4, vec![f32::NAN; 32]).unwrap();
        assert!(regions(&all_unknown, 0.0, 1).unwrap().is_empty());
    }

    #[test]
    fn largest_region_centroid_and_leftward_direction() {
        let mut f = Flow::zeros(20, 30);
        for y in 5..9 {
            for x in 10..16 {
                // Leftward with a little jitter across ±π: atan2 would average to ~0.
                let v = if (x + y) % 2 == 0 { 0.05 } else { -0.05 };
                f.set(y, x, -4.0, v);
            }
        }
        f.set(0, 0, 9.0, 0.0); // a one-pixel blip
        let r = regions(&f, 1.0, 2).unwrap();
        assert_eq!(r.len(), 1);
        assert_eq!(r[0].pixels, 24);
        assert!((r[0].centroid.0 - 12.5).abs() < 1e-12 && (r[0].centroid.1 - 6.5).abs() < 1e-12);
        let d = r[0].direction.unwrap();
        assert!(
            (d.abs() - std::f64::consts::PI).abs() < 0.02,
            "direction {d}"
        );
        assert!((r[0].speed - 4.0).abs() < 0.01);
    }

    #[test]
    fn still_objects_and_bad_flow() {
        let f = Flow::zeros(8, 8);
        assert!(regions(&f, 0.5, 1).unwrap().is_empty());
        // Threshold 0 with a zero vector inside is still: no direction, no NaN.
        let mut g = Flow::zeros(4, 4);
        g.set(1, 1, 1.0, 0.0);
        g.set(1, 2, -1.0, 0.0);
        let r = regions(&g, 0.0, 1).unwrap();
        assert!(r[0].direction.is_none());
        // An unknown vector is not moving; a bad threshold is an error.
        let mut unknown = Flow::zeros(4, 4);
        unknown.set(2, 2, f32::NAN, 0.0);
        assert!(regions(&unknown, 0.5, 1).unwrap().is_empty());
        for t in [-1.0, f64::NAN, f64::INFINITY] {
            assert!(regions(&f, t, 1).is_err(), "{t}");
        }
    }
}
