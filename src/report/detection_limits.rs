//! Note S12's detection limits through the network (Fig. S10 a–g): the rocket moved 3 px up,
//! left and up-right and discs of radius 8, 5 and 3 px moved 15 px right, 701×701 (or the same
//! movers centred in frames of other sizes), through the metalens camera, then MMS flow; scored
//! inside the true moving region (magnitude, direction, share detected as moving) and outside
//! it (false-motion area).

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::flow::infer::Predictor;
use crate::flow::viz::flow_to_image;
use crate::imaging::pipeline::Camera;
use crate::imaging::{CameraConfig, psf_source};
use crate::rng;
use crate::scene::LayeredScene;
use crate::scene::patterns::{self, RocketStep};
use crate::types::{Flow, Image};

/// One test scene of Fig. S10.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum LimitCase {
    /// The rocket moved 3 px in a direction (Fig. S10a–c).
    Rocket(RocketStep),
    /// A disc of this radius moving 15 px right (Fig. S10e–g).
    Disc(f64),
}

impl LimitCase {
    pub fn name(&self) -> String {
        match self {
            LimitCase::Rocket(s) => format!(
                "rocket {}",
                serde_json::to_string(s)
                    .unwrap_or_default()
                    .trim_matches('"')
            ),
            LimitCase::Disc(r) => format!("disc r = {r}"),
        }
    }

    /// The case's name in a `side`-pixel frame: Note S12's own name in its 701×701 frame.
    pub fn name_in(&self, side: usize) -> String {
        match side {
            patterns::S12_SIZE => self.name(),
            _ => format!("{} in {side}×{side}", self.name()),
        }
    }

    fn scene(&self, side: usize) -> Result<LayeredScene> {
        match self {
            LimitCase::Rocket(s) => patterns::rocket(*s, 3, side),
            LimitCase::Disc(r) => patterns::disc(*r, 3, side),
        }
    }
}

/// The experiment: cases, camera, network settings and the detection rule.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LimitsConfig {
    pub cases: Vec<LimitCase>,
    /// Frame sides, px: every case is drawn centred in each (Note S12's 701 by default). The
    /// movers keep their size, so a larger frame only adds plain background around them.
    pub frames: Vec<usize>,
    pub camera: CameraConfig,
    /// Seed of the camera noise.
    pub seed: u64,
    /// Iteration counts to score.
    pub iters: Vec<usize>,
    /// A pixel moves when its estimated flow is at least this long, px.
    pub moving_px: f64,
    /// False motion is counted farther than this from the true moving region (flow at the
    /// edge of a blurred object spreads over the blur), px.
    pub margin_px: f64,
    /// A case counts as detected when at least this share of its moving region moves and the
    /// mean estimated direction is within `max_direction_deg` of the true one.
    pub min_detected: f64,
    pub max_direction_deg: f64,
}

impl Default for LimitsConfig {
    fn default() -> Self {
        Self {
            cases: vec![
                LimitCase::Rocket(RocketStep::Up),
                LimitCase::Rocket(RocketStep::Left),
                LimitCase::Rocket(RocketStep::UpRight),
                LimitCase::Disc(8.0),
                LimitCase::Disc(5.0),
                LimitCase::Disc(3.0),
            ],
            frames: vec![patterns::S12_SIZE],
            camera: CameraConfig::default(),
            seed: 0,
            iters: vec![4, 12],
            moving_px: 1.0,
            margin_px: 4.0,
            min_detected: 0.5,
            max_direction_deg: 20.0,
        }
    }
}

/// The scores of one case at one iteration count.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LimitScore {
    pub case: String,
    pub iters: usize,
    /// The true displacement, px.
    pub true_flow: [f64; 2],
    /// Pixels of the true moving region.
    pub region_px: usize,
    /// Mean estimated flow vector inside the region and its length, px.
    pub mean_flow: [f64; 2],
    pub mean_magnitude: f64,
    /// Length of the mean estimated vector minus the true length, px.
    pub magnitude_error: f64,
    /// Angle between the mean estimated vector and the true one, degrees.
    pub direction_error_deg: f64,
    /// Share of the region whose estimated flow is at least `moving_px` long.
    pub detected_fraction: f64,
    /// Pixels farther than `margin_px` from the region that move, and their share of that area.
    pub false_motion_px: usize,
    pub false_motion_fraction: f64,
    /// Detected in the right direction by the config's rule.
    pub detected: bool,
    pub ms: f64,
}

