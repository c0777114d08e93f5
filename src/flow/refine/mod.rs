//! Variational refinement of an estimated flow (the last stage of DIS, Kroeger et al. 2016,
//! after Brox et al. 2004): the network's flow, which works at 1/8 resolution, is refined at
//! 1/4, 1/2 and full resolution by brightness and gradient constancy with a robust
//! smoothness term, which recovers the sub-pixel accuracy a 1/8-resolution estimate lacks.
//! A coarse pass's increment fades where the full-size flow, within the reach of the pass's
//! derivatives, holds detail its coarse version lacks (a small mover the network resolved,
//! Note S12's r = 3 disc; a motion boundary blurred by the metalens), which it would erase.

pub mod linearise;
#[cfg(test)]
mod reference;
pub mod solver;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::imaging::box_filter::{box_mean, box_min};
use crate::imaging::resize::downscale;
use crate::types::{Flow, Image};

use super::resample::resize_flow;

/// How a flow estimate is refined after the network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RefineConfig {
    /// Downscaling factors, coarse to fine; each runs the solver once on frames area-averaged
    /// by that factor and adds its increment to the flow.
    #[serde(default = "default_scales")]
    pub scales: Vec<u32>,
    /// Smoothness weight α.
    #[serde(default = "default_alpha")]
    pub alpha: f32,
    /// Brightness-constancy weight δ.
    #[serde(default = "default_delta")]
    pub delta: f32,
    /// Gradient-constancy weight γ.
    #[serde(default = "default_gamma")]
    pub gamma: f32,
    /// Outer (lagged robust weight) iterations per scale.
    #[serde(default = "default_fixed_point")]
    pub fixed_point_iters: usize,
    /// Red–black SOR sweeps per outer iteration.
    #[serde(default = "default_sor")]
    pub sor_iters: usize,
    /// Over-relaxation factor ω ∈ (0, 2).
    #[serde(default = "default_omega")]
    pub omega: f32,
    /// κ of the local smoothness weight exp(−κ·|∇I|/255) (DeepFlow's); 0: α everywhere.
    #[serde(default = "default_kappa")]
    pub kappa: f32,
}

// The energy's weights and iteration counts are OpenCV's VariationalRefinement settings in its
// DIS presets (α 20, δ 5, γ 10, 5 fixed-point iterations of 5 SOR sweeps). Its ω = 1.6 suits
// DIS's start, its patch search, already within a fraction of a pixel; the network's start is
// off by up to a pixel (it reports almost nothing of a sub-pixel motion), and from there the
// same sweeps at ω 1.6 stop far short of the energy's minimum. At ω 1.9 they reach it at the
// same cost (`docs/flow.md`, measured on pairs of the training photographs). The scales were
// chosen on the trend of the real-pair benchmark (1/4 to full resolution; from 1/8 the KITTI
// pair got worse). κ = 5 (DeepFlow's value) weighs the smoothness term down across image edges,
// where a moving object's boundary is likely to lie; on generated pairs κ 10 did a little
// better, but lost one of Note S12's cases (the textureless rocket, filled in from its edges).
fn default_scales() -> Vec<u32> {
    vec![4, 2, 1]
}
fn default_alpha() -> f32 {
    20.0
}
fn default_delta() -> f32 {
    5.0
}
fn default_gamma() -> f32 {
    10.0
}
fn default_fixed_point() -> usize {
    5
}
fn default_sor() -> usize {
    5
}
fn default_omega() -> f32 {
    1.9
}
fn default_kappa() -> f32 {
    5.0
}

impl Default for RefineConfig {
    fn default() -> Self {
        Self {
            scales: default_scales(),
            alpha: default_alpha(),
            delta: default_delta(),
            gamma: default_gamma(),
            fixed_point_iters: default_fixed_point(),
            sor_iters: default_sor(),
            omega: default_omega(),
            kappa: default_kappa(),
        }
    }
}

impl RefineConfig {
    /// Checks every field's range; `what` names the setting in the message.
    pub fn validate(&self, what: &str) -> Result<()> {
        let bad =
            |field: &str, reason: String| Err(Error::invalid(format!("{what}.{field}"), reason));
        if self.scales.is_empty() || self.scales.iter().any(|&s| s == 0 || s > 64) {
            return bad(
                "scales",
                format!(
                    "must be a non-empty list of factors in 1..=64, got {:?}",
                    self.scales
                ),
            );
        }
        for (name, x) in [
            ("alpha", self.alpha),
            ("delta", self.delta),
            ("gamma", self.gamma),
            ("kappa", self.kappa),
        ] {
            if !(x.is_finite() && x >= 0.0) {
                return bad(name, format!("must be a finite number ≥ 0, got {x}"));
            }
        }
        if !(self.omega.is_finite() && self.omega > 0.0 && self.omega < 2.0) {
            return bad("omega", format!("must be in (0, 2), got {}", self.omega));
        }
        if self.fixed_point_iters > 1000 || self.sor_iters > 1000 {
            return bad("iterations", "at most 1000 each".into());
        }
        Ok(())
    }
}

/// The choice of `--refine`: the network alone, the variational refinement with its default
/// settings, or with the settings of a JSON file (the fields of [`RefineConfig`]).
#[derive(Clone, Debug, PartialEq, Default)]
pub enum Refine {
    None,
    #[default]
    Variational,
    Custom(RefineConfig),
}

