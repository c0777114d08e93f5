//! The MMS network's configuration (Notes S9–S11): two named sizes, `mms` (RAFT-sized) and
//! `mms-small` (sized to train on a 2-core CPU). The config travels with the weights.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Feature normalisation inside an encoder.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NormKind {
    /// Per-sample, per-channel (RAFT's feature encoder).
    Instance,
    /// Groups of channels; independent of the batch, so training and inference agree.
    Group,
    None,
}

/// Every size of the network. Unknown keys are rejected.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MmsConfig {
    /// `mms`, `mms-small`, or a user's name.
    pub name: String,
    /// Channels of the three encoder stages (1/2, 1/4, 1/8 resolution).
    pub encoder_dims: [usize; 3],
    /// Channels of the matching features at 1/8 resolution.
    pub feature_dim: usize,
    /// GRU hidden state channels.
    pub hidden_dim: usize,
    /// Context feature channels fed to every update.
    pub context_dim: usize,
    /// Motion encoder widths: correlation branch, flow branch, output.
    pub motion_dims: [usize; 3],
    /// Width of the flow and mask heads.
    pub head_dim: usize,
    /// Dilation rates of the DASPP block (Eq. S14).
    pub dilations: Vec<usize>,
    /// Correlation pyramid levels.
    pub corr_levels: usize,
    /// Lookup radius r: a (2r+1)² window per level.
    pub corr_radius: usize,
    /// Refinement iterations by default.
    pub iters: usize,
    pub feature_norm: NormKind,
    pub context_norm: NormKind,
}

impl MmsConfig {
    /// The full-size network, the size of RAFT (Note S9).
    pub fn mms() -> Self {
        Self {
            name: "mms".into(),
            encoder_dims: [64, 96, 128],
            feature_dim: 256,
            hidden_dim: 128,
            context_dim: 128,
            motion_dims: [256, 128, 128],
            head_dim: 256,
            dilations: vec![6, 12, 18],
            corr_levels: 4,
            corr_radius: 4,
            iters: 12,
            feature_norm: NormKind::Instance,
            context_norm: NormKind::Group,
        }
    }

    /// The small network: the same structure, narrower, for training on a laptop CPU.
    pub fn mms_small() -> Self {
        Self {
            name: "mms-small".into(),
            encoder_dims: [32, 48, 64],
            feature_dim: 96,
            hidden_dim: 64,
            context_dim: 48,
            motion_dims: [64, 32, 64],
            head_dim: 96,
            dilations: vec![6, 12, 18],
            corr_levels: 4,
            corr_radius: 4,
            iters: 12,
            feature_norm: NormKind::Instance,
            context_norm: NormKind::Group,
        }
    }

    /// A named config.
    pub fn named(name: &str) -> Result<Self> {
        match name {
            "mms" => Ok(Self::mms()),
            "mms-small" => Ok(Self::mms_small()),
            other => Err(Error::invalid(
                "model",
                format!("unknown model {other:?}; use mms or mms-small"),
            )),
        }
    }

    /// Checks the sizes.
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("encoder_dims", self.encoder_dims.iter().all(|&d| d > 0)),
            ("feature_dim", self.feature_dim > 0),
            ("hidden_dim", self.hidden_dim > 0),
            ("context_dim", self.context_dim > 0),
            (
                "motion_dims",
                self.motion_dims.iter().all(|&d| d > 0) && self.motion_dims[2] > 2,
            ),
            ("head_dim", self.head_dim > 0),
            ("corr_levels", (1..=6).contains(&self.corr_levels)),
            ("corr_radius", (1..=8).contains(&self.corr_radius)),
            ("iters", (1..=64).contains(&self.iters)),
            (
                "dilations",
                self.dilations.iter().all(|&d| (1..=64).contains(&d)),
            ),
        ];
        for (name, ok) in positive {
            if !ok {
                return Err(Error::invalid(format!("model.{name}"), "out of range"));
            }
        }
        for (name, norm, dims) in [
            ("feature_norm", self.feature_norm, self.feature_dim),
            (
                "context_norm",
                self.context_norm,
                self.hidden_dim + self.context_dim,
            ),
        ] {
            if norm == NormKind::Group
                && (self.encoder_dims.iter().any(|d| d % 8 != 0) || dims % 8 != 0)
            {
                return Err(Error::invalid(
                    format!("model.{name}"),
                    "group norm needs every width divisible by 8",
                ));
            }
        }
        Ok(())
    }

    /// Channels of one correlation feature vector: levels · (2r+1)².
    pub fn corr_channels(&self) -> usize {
        self.corr_levels * (2 * self.corr_radius + 1).pow(2)
    }

    /// The smallest input side the pyramid supports: every level needs at least 2 cells.
    pub fn min_side(&self) -> usize {
        8 * (1 << self.corr_levels.saturating_sub(1)).max(2)
    }
}
