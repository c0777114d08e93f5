//! Detection that does not believe every blob (Note S13's region of interest): the
//! background's global motion is fitted and subtracted, the magnitude threshold (raised to the
//! frame's robust flow-noise floor) cuts regions, or, with the change test, a pixel moves
//! where its flow passes the threshold and the frames changed there, and each such seed
//! grows to its object by the motion the frames confirm. Each region must then pass the
//! photometric test (warping frame 2 with its flow explains the change better than the
//! background's motion) before it reaches the tracker. Every region is kept with its verdict
//! and the reason, for the debug output (`regions.jsonl`).

use super::align::align;
use super::background::{BackgroundModel, GlobalMotion, fit};
use super::change::change_mask;
use super::detect_config::DetectConfig;
use super::grow::{grow, seed_motion};
use super::noise_floor::noise_floor;
use super::photometric::GreyPair;
use super::retry::{aligned_retry, crowded_retries, weak};
use super::roi::{Region, components, regions_of};
use super::split::{self, Seed};
use super::still_background::{ColourFrame, Placement, StillBackground};
use super::trim::trim;
use crate::error::{Error, Result};
use crate::imaging::box_filter::dilate;
use crate::types::Flow;

/// One region and what the detector made of it.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    pub region: Region,
    /// Mean warp residuals (with the region's flow, with the background's motion), when the
    /// photometric test ran.
    pub residuals: Option<(f64, f64)>,
    pub accepted: bool,
    pub reason: String,
    /// A weak detection beside another region (`retry::crowded_retries`), not accepted yet:
    /// it may be a piece of its neighbour's object, or a mover of its own. It is accepted only
    /// where the still background places it on an object of its own (`place`).
    pub beside: bool,
    /// What the still background did with an accepted region's centroid (when it ran).
    pub placement: Option<Placement>,
}

impl Candidate {
    /// Residual with the flow over residual with the background's motion.
    pub fn ratio(&self) -> Option<f64> {
        self.residuals
            .map(|(f, n)| if n > 0.0 { f / n } else { f64::INFINITY })
    }
}

/// One frame's detection.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameDetection {
    pub background: GlobalMotion,
    /// The fitted global motion when the frames did not support it: it was still subtracted
    /// from the flow, but the change mask and the photometric test took the background as
    /// still; `None` when the frames supported it or were not checked.
    pub rejected_background: Option<GlobalMotion>,
    /// Whether the frames explain the fitted motion beyond what its warp's interpolation of
    /// their noise does (`GreyPair::explains`); `true` when they were not asked. The placement
    /// takes the camera as still when they do not.
    pub background_explained: bool,
    /// The magnitude threshold used (px/frame, relative to the background).
    pub threshold: f64,
    /// The change test's level (grey levels in [0, 1]), when it ran.
    pub change_level: Option<f64>,
    pub candidates: Vec<Candidate>,
}

impl FrameDetection {
    /// The accepted regions, largest first (a split region's parts in its place).
    pub fn accepted(&self) -> Vec<Region> {
        self.candidates
            .iter()
            .filter(|c| c.accepted)
            .map(|c| c.region.clone())
            .collect()
    }

    /// Records each accepted region's mean colour in frame n (`frame`, its colour samples) over
    /// a disc of half its equivalent radius (at least 2 px) at its centre, the placed one when
    /// the still background placed it (`Region::colour`, the tracker's appearance cue). A
    /// region whose foreground lies far from its flow's centroid (`Placement::Far`: a smear
    /// along its object's path, or another object's foreground) has none: its centroid need
    /// not lie on any object, and the background's colour there would gate its association
    /// and enter its track's appearance as if it were the object's.
    pub fn colour(&mut self, frame: &ColourFrame) {
        for c in self.candidates.iter_mut().filter(|c| c.accepted) {
            let r = &mut c.region;
            if r.placed.is_none() && matches!(c.placement, Some(Placement::Far { .. })) {
                r.colour = None;
                continue;
            }
            let radius = (0.5 * (r.pixels as f64 / std::f64::consts::PI).sqrt()).max(2.0);
            r.colour = frame.mean_in_disc(r.placed.unwrap_or(r.centroid), radius);
        }
    }

