//! What the placement on the frame (Notes S13–S15: the object rather than the flow's blob) is
//! given and gives: the frames it reads (`ColourFrame`), its settings (`PlaceConfig`) and what
//! it did with a region (`Placement`). The still background (`track::detect::still_background`) and the
//! frame's foreground (`track::detect::foreground`) both read them.

use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::types::Image;

/// One frame's samples for the background model, planar `[C, H, W]` in 8-bit levels (C = 1
/// for a grey frame, 3 for colour: colour separates a mover from a background of the same
/// brightness). Cheap to clone.
#[derive(Clone, Debug)]
pub struct ColourFrame {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    data: Arc<[u8]>,
}

impl ColourFrame {
    /// The first three channels of `img` (values in [0, 1]), rounded to 8 bits.
    pub fn new(img: &Image) -> Self {
        let channels = img.channels().min(3);
        let mut data = Vec::with_capacity(channels * img.height() * img.width());
        for c in 0..channels {
            data.extend(
                img.plane(c)
                    .iter()
                    .map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8),
            );
        }
        Self {
            width: img.width(),
            height: img.height(),
            channels,
            data: data.into(),
        }
    }

    /// The mean of each channel over the pixels within `radius` of `centre` (R, G, B; a grey
    /// frame's level three times); `None` when no pixel lies there.
    pub fn mean_in_disc(&self, centre: (f64, f64), radius: f64) -> Option<[f64; 3]> {
        let mut sum = [0.0f64; 3];
        let mut n = 0usize;
        for (x, y) in disc(centre, radius, self.width, self.height) {
            let p = y * self.width + x;
            for (c, s) in sum.iter_mut().enumerate() {
                *s += self.plane(c.min(self.channels - 1))[p] as f64;
            }
            n += 1;
        }
        (n > 0).then(|| sum.map(|s| s / n as f64))
    }

    /// Channel `c`'s 8-bit samples, `[H, W]`.
    pub(crate) fn plane(&self, c: usize) -> &[u8] {
        let n = self.width * self.height;
        &self.data[c * n..(c + 1) * n]
    }
}

/// Settings of the placement on the frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PlaceConfig {
    /// `null` (the default): on for an estimated flow (MMS), off for a given one, whose regions
    /// are the objects already. Needs frames.
    pub enabled: Option<bool>,
    /// Frames in the temporal median (the last ones before frame n).
    pub frames: usize,
    /// Frames needed before the model is used.
    pub min_frames: usize,
    /// Side of the box (pixels, odd) over which the colour difference is averaged.
    pub window: usize,
    /// The foreground level: the median plus this many robust standard deviations of the
    /// averaged difference over the frame.
    pub k: f64,
    /// Mean-shift iterations.
    pub iterations: usize,
    /// The placement is refused when it moves the centroid by more than this share of the
    /// region's equivalent radius (the foreground there is another object).
    pub max_shift: f64,
    /// ... or when fewer foreground pixels than this share of the region's area lie in the
    /// final disc (the object stopped and joined the background).
    pub min_cover: f64,
    /// Each stored frame's objects (its placed regions) are left out of the median in a disc
    /// of this many times their equivalent radius; a pixel left free in fewer than
    /// `foreground::MIN_UNCOVERED` frames takes the median of them all. 0 turns it off.
    pub mask: f64,
    /// Regions within this many times the sum of their equivalent radii of each other form a
    /// crowd (two movers side by side, or a fragment beside its object), whose members are
    /// placed together: each pixel of the foreground counts for the nearest member's mean
    /// shift only, and two members whose centres end on one blob of foreground (no valley
    /// between them) keep their flow centroids.
    pub crowd: f64,
    /// Splitting a merged region (`track::detect::split`): the foreground's centres found from the
    /// predictions of the tracks it hides must lie at least this share of the sum of their
    /// radii apart, or the region stays one (one object hides the other). 0 turns it off.
    pub split: f64,
    /// The colour difference is weighed in the camera's noise at each pixel's level (each
    /// channel's temporal spread as a function of its level, measured on the still
    /// background: `track::detect::noise_level`) rather than in 8-bit levels: a mover over a dark,
    /// quiet part of the background counts as surely as over a bright, noisy one.
    pub pixel_noise: bool,
    /// The floor of that spread (8-bit levels) with `pixel_noise`: quantisation makes a flat
    /// or clipped background's spread 0.
    pub noise_floor: f64,
    /// Above this background motion (px/frame, its largest over the frame), the camera moves:
    /// the model starts over. Not lower: an estimated flow's global bias on a still scene
    /// reaches 0.5–0.8 px at the corners, and a sub-pixel warp's smoothing lets the frames
    /// seem to support it.
    pub max_camera_motion: f64,
}