impl LimitsConfig {
    pub fn validate(&self) -> Result<()> {
        if self.cases.is_empty() {
            return Err(Error::invalid("cases", "empty list"));
        }
        if self.frames.is_empty() {
            return Err(Error::invalid("frames", "empty list"));
        }
        // Every case must fit every frame: drawing each checks the sizes (cheaply: no render).
        for &side in &self.frames {
            for c in &self.cases {
                c.scene(side).map_err(|e| {
                    Error::invalid("cases", format!("{} in {side} px: {e}", c.name()))
                })?;
            }
        }
        if self.iters.is_empty() || self.iters.iter().any(|&n| n == 0 || n > 256) {
            return Err(Error::invalid(
                "iters",
                format!("each must be 1..=256, got {:?}", self.iters),
            ));
        }
        for (name, v) in [
            ("moving_px", self.moving_px),
            ("margin_px", self.margin_px),
            ("max_direction_deg", self.max_direction_deg),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    name,
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.min_detected) {
            return Err(Error::invalid(
                "min_detected",
                format!("must be in [0, 1], got {}", self.min_detected),
            ));
        }
        self.camera.validate()
    }

    /// Reads a config; relative PSF paths are relative to the file.
    pub fn from_file(path: &Path) -> Result<Self> {
        let mut cfg: Self = crate::io::read_json(path)?;
        cfg.camera
            .resolve_paths(path.parent().unwrap_or(Path::new("")));
        cfg.validate().map_err(|e| crate::io::in_config(path, e))?;
        Ok(cfg)
    }
}

/// One case through the camera and the network: its frames, true and estimated flows.
pub struct CaseRun {
    pub case: LimitCase,
    pub frames: [Image; 2],
    pub truth: Flow,
    /// One estimate per iteration count of the config, in its order.
    pub estimates: Vec<Flow>,
    pub scores: Vec<LimitScore>,
}

/// Runs every case of `cfg` with `predictor`.
pub fn run(cfg: &LimitsConfig, predictor: &Predictor) -> Result<Vec<CaseRun>> {
    cfg.validate()?;
    let (psf, _) = psf_source::load(&cfg.camera.psf)?;
    let camera = Camera::new(&cfg.camera, psf)?;
    let mut runs = Vec::new();
    let drawn = cfg
        .cases
        .iter()
        .enumerate()
        .flat_map(|(k, case)| cfg.frames.iter().map(move |&side| (k, case, side)));
    for (k, case, side) in drawn {
        let scene = case.scene(side)?;
        let truth = scene.flow()?;
        // The noise of Note S12's own frames is seeded as it always was (the published tables
        // stay reproducible); other sizes get their own.
        let seed = match side {
            patterns::S12_SIZE => rng::derive(cfg.seed, &[k as u64]),
            _ => rng::derive(cfg.seed, &[k as u64, side as u64]),
        };
        let frames = [
            camera.apply(
                &scene.render(0)?,
                rng::derive(seed, &[rng::purpose::NOISE_FRAME1]),
            )?,
            camera.apply(
                &scene.render(1)?,
                rng::derive(seed, &[rng::purpose::NOISE_FRAME2]),
            )?,
        ];
        let (mut estimates, mut scores) = (Vec::new(), Vec::new());
        for &iters in &cfg.iters {
            let t = std::time::Instant::now();
            let est = predictor.predict(&frames[0], &frames[1], iters)?;
            let ms = t.elapsed().as_secs_f64() * 1e3;
            scores.push(score(cfg, &case.name_in(side), iters, &truth, &est, ms));
            estimates.push(est);
        }
        runs.push(CaseRun {
            case: case.clone(),
            frames,
            truth,
            estimates,
            scores,
        });
    }
    Ok(runs)
}