    /// Places the accepted regions on frame n (`frame`, its colour samples) with the still
    /// background, which then keeps the frame. The camera counts as still when the frames did
    /// not support the fitted background motion or when that motion is small. A region over
    /// the predictions of two or more `seeds` (the confirmed tracks) is split between them
    /// where the foreground shows an object near each (`track::detect::split`): its parts take its
    /// place in the candidates, one per track. A weak detection beside another region
    /// (`Candidate::beside`) is placed with its crowd and accepted where it is placed on an
    /// object of its own, a mover beside another one; where it is not (a piece of its
    /// neighbour's object, or nothing the frame shows), it stays refused and the crowd is
    /// placed without it.
    pub fn place(&mut self, model: &mut StillBackground, frame: &ColourFrame, seeds: &[Seed]) {
        let camera = match self.rejected_background {
            None if self.background_explained => {
                self.background.max_magnitude(frame.width, frame.height)
            }
            _ => 0.0,
        };
        let wanted: Vec<&Candidate> = self
            .candidates
            .iter()
            .filter(|c| c.accepted || c.beside)
            .collect();
        let at_region: Vec<((f64, f64), usize)> = wanted
            .iter()
            .map(|c| (c.region.centroid, c.region.pixels))
            .collect();
        // A pending detection hides no track: it is split between none.
        let hidden: Vec<Vec<Seed>> = wanted
            .iter()
            .map(|c| {
                if c.beside {
                    Vec::new()
                } else {
                    split::covered(&c.region, seeds)
                }
            })
            .collect();
        let at: Vec<Vec<((f64, f64), f64)>> = hidden
            .iter()
            .map(|h| h.iter().map(|s| (s.at, s.radius)).collect())
            .collect();
        let pending: Vec<bool> = wanted.iter().map(|c| c.beside).collect();
        let placed = model.place_or_split(frame, camera, &at_region, &at, &pending);
        let mut out = Vec::with_capacity(self.candidates.len());
        let mut next = placed.into_iter().zip(hidden);
        for mut c in std::mem::take(&mut self.candidates) {
            if !(c.accepted || c.beside) {
                out.push(c);
                continue;
            }
            let Some((p, hidden)) = next.next() else {
                out.push(c);
                continue;
            };
            if c.beside {
                c.beside = false;
                match &p {
                    Placement::Moved { to } => {
                        c.accepted = true;
                        c.region.placed = Some(*to);
                        c.reason += ", placed on an object of its own";
                    }
                    _ => c.reason += &format!(": {}", p.describe()),
                }
                c.placement = Some(p);
                out.push(c);
                continue;
            }
            match &p {
                Placement::Moved { to } => c.region.placed = Some(*to),
                Placement::Far { to, .. } => c.region.foreground = Some(*to),
                Placement::Kept(_) => {}
                Placement::Split { to } => {
                    for (seed, &at) in hidden.iter().zip(to) {
                        out.push(Candidate {
                            region: split::part(&c.region, seed, at, to.len()),
                            placement: Some(p.clone()),
                            ..c.clone()
                        });
                    }
                    continue;
                }
            }
            c.placement = Some(p);
            out.push(c);
        }
        self.candidates = out;
    }
}

/// Detects the moving regions of `flow` (frame n → n + 1); `frames` (n and n + 1) enable the
/// photometric test. `threshold`, `noise_k` and `min_area` are the magnitude test's settings.
pub fn detect(
    flow: &Flow,
    frames: Option<&GreyPair>,
    threshold: f64,
    noise_k: f64,
    min_area: usize,
    cfg: &DetectConfig,
) -> Result<FrameDetection> {
    let background = fit(flow, cfg.background, cfg.background_samples);
    // What the frames say the background does: the fit, unless they do not support it. The
    // fit still comes off the flow before the threshold (an estimator's bias is removed like
    // a camera's motion), but the tests that ask the frames what changed (the change mask and
    // the photometric test) compare against the motion the frames support.
    let judged = (cfg.check_background && background.params.iter().any(|&a| a != 0.0))
        .then(|| frames.and_then(|p| p.judge(&background, cfg.background_samples)))
        .flatten();
    let unsupported =
        (cfg.photometric || cfg.change == Some(true)) && judged.is_some_and(|j| !j.supported);
    // Whether the camera moves is asked without the interpolation's gain: a still, flat
    // background under MMS can carry several pixels of spurious motion that a warp
    // "explains" only by averaging the noise (`GreyPair::explains`).
    let background_explained = judged.is_none_or(|j| j.explained);
    let (null, rejected_background) = if unsupported {
        (GlobalMotion::zero(), Some(background))
    } else {
        (background, None)
    };
    let relative = if cfg.background == BackgroundModel::None {
        None
    } else {
        Some(background.subtract(flow))
    };
    let test = relative.as_ref().unwrap_or(flow);
    let pair = frames.filter(|_| cfg.change == Some(true));
    let changed = pair.map(|p| {
        let c = change_mask(p, &null, cfg.change_window, cfg.change_k, cfg.min_change);
        (p, c)
    });
    let (threshold, found) = match &changed {
        Some((pair, c)) => {
            let seeds = Seeds {
                changed: &c.mask,
                level: c.level,
                background: &background,
                pair,
            };
            (
                threshold,
                grown_regions(test, flow, &seeds, threshold, min_area, cfg)?,
            )
        }
        None => {
            let t = threshold.max(noise_floor(test, noise_k));
            (t, regions_of(test, flow, t, min_area)?)
        }
    };
    let aligner = frames.filter(|_| cfg.align == Some(true));
    let mut candidates: Vec<Candidate> = found
        .into_iter()
        .map(|(mut region, pixels)| {
            let photometric = frames.filter(|_| cfg.photometric);
            let residuals = photometric.and_then(|p| p.residuals(&pixels, flow, &null));
            let (accepted, reason) = match (photometric, residuals) {
                (None, _) => (true, "magnitude (no photometric test)".to_string()),
                (Some(_), None) => (
                    false,
                    "photometric: no pixel of the region can be warped".to_string(),
                ),
                (Some(_), Some((_, rn))) if rn < cfg.min_change => (
                    false,
                    format!(
                        "photometric: nothing changed (residual {rn:.2e} < {:.1e})",
                        cfg.min_change
                    ),
                ),
                (Some(_), Some((rf, rn))) => {
                    let r = rf / rn;
                    let max = cfg.max_residual_ratio;
                    let retried = aligner
                        .filter(|_| r > max && cfg.retry_aligned)
                        .and_then(|p| {
                            aligned_retry(
                                p,
                                &pixels,
                                &region,
                                rn,
                                max,
                                cfg.align_reach,
                                cfg.align_weights,
                            )
                        });
                    if let Some((motion, ra)) = retried {
                        region = weak(&region, motion);
                        (
                            true,
                            format!(
                                "photometric with the aligned motion: ratio {ra:.2} <= {max:.2} \
                                 (with the flow {r:.2}); weak"
                            ),
                        )
                    } else if r <= max {
                        (true, format!("photometric: ratio {r:.2} <= {max:.2}"))
                    } else {
                        (false, format!("photometric: ratio {r:.2} > {max:.2}"))
                    }
                }
            };
            // The accepted region's motion, as the frames confirm it.
            if accepted
                && !region.weak
                && let Some(p) = aligner
            {
                region.aligned = align(
                    p.first_colour(),
                    p.second_colour(),
                    &pixels,
                    region.mean_flow,
                    cfg.align_reach,
                    cfg.align_weights,
                )
                .filter(|a| a.residual < a.start_residual)
                .map(|a| a.motion);
            }
            Candidate {
                region,
                residuals,
                accepted,
                reason,
                beside: false,
                placement: None,
            }
        })
        .collect();
    // A retried region beside another may be a piece of its neighbour's object: it is not
    // accepted unless the still background places it on an object of its own (`place`).
    let places: Vec<_> = candidates
        .iter()
        .map(|c| (c.region.centroid, c.region.pixels))
        .collect();
    let retried: Vec<bool> = candidates
        .iter()
        .map(|c| c.accepted && c.region.weak)
        .collect();
    for (c, crowded) in candidates
        .iter_mut()
        .zip(crowded_retries(&places, &retried))
    {
        if crowded {
            c.accepted = false;
            c.beside = true;
            c.reason = format!("{}, but beside another region", c.reason);
        }
    }
    Ok(FrameDetection {
        background,
        rejected_background,
        background_explained,
        threshold,
        change_level: changed.map(|(_, c)| c.level),
        candidates,
    })
}

