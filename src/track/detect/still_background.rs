//! Where a detected region's object is (Note S13's centroid, Eq. S17), measured on the frame
//! rather than on the flow: with a still camera, the background is the per-pixel temporal
//! median of the last frames, and the object is where frame n differs from it. An estimated
//! flow smears a small mover's motion into a blob that is neither its shape nor centred on it
//! (on the Table S5 clips its centroid is 5–7 px RMS off the object's); the difference from
//! the background is centred on the object. Each accepted region's centroid moves to the mode
//! of the foreground weight near it, found by mean shift (Comaniciu & Meer 2002) in a disc of
//! the region's equivalent radius, and keeps its flow centroid where the foreground does not
//! confirm it (an object that stopped and joined the background, one hidden by another, a
//! camera that moves). The median leaves out, in each stored frame, the discs where that
//! frame's objects were (selective update, as in Koller et al. 1994 and Stauffer & Grimson
//! 1999): a mover slower than its own diameter per half window otherwise stays in its
//! background, and the foreground shows only its leading part. The foreground and the mean
//! shift are `track::detect::foreground`'s; this file keeps the frames, their objects and the verdicts.

use std::collections::VecDeque;

use super::foreground::{Covered, Foreground};
pub use super::placement::{ColourFrame, PlaceConfig, Placement};
use crate::error::Result;

/// The still camera's recent frames.
pub struct StillBackground {
    cfg: PlaceConfig,
    frames: VecDeque<ColourFrame>,
    /// Where each stored frame's objects were, `covered[i]` for `frames[i]`.
    covered: VecDeque<Covered>,
}

impl StillBackground {
    pub fn new(cfg: PlaceConfig) -> Result<Self> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            frames: VecDeque::new(),
            covered: VecDeque::new(),
        })
    }

    /// Places each region (its flow centroid and area in pixels) on frame n's foreground,
    /// then keeps frame n for the model. `camera_motion`: the background's fitted motion
    /// (px/frame, its largest over the frame) that the frames support; above
    /// `max_camera_motion` the model starts over and nothing is placed.
    pub fn place(
        &mut self,
        frame: &ColourFrame,
        camera_motion: f64,
        regions: &[((f64, f64), usize)],
    ) -> Vec<Placement> {
        self.place_or_split(frame, camera_motion, regions, &[], &[])
    }

    /// As `place`, and each region with two or more seeds (the predictions and radii of the
    /// tracks it hides, `seeds[i]` for region i; a shorter list means none) is split between
    /// them where the foreground shows an object near each (`Placement::Split`): the
    /// mean shift from each seed must be placed (within `max_shift` of its radius) and the
    /// centres lie at least `split` × the sum of their radii apart. A region marked `pending`
    /// (`pending[i]`; a shorter list means none) stands only if it is placed on an object of
    /// its own (`Placement::Moved`): otherwise its crowd is placed again without it, it gets
    /// `Kept`, and it masks nothing in the frame's background.
    pub fn place_or_split(
        &mut self,
        frame: &ColourFrame,
        camera_motion: f64,
        regions: &[((f64, f64), usize)],
        seeds: &[Vec<((f64, f64), f64)>],
        pending: &[bool],
    ) -> Vec<Placement> {
        let is_pending = |i: usize| pending.get(i).copied().unwrap_or(false);
        let cfg = &self.cfg;
        let kept = |why: String| vec![Placement::Kept(why); regions.len()];
        let out = if camera_motion > cfg.max_camera_motion {
            self.frames.clear();
            self.covered.clear();
            kept(format!("the camera moves ({camera_motion:.2} px/frame)"))
        } else if self.frames.front().is_some_and(|f| {
            (f.width, f.height, f.channels) != (frame.width, frame.height, frame.channels)
        }) {
            self.frames.clear();
            self.covered.clear();
            kept("the frame size changed".into())
        } else if self.frames.len() < cfg.min_frames {
            kept(format!(
                "the background has {} of {} frames",
                self.frames.len(),
                cfg.min_frames
            ))
        } else {
            // The foreground (its noise floor alone is a thousand medians) only for a frame
            // with a region to place.
            let foreground = || {
                Foreground::new(
                    &self.frames,
                    &self.covered,
                    frame,
                    cfg.window,
                    cfg.k,
                    cfg.noise(),
                )
            };
            let mut fg = None;
            let mut out: Vec<Option<Placement>> = regions
                .iter()
                .enumerate()
                .map(|(i, _)| {
                    let mine = seeds.get(i).map_or(&[][..], Vec::as_slice);
                    if cfg.split > 0.0 && mine.len() >= 2 {
                        let fg = fg.get_or_insert_with(foreground);
                        if let Some(to) = fg.split(mine, cfg) {
                            return Some(Placement::Split { to });
                        }
                    }
                    None
                })
                .collect();
            // The rest in crowds (`crowds`), each crowd placed at once; a region alone is a
            // crowd of one.
            let free: Vec<usize> = (0..regions.len()).filter(|&i| out[i].is_none()).collect();
            for mut crowd in crowds(regions, &free, cfg.crowd) {
                let fg = fg.get_or_insert_with(foreground);
                // A pending member the foreground does not place on an object of its own
                // (a piece of a neighbour's object, or no object) leaves the crowd, and the
                // rest is placed again without it.
                while !crowd.is_empty() {
                    let starts: Vec<((f64, f64), usize)> =
                        crowd.iter().map(|&i| regions[i]).collect();
                    let placed = fg.place_jointly(&starts, cfg);
                    let refused = |i: usize, p: &Placement| {
                        is_pending(i) && !matches!(p, Placement::Moved { .. })
                    };
                    if !crowd.iter().zip(&placed).any(|(&i, p)| refused(i, p)) {
                        for (&i, p) in crowd.iter().zip(placed) {
                            out[i] = Some(p);
                        }
                        break;
                    }
                    for (&i, p) in crowd.iter().zip(&placed) {
                        if refused(i, p) {
                            out[i] = Some(Placement::Kept(format!(
                                "not placed on an object of its own ({})",
                                p.describe()
                            )));
                        }
                    }
                    crowd.retain(|&i| out[i].is_none());
                }
            }
            out.into_iter()
                .map(|p| p.unwrap_or_else(|| Placement::Kept("not placed".into())))
                .collect()
        };
        let covered = match self.cfg.mask {
            m if m > 0.0 => covered(regions, seeds, &out, m, is_pending),
            _ => Vec::new(),
        };
        self.frames.push_back(frame.clone());
        self.covered.push_back(covered);
        while self.frames.len() > self.cfg.frames {
            self.frames.pop_front();
            self.covered.pop_front();
        }
        out
    }
}