/// Scores `est` against the true flow of a scene with one mover on a still background.
pub fn score(
    cfg: &LimitsConfig,
    case: &str,
    iters: usize,
    truth: &Flow,
    est: &Flow,
    ms: f64,
) -> LimitScore {
    let (h, w) = (truth.height(), truth.width());
    let moving: Vec<bool> = (0..h * w)
        .map(|i| {
            let (u, v) = truth.get(i / w, i % w);
            u.hypot(v) > 1e-6
        })
        .collect();
    let near = dilate(&moving, h, w, cfg.margin_px);
    let (mut n, mut su, mut sv, mut tu, mut tv, mut det, mut smag) =
        (0usize, 0.0, 0.0, 0.0, 0.0, 0usize, 0.0);
    let (mut outside, mut false_px) = (0usize, 0usize);
    for i in 0..h * w {
        let (y, x) = (i / w, i % w);
        let (u, v) = est.get(y, x);
        let (u, v) = (u as f64, v as f64);
        let len = u.hypot(v);
        let moves = len.is_finite() && len >= cfg.moving_px;
        if moving[i] {
            let (gu, gv) = truth.get(y, x);
            n += 1;
            su += u;
            sv += v;
            tu += gu as f64;
            tv += gv as f64;
            smag += len;
            det += moves as usize;
        } else if !near[i] {
            outside += 1;
            false_px += moves as usize;
        }
    }
    let nf = n.max(1) as f64;
    let (mu, mv, gu, gv) = (su / nf, sv / nf, tu / nf, tv / nf);
    let (mlen, glen) = (mu.hypot(mv), gu.hypot(gv));
    let direction_error_deg = if mlen > 0.0 && glen > 0.0 {
        ((mu * gu + mv * gv) / (mlen * glen))
            .clamp(-1.0, 1.0)
            .acos()
            .to_degrees()
    } else {
        180.0
    };
    let detected_fraction = det as f64 / nf;
    LimitScore {
        case: case.to_string(),
        iters,
        true_flow: [gu, gv],
        region_px: n,
        mean_flow: [mu, mv],
        mean_magnitude: smag / nf,
        magnitude_error: mlen - glen,
        direction_error_deg,
        detected_fraction,
        false_motion_px: false_px,
        false_motion_fraction: false_px as f64 / outside.max(1) as f64,
        detected: n > 0
            && detected_fraction >= cfg.min_detected
            && direction_error_deg <= cfg.max_direction_deg,
        ms,
    }
}

/// Pixels within `r` (Euclidean) of a set pixel.
fn dilate(mask: &[bool], h: usize, w: usize, r: f64) -> Vec<bool> {
    let ri = r.floor() as isize;
    let mut out = mask.to_vec();
    for y in 0..h as isize {
        for x in 0..w as isize {
            if !mask[(y * w as isize + x) as usize] {
                continue;
            }
            for dy in -ri..=ri {
                for dx in -ri..=ri {
                    let (yy, xx) = (y + dy, x + dx);
                    if yy >= 0
                        && xx >= 0
                        && yy < h as isize
                        && xx < w as isize
                        && ((dx * dx + dy * dy) as f64) <= r * r
                    {
                        out[(yy * w as isize + xx) as usize] = true;
                    }
                }
            }
        }
    }
    out
}

/// Fig. S10's layout, one row per case: camera frame 1, the true flow and the estimate at the
/// last iteration count, each as the whole frame (halved) and a 2× zoom on the mover.
pub fn figure(runs: &[CaseRun]) -> Image {
    const CELL: usize = 350;
    let cols = 6;
    let mut out = Image::zeros(3, CELL * runs.len().max(1), CELL * cols);
    for (row, r) in runs.iter().enumerate() {
        let (cy, cx) = centroid(&r.truth);
        let scale = r.truth.max_magnitude().max(1.0) * 1.25;
        let est = r.estimates.last().map(|e| flow_to_image(e, Some(scale)));
        let panels = [
            Some(grey_to_rgb(&r.frames[0])),
            Some(flow_to_image(&r.truth, Some(scale))),
            est,
        ];
        for (k, p) in panels.iter().enumerate() {
            let Some(p) = p else { continue };
            paste(
                &mut out,
                p,
                row * CELL,
                (2 * k) * CELL,
                CELL,
                0.0,
                0.0,
                p.width() as f64 / CELL as f64,
            );
            // Zoom: a CELL/2 window around the mover, shown at 2×.
            let (y0, x0) = (cy - CELL as f64 / 4.0, cx - CELL as f64 / 4.0);
            paste(
                &mut out,
                p,
                row * CELL,
                (2 * k + 1) * CELL,
                CELL,
                y0,
                x0,
                0.5,
            );
        }
    }
    out
}