/// What the change test's seeds are made of: the change mask (`[H, W]`), the background's
/// motion and the frames.
struct Seeds<'a> {
    changed: &'a [bool],
    /// The change test's level (grey levels in [0, 1]).
    level: f64,
    background: &'a GlobalMotion,
    pair: &'a GreyPair,
}

/// The regions of the change test: seeds where |`test`| > `threshold` and the frames
/// changed, each with the motion the frames confirm (`seed_motion`), grown to its object's
/// extent near the change (largest seed first, no pixel in two regions), with the
/// statistics of `stats`.
fn grown_regions(
    test: &Flow,
    stats: &Flow,
    seeds: &Seeds,
    threshold: f64,
    min_area: usize,
    cfg: &DetectConfig,
) -> Result<Vec<(Region, Vec<usize>)>> {
    let (w, h) = (test.width(), test.height());
    let changed = seeds.changed;
    if changed.len() != w * h {
        return Err(Error::shape(
            "change mask",
            format!("{} pixels", w * h),
            format!("{} pixels", changed.len()),
        ));
    }
    let allowed = dilate(changed, w, h, cfg.grow_reach);
    let mut claimed = vec![false; w * h];
    let seeds_mask: Vec<bool> = (0..w * h)
        .map(|p| {
            let (a, b) = (test.u()[p] as f64, test.v()[p] as f64);
            let m = a.hypot(b);
            changed[p]
                && m.is_finite()
                && m > threshold
                && stats.u()[p].is_finite()
                && stats.v()[p].is_finite()
        })
        .collect();
    let mut seeds_found: Vec<Vec<usize>> = components(&seeds_mask, w, h)
        .into_iter()
        .filter(|px| px.len() >= min_area.max(1))
        .collect();
    seeds_found.sort_by_key(|px| std::cmp::Reverse(px.len()));
    let mut out: Vec<(Region, Vec<usize>)> = seeds_found
        .into_iter()
        .filter_map(|seed| {
            let m = seed_motion(&seed, stats, seeds.background, seeds.pair, 32)?;
            let grown = grow(
                &seed,
                m,
                test,
                threshold,
                cfg.grow_margin,
                &allowed,
                &mut claimed,
            );
            Some(if cfg.trim {
                trim(&grown, m, seeds.background, seeds.pair, 2, seeds.level)
            } else {
                grown
            })
        })
        .filter(|px| px.len() >= min_area.max(1))
        .map(|px| (Region::of(&px, stats), px))
        .collect();
    out.sort_by_key(|r| std::cmp::Reverse(r.0.pixels));
    Ok(out)
}

#[cfg(test)]
mod tests;