/// The discs frame n's objects cover, `mask` × their equivalent radius about where each was
/// placed (its flow centroid where it was not; each part of a split about its own centre); a
/// pending region covers something only where it was placed.
fn covered(
    regions: &[((f64, f64), usize)],
    seeds: &[Vec<((f64, f64), f64)>],
    placed: &[Placement],
    mask: f64,
    pending: impl Fn(usize) -> bool,
) -> Covered {
    let radius = equivalent_radius;
    let mut out = Vec::with_capacity(regions.len());
    for (i, &(c, area)) in regions.iter().enumerate() {
        if pending(i) && !matches!(placed.get(i), Some(Placement::Moved { .. })) {
            continue;
        }
        match placed.get(i) {
            Some(Placement::Split { to }) => {
                let mine = seeds.get(i).map_or(&[][..], Vec::as_slice);
                out.extend(to.iter().zip(mine).map(|(&p, &(_, r))| (p, mask * r)));
            }
            Some(Placement::Moved { to }) => out.push((*to, mask * radius(area))),
            _ => out.push((c, mask * radius(area))),
        }
    }
    out
}

/// The radius of a disc of `area` pixels.
fn equivalent_radius(area: usize) -> f64 {
    (area as f64 / std::f64::consts::PI).sqrt()
}

/// The `members` (indices into `regions`) grouped into crowds: two regions are in one when
/// they lie within `factor` × the sum of their equivalent radii of each other
/// (`PlaceConfig::crowd`), and so on transitively; each crowd in index order, the crowds in
/// the order of their first members.
fn crowds(regions: &[((f64, f64), usize)], members: &[usize], factor: f64) -> Vec<Vec<usize>> {
    let radius = equivalent_radius;
    let near = |i: usize, j: usize| {
        let (((x, y), a), ((u, v), b)) = (regions[i], regions[j]);
        (u - x).hypot(v - y) < factor * (radius(a) + radius(b))
    };
    let mut group: Vec<usize> = (0..members.len()).collect();
    fn root(group: &mut [usize], mut k: usize) -> usize {
        while group[k] != k {
            group[k] = group[group[k]];
            k = group[k];
        }
        k
    }
    for a in 0..members.len() {
        for b in a + 1..members.len() {
            if near(members[a], members[b]) {
                let (ra, rb) = (root(&mut group, a), root(&mut group, b));
                group[ra.max(rb)] = ra.min(rb);
            }
        }
    }
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut slot = vec![usize::MAX; members.len()];
    for (k, &m) in members.iter().enumerate() {
        let r = root(&mut group, k);
        if slot[r] == usize::MAX {
            slot[r] = out.len();
            out.push(Vec::new());
        }
        out[slot[r]].push(m);
    }
    out
}

/// The distance to another region, when one of at least a quarter of region `i`'s area lies
/// within `factor` × the sum of their equivalent radii (`PlaceConfig::crowd`).
pub(crate) fn crowded(regions: &[((f64, f64), usize)], i: usize, factor: f64) -> Option<f64> {
    let radius = equivalent_radius;
    let ((x, y), a) = regions[i];
    regions
        .iter()
        .enumerate()
        .filter(|&(j, &(_, b))| j != i && 4 * b >= a)
        .map(|(_, &((u, v), b))| ((u - x).hypot(v - y), b))
        .filter(|&(d, b)| d < factor * (radius(a) + radius(b)))
        .map(|(d, _)| d)
        .min_by(|p, q| p.total_cmp(q))
}

#[cfg(test)]
mod tests;