fn grey_to_rgb(img: &Image) -> Image {
    if img.channels() == 3 {
        return img.clone();
    }
    let p = img.plane(0).to_vec();
    Image::from_vec(
        3,
        img.height(),
        img.width(),
        [p.clone(), p.clone(), p].concat(),
    )
    .unwrap_or_else(|_| Image::zeros(3, img.height(), img.width()))
}

fn centroid(flow: &Flow) -> (f64, f64) {
    let (h, w) = (flow.height(), flow.width());
    let (mut n, mut sy, mut sx) = (0.0, 0.0, 0.0);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = flow.get(y, x);
            if u.hypot(v) > 1e-6 {
                n += 1.0;
                sy += y as f64;
                sx += x as f64;
            }
        }
    }
    if n == 0.0 {
        (h as f64 / 2.0, w as f64 / 2.0)
    } else {
        (sy / n, sx / n)
    }
}

/// Copies a `cell × cell` window of `src` (nearest sample; source pixel = origin + step · i)
/// into `dst` at (top, left); outside the source is black.
#[allow(clippy::too_many_arguments)]
fn paste(
    dst: &mut Image,
    src: &Image,
    top: usize,
    left: usize,
    cell: usize,
    y0: f64,
    x0: f64,
    step: f64,
) {
    let (h, w) = (src.height() as isize, src.width() as isize);
    let (dh, dw) = (dst.height(), dst.width());
    for c in 0..3 {
        let sc = c.min(src.channels() - 1);
        for i in 0..cell {
            for j in 0..cell {
                let (sy, sx) = (
                    (y0 + step * i as f64).floor() as isize,
                    (x0 + step * j as f64).floor() as isize,
                );
                let v = if sy >= 0 && sx >= 0 && sy < h && sx < w {
                    src.get(sc, sy as usize, sx as usize)
                } else {
                    0.0
                };
                let (ty, tx) = (top + i, left + j);
                if ty < dh && tx < dw {
                    dst.plane_mut(c)[ty * dw + tx] = v;
                }
            }
        }
    }
}

/// The table of the scores, one row per case and iteration count.
pub fn markdown(scores: &[LimitScore], cfg: &LimitsConfig) -> String {
    let mut s = "| case | iterations | true flow (px) | mean estimate (px) | magnitude error (px) | direction error (°) | detected share | false-motion area (px, share) | detected | ms |\n|---|---|---|---|---|---|---|---|---|---|\n"
        .to_string();
    for r in scores {
        s += &format!(
            "| {} | {} | ({:.1}, {:.1}) | ({:.2}, {:.2}) | {:+.2} | {:.1} | {:.2} | {} ({:.4}) | {} | {:.0} |\n",
            r.case,
            r.iters,
            r.true_flow[0],
            r.true_flow[1],
            r.mean_flow[0],
            r.mean_flow[1],
            r.magnitude_error,
            r.direction_error_deg,
            r.detected_fraction,
            r.false_motion_px,
            r.false_motion_fraction,
            if r.detected { "yes" } else { "no" },
            r.ms
        );
    }
    s += &format!(
        "\nA pixel moves when its estimated flow is at least {} px long; false motion is counted farther than {} px from the true region; detected = at least {:.0} % of the region moves and the mean direction is within {}°.\n",
        cfg.moving_px,
        cfg.margin_px,
        cfg.min_detected * 100.0,
        cfg.max_direction_deg
    );
    s
}

#[cfg(test)]
mod tests;