impl Default for PlaceConfig {
    fn default() -> Self {
        Self {
            enabled: None,
            frames: 30,
            min_frames: 10,
            window: 5,
            k: 3.0,
            iterations: 5,
            max_shift: 0.5,
            min_cover: 0.25,
            mask: 1.5,
            crowd: 2.5,
            split: 0.5,
            pixel_noise: true,
            noise_floor: 3.0,
            max_camera_motion: 2.0,
        }
    }
}

impl PlaceConfig {
    pub fn validate(&self) -> Result<()> {
        if self.frames == 0 || self.frames > 255 {
            return Err(Error::invalid(
                "detect.place.frames",
                format!("must be 1..=255, got {}", self.frames),
            ));
        }
        if self.min_frames == 0 || self.min_frames > self.frames {
            return Err(Error::invalid(
                "detect.place.min_frames",
                format!(
                    "must be 1..=frames ({}), got {}",
                    self.frames, self.min_frames
                ),
            ));
        }
        if self.window.is_multiple_of(2) || self.window > 31 {
            return Err(Error::invalid(
                "detect.place.window",
                format!("must be odd and at most 31, got {}", self.window),
            ));
        }
        if self.iterations == 0 || self.iterations > 100 {
            return Err(Error::invalid(
                "detect.place.iterations",
                format!("must be 1..=100, got {}", self.iterations),
            ));
        }
        for (name, v) in [
            ("k", self.k),
            ("max_shift", self.max_shift),
            ("min_cover", self.min_cover),
            ("mask", self.mask),
            ("crowd", self.crowd),
            ("split", self.split),
            ("max_camera_motion", self.max_camera_motion),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::invalid(
                    format!("detect.place.{name}"),
                    format!("must be finite and >= 0, got {v}"),
                ));
            }
        }
        if !(self.noise_floor.is_finite() && self.noise_floor > 0.0) {
            return Err(Error::invalid(
                "detect.place.noise_floor",
                format!("must be finite and > 0, got {}", self.noise_floor),
            ));
        }
        Ok(())
    }

    /// The spread's floor where differences are weighed in each pixel's noise.
    pub(crate) fn noise(&self) -> Option<f64> {
        self.pixel_noise.then_some(self.noise_floor)
    }
}

/// What the placement did with one region.
#[derive(Clone, Debug, PartialEq)]
pub enum Placement {
    /// The foreground's centre, where the region's centroid moves.
    Moved { to: (f64, f64) },
    /// Kept at the flow's centroid, though the foreground has a centre at `to`, more than
    /// `max_shift` of the region's radius away (`shift` px; the limit `limit` px): another
    /// object's, or this one's where the flow smeared its motion far along its path. The
    /// tracker takes it where its own prediction confirms it (`Region::foreground`).
    Far {
        to: (f64, f64),
        shift: f64,
        limit: f64,
    },
    /// Kept at the flow's centroid, and why.
    Kept(String),
    /// A merged region split between the tracks it hides: the foreground's centre found from
    /// each one's prediction, in the order of the seeds (`track::detect::split`).
    Split { to: Vec<(f64, f64)> },
}

impl Placement {
    pub fn describe(&self) -> String {
        match self {
            Placement::Moved { to } => {
                format!("placed on the foreground at ({:.1}, {:.1})", to.0, to.1)
            }
            Placement::Far { to, shift, limit } => format!(
                "flow centroid kept: the foreground's centre ({:.1}, {:.1}) is {shift:.1} px away \
                 (more than {limit:.1})",
                to.0, to.1
            ),
            Placement::Kept(why) => format!("flow centroid kept: {why}"),
            Placement::Split { to } => {
                let at: Vec<String> = to
                    .iter()
                    .map(|p| format!("({:.1}, {:.1})", p.0, p.1))
                    .collect();
                format!("split between the tracks it hides, at {}", at.join(", "))
            }
        }
    }
}

/// The pixels (x, y) of a `w` × `h` frame within `radius` of `centre`; none for a
/// non-finite centre or radius.
pub(crate) fn disc(
    centre: (f64, f64),
    radius: f64,
    w: usize,
    h: usize,
) -> impl Iterator<Item = (usize, usize)> {
    let ok = centre.0.is_finite() && centre.1.is_finite() && radius.is_finite() && w * h > 0;
    let span = |c: f64, n: usize| {
        let (lo, hi) = ((c - radius).ceil().max(0.0), (c + radius).floor());
        if ok && lo <= hi && lo <= (n - 1) as f64 {
            lo as usize..(hi.min((n - 1) as f64) as usize + 1)
        } else {
            0..0
        }
    };
    let (xs, ys) = (span(centre.0, w), span(centre.1, h));
    ys.flat_map(move |y| xs.clone().map(move |x| (x, y)))
        .filter(move |&(x, y)| (x as f64 - centre.0).hypot(y as f64 - centre.1) <= radius)
}