impl Refine {
    /// Parses `none`, `variational` or the path of a `.json` file of settings.
    pub fn parse(s: &str) -> Result<Self> {
        match s {
            "none" => Ok(Refine::None),
            "variational" => Ok(Refine::Variational),
            _ if s.ends_with(".json") => {
                let path = std::path::Path::new(s);
                let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
                let cfg: RefineConfig = serde_json::from_str(&text).map_err(|e| Error::Config {
                    path: path.into(),
                    reason: e.to_string(),
                })?;
                cfg.validate("refine")?;
                Ok(Refine::Custom(cfg))
            }
            _ => Err(Error::invalid(
                "--refine",
                format!("expected none, variational or a .json file of settings, got {s:?}"),
            )),
        }
    }

    /// The config to refine with, if any.
    pub fn config(&self) -> Option<RefineConfig> {
        match self {
            Refine::None => None,
            Refine::Variational => Some(RefineConfig::default()),
            Refine::Custom(c) => Some(c.clone()),
        }
    }
}

/// `flow` from `img1` to `img2` refined coarse to fine over `cfg.scales`.
pub fn refine(img1: &Image, img2: &Image, flow: &Flow, cfg: &RefineConfig) -> Result<Flow> {
    cfg.validate("refine")?;
    let (_, h, w) = img1.shape();
    if img2.shape().1 != h || img2.shape().2 != w || (flow.height(), flow.width()) != (h, w) {
        return Err(Error::shape(
            "refinement inputs",
            format!("two images and a flow of {w}x{h}"),
            format!(
                "{}x{} and a flow of {}x{}",
                img2.width(),
                img2.height(),
                flow.width(),
                flow.height()
            ),
        ));
    }
    if flow.data().iter().any(|x| !x.is_finite()) {
        return Err(Error::invalid("flow to refine", "holds non-finite vectors"));
    }
    if h == 0 || w == 0 {
        return Ok(flow.clone());
    }
    let k = solver::Weights {
        alpha: cfg.alpha,
        delta: cfg.delta,
        gamma: cfg.gamma,
        fixed_point_iters: cfg.fixed_point_iters,
        sor_iters: cfg.sor_iters,
        omega: cfg.omega,
    };
    let mut out = flow.clone();
    // The frames' luma once, downscaled per scale (both steps are linear, so the order only
    // changes float rounding).
    let (g1, g2) = (grey255(img1)?, grey255(img2)?);
    for &s in &cfg.scales {
        let scaled;
        let (a, b) = if s == 1 {
            (&g1, &g2)
        } else {
            scaled = (
                downscale(&g1, 1.0 / s as f64)?,
                downscale(&g2, 1.0 / s as f64)?,
            );
            (&scaled.0, &scaled.1)
        };
        let (_, sh, sw) = a.shape();
        if sh < 3 || sw < 3 {
            continue; // too small to hold a derivative
        }
        // The flow area-averaged as the frames are, its vectors scaled by the size ratio.
        let start = resize_flow(&out, sh, sw)?;
        let (i0, i1) = (a.plane(0), b.plane(0));
        let mut u = start.u().to_vec();
        let mut v = start.v().to_vec();
        let terms = linearise::terms(i0, i1, &u, &v, sh, sw, cfg.kappa);
        solver::solve(&terms, &mut u, &mut v, sh, sw, &k);
        if (sh, sw) == (h, w) {
            let mut data = u;
            data.extend_from_slice(&v);
            out = Flow::from_vec(h, w, data)?;
        } else {
            // Add the increment, brought back to full size, to the full-size flow.
            let inc: Vec<f32> = u
                .iter()
                .chain(&v)
                .zip(start.data())
                .map(|(r, s)| r - s)
                .collect();
            let inc = resize_flow(&Flow::from_vec(sh, sw, inc)?, h, w)?;
            // The coarse pass sees the flow as its coarse version. Where the full-size flow
            // holds detail that version lacks (a small mover the network resolved), deviating
            // from it by a coarse pixel (s px) or more, the pass solved for a flow that is not
            // there, and its increment would smooth the detail away for good: the finer passes'
            // linearisation cannot bring back a motion many pixels off. So the increment fades
            // from whole where the coarse version holds the flow to nothing a coarse pixel away
            // from it. A coarse pixel's constraints read the frames over the five-point
            // derivatives' reach, two coarse pixels, so detail that near also corrupts its
            // increment (through the metalens, whose blur spreads a mover's light over tens of
            // pixels, most of all): the weight is the least over that reach (2s px), then
            // averaged over a coarse pixel's neighbourhood.
            let n = h * w;
            let coarse = resize_flow(&start, h, w)?;
            let (f, c) = (out.data(), coarse.data());
            let weight: Vec<f32> = (0..n)
                .map(|k| {
                    let d = (f[k] - c[k]).hypot(f[n + k] - c[n + k]);
                    (1.0 - d / s as f32).clamp(0.0, 1.0)
                })
                .collect();
            let weight = box_min(&weight, w, h, 2 * s as usize);
            let (weight, _) = box_mean(&weight, w, h, s as usize);
            let data: Vec<f32> = out
                .data()
                .iter()
                .zip(inc.data())
                .enumerate()
                .map(|(k, (o, i))| o + weight[k % n] * i)
                .collect();
            out = Flow::from_vec(h, w, data)?;
        }
    }
    Ok(out)
}

/// The luma (Rec. 601) of `img` in 8-bit units, one plane; a grey image is its own channel.
fn grey255(img: &Image) -> Result<Image> {
    let (c, h, w) = img.shape();
    let data = if c < 3 {
        img.plane(0).iter().map(|x| 255.0 * x).collect()
    } else {
        let (r, g, b) = (img.plane(0), img.plane(1), img.plane(2));
        (0..h * w)
            .map(|i| 255.0 * (0.299 * r[i] + 0.587 * g[i] + 0.114 * b[i]))
            .collect()
    };
    Image::from_vec(1, h, w, data)
}

#[cfg(test)]
mod tests;
