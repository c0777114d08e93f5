//! The heavy operations of one MMS pair, enumerated from its config along the layers of
//! `flow::model`: each kernel call with its real shapes, FLOPs and weights, and how often it runs
//! per pair (`pins bench-flow --mode kernels` times them).

use serde::Serialize;

use crate::flow::kernels::act::Act;
use crate::flow::kernels::geometry::{ConvParams, Geometry};
use crate::flow::kernels::shifted;
use crate::flow::model::{MmsConfig, NormKind};

/// One kernel call of the network, with its real shapes.
#[derive(Clone, Debug, PartialEq)]
pub enum Kernel {
    /// `x` `[B, Cin, H, W]` ⋆ `w` `[Cout, Cin, kh, kw]` + bias, then the activation.
    Conv {
        xs: [usize; 4],
        ws: [usize; 4],
        params: ConvParams,
        act: Act,
    },
    /// Instance (groups = C) or group normalisation of `[B, C, HW]`, with γ and β.
    Norm { shape: [usize; 3], groups: usize },
    /// The correlation volume of `[B, C, H, W]` features and its pooled pyramid.
    Corr { shape: [usize; 4], levels: usize },
    /// The (2r+1)² window lookup of every level around `[B, 2, H, W]` positions.
    Lookup {
        shape: [usize; 3],
        levels: usize,
        radius: usize,
    },
    /// Convex 8× upsampling of a `[B, 2, H, W]` flow by `[B, 576, H, W]` logits.
    Upsample { shape: [usize; 3] },
}

impl Kernel {
    /// Floating-point operations of one call: 2 per multiply-add of a convolution or product,
    /// 7 per value of a normalisation (mean 1, variance 3, normalise 3), 3 per bilinear
    /// interpolation step of the lookup (rows, then columns), 81 per full-resolution pixel of
    /// the upsampling (a 9-way softmax at 5 per term, 2 × 9 multiply-adds), 4 per pooled cell.
    pub fn flops(&self) -> f64 {
        match *self {
            Kernel::Conv { xs, ws, params, .. } => {
                let g = Geometry::new(xs, ws, &params);
                2.0 * (g.batch * g.cout * g.k() * g.ho * g.wo) as f64
            }
            Kernel::Norm { shape, .. } => 7.0 * shape.iter().product::<usize>() as f64,
            Kernel::Corr {
                shape: [b, c, h, w],
                levels,
            } => {
                let hw = (h * w) as f64;
                let pooled: f64 = (1..levels)
                    .map(|l| ((h >> l) * (w >> l)) as f64)
                    .sum::<f64>();
                b as f64 * (2.0 * c as f64 * hw * hw + 4.0 * hw * pooled)
            }
            Kernel::Lookup {
                shape: [b, h, w],
                levels,
                radius,
            } => {
                let k = (2 * radius + 1) as f64;
                (b * h * w * levels) as f64 * 3.0 * ((k + 1.0) * k + k * k)
            }
            Kernel::Upsample { shape: [b, h, w] } => 81.0 * (b * 64 * h * w) as f64,
        }
    }

    /// The shapes, as the table prints them.
    pub fn shape(&self) -> String {
        match *self {
            Kernel::Conv { xs, ws, params, .. } => {
                let g = Geometry::new(xs, ws, &params);
                let path = if shifted::eligible_forward(&g) {
                    "shifted"
                } else {
                    "unfolded"
                };
                let stride = match params.stride[0] {
                    1 => String::new(),
                    s => format!("/{s}"),
                };
                let dil = match params.dilation[0] {
                    1 => String::new(),
                    d => format!(" d{d}"),
                };
                format!(
                    "{}×{}{stride}{dil} {}→{} at {}×{}, {path}",
                    ws[2], ws[3], ws[1], ws[0], g.ho, g.wo
                )
            }
            Kernel::Norm {
                shape: [_, c, hw],
                groups,
            } => format!("{c} ch × {hw} px, {groups} groups"),
            Kernel::Corr {
                shape: [_, c, h, w],
                levels,
            } => format!("{c} ch, ({h}·{w})² pairs, {levels} levels"),
            Kernel::Lookup {
                shape: [_, h, w],
                levels,
                radius,
            } => format!("{levels} × {k}² taps at {h}×{w}", k = 2 * radius + 1),
            Kernel::Upsample { shape: [_, h, w] } => format!("{h}×{w} → {}×{}", 8 * h, 8 * w),
        }
    }

    /// Weight elements of a convolution (0 for the other kernels).
    pub fn weights(&self) -> usize {
        match self {
            Kernel::Conv { ws, .. } => ws.iter().product(),
            _ => 0,
        }
    }
}

/// Where an operation runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Part {
    /// The feature encoder (both frames) and the context encoder (frame 1).
    Encoders,
    /// Once per pair: the correlation volume and the final upsampling.
    Pair,
    /// Every refinement.
    Update,
}

/// One operation of the network and how often it runs per pair.
#[derive(Clone, Debug)]
pub struct Op {
    pub name: String,
    pub part: Part,
    pub count: usize,
    pub kernel: Kernel,
}

/// The heavy operations of one pair (batch 1) at `height`×`width` with `iters` refinements,
/// each layer as often as it runs: the feature encoder on both frames (once more per frame on
/// a video that reuses them: one), the context encoder on frame 1, the update block `iters`
/// times, its flow head alone before the last update and stacked with the mask head at the
/// last (as `Mms::iterate` runs them without `all`). Identical layers are merged, their
/// counts added. Every image is timed on its own (batch 1).
pub fn ops(cfg: &MmsConfig, height: usize, width: usize, iters: usize) -> Vec<Op> {
    let mut merged: Vec<Op> = Vec::new();
    for op in layers(cfg, height, width, iters) {
        match merged
            .iter_mut()
            .find(|m| m.name == op.name && m.kernel == op.kernel)
        {
            Some(m) => m.count += op.count,
            None => merged.push(op),
        }
    }
    merged
}

/// [`ops`] before merging: one entry per layer of the model (per encoder, per head).
fn layers(cfg: &MmsConfig, height: usize, width: usize, iters: usize) -> Vec<Op> {
    let mut out = Vec::new();
    encoder(
        &mut out,
        cfg,
        cfg.feature_dim,
        cfg.feature_norm,
        2,
        [height, width],
    );
    encoder(
        &mut out,
        cfg,
        cfg.hidden_dim + cfg.context_dim,
        cfg.context_norm,
        1,
        [height, width],
    );
    let (h8, w8) = (height / 8, width / 8);
    let at = |c: usize| [1, c, h8, w8];
    let push = |out: &mut Vec<Op>, name: &str, part: Part, count: usize, kernel: Kernel| {
        if count > 0 {
            out.push(Op {
                name: name.into(),
                part,
                count,
                kernel,
            });
        }
    };
    push(
        &mut out,
        "correlation volume + pyramid",
        Part::Pair,
        1,
        Kernel::Corr {
            shape: at(cfg.feature_dim),
            levels: cfg.corr_levels,
        },
    );
    let u = Part::Update;
    push(
        &mut out,
        "correlation lookup",
        u,
        iters,
        Kernel::Lookup {
            shape: [1, h8, w8],
            levels: cfg.corr_levels,
            radius: cfg.corr_radius,
        },
    );
    let [dc, df, dout] = cfg.motion_dims;
    let conv_at = |cin: usize, cout: usize, k: usize, act: Act| {
        let p = (k - 1) / 2;
        Kernel::Conv {
            xs: at(cin),
            ws: [cout, cin, k, k],
            params: ConvParams::same(p, 1),
            act,
        }
    };
    let (relu, id) = (Act::Relu, Act::Identity);
    let motion = [
        ("motion corr 1×1", cfg.corr_channels(), dc, 1),
        ("motion corr 3×3", dc, dc, 3),
        ("motion flow 7×7", 2, df, 7),
        ("motion flow 3×3", df, df / 2, 3),
        ("motion out 3×3", dc + df / 2, dout - 2, 3),
    ];
    for (name, cin, cout, k) in motion {
        push(&mut out, name, u, iters, conv_at(cin, cout, k, relu));
    }
    // The ConvGRU at inference (`ops::gru`): x once for all three gates, h once for z and r,
    // r⊙h for q.
    let (ch, cx) = (cfg.hidden_dim, cfg.context_dim + dout);
    push(
        &mut out,
        "GRU x → z,r,q 3×3",
        u,
        iters,
        conv_at(cx, 3 * ch, 3, id),
    );
    push(
        &mut out,
        "GRU h → z,r 3×3",
        u,
        iters,
        conv_at(ch, 2 * ch, 3, id),
    );
    push(
        &mut out,
        "GRU r⊙h → q 3×3",
        u,
        iters,
        conv_at(ch, ch, 3, id),
    );
    let head = cfg.head_dim;
    push(
        &mut out,
        "flow head 3×3",
        u,
        iters - 1,
        conv_at(ch, head, 3, relu),
    );
    push(
        &mut out,
        "flow + mask heads 3×3",
        u,
        1,
        conv_at(ch, 2 * head, 3, relu),
    );
    push(&mut out, "flow out 3×3", u, iters, conv_at(head, 2, 3, id));
    push(&mut out, "mask out 1×1", u, 1, conv_at(head, 64 * 9, 1, id));
    push(
        &mut out,
        "convex upsampling",
        Part::Pair,
        1,
        Kernel::Upsample { shape: [1, h8, w8] },
    );
    out
}

/// The layers of one DSMSCE encoder (`model::encoder`) on `count` images per pair.
fn encoder(
    out: &mut Vec<Op>,
    cfg: &MmsConfig,
    dim: usize,
    norm: NormKind,
    count: usize,
    [height, width]: [usize; 2],
) {
    let [d1, d2, d3] = cfg.encoder_dims;
    let mut push = |name: &str, kernel: Kernel| {
        out.push(Op {
            name: name.into(),
            part: Part::Encoders,
            count,
            kernel,
        })
    };
    // A k×k layer with stride s and dilation d on a [1, cin, h, w] input, padded as
    // `blocks::conv` pads.
    let layer = |cin: usize, cout: usize, k: usize, s: usize, d: usize, [h, w]: [usize; 2]| {
        let p = d * (k - 1) / 2;
        Kernel::Conv {
            xs: [1, cin, h, w],
            ws: [cout, cin, k, k],
            params: ConvParams {
                stride: [s, s],
                padding: [(p, p), (p, p)],
                dilation: [d, d],
            },
            act: Act::Identity,
        }
    };
    let norm_of = |c: usize, [h, w]: [usize; 2]| {
        match norm {
            NormKind::Instance => Some(("instance norm", c)),
            NormKind::Group => Some(("group norm", 8.min(c))),
            NormKind::None => None,
        }
        .map(|(name, groups)| {
            (
                name,
                Kernel::Norm {
                    shape: [1, c, h * w],
                    groups,
                },
            )
        })
    };
    let half = |[h, w]: [usize; 2]| [h.div_ceil(2), w.div_ceil(2)];
    let s1 = [height.div_ceil(2), width.div_ceil(2)];
    push("stem 7×7/2", layer(3, d1, 7, 2, 1, [height, width]));
    let mut norms = vec![(d1, s1)];
    // The residual stages: (input, output channels, stride of the first block, input size).
    let (s2, s3) = (half(s1), half(half(s1)));
    for (stage, cin, cout, stride, size) in
        [(1, d1, d1, 1, s1), (2, d1, d2, 2, s1), (3, d2, d3, 2, s2)]
    {
        let out_size = if stride == 1 { size } else { half(size) };
        push(
            &format!("stage {stage} 3×3{}", if stride == 1 { "" } else { "/2" }),
            layer(cin, cout, 3, stride, 1, size),
        );
        for _ in 0..3 {
            push(
                &format!("stage {stage} 3×3"),
                layer(cout, cout, 3, 1, 1, out_size),
            );
        }
        norms.extend([(cout, out_size); 4]);
        if stride != 1 || cin != cout {
            push(
                &format!("stage {stage} skip 1×1/{stride}"),
                layer(cin, cout, 1, stride, 1, size),
            );
            norms.push((cout, out_size));
        }
    }
    push("pyramid fuse 3×3", layer(4 * d3, d3, 3, 1, 1, s3));
    norms.push((d3, s3));
    push("DASPP 1×1", layer(d3, d3, 1, 1, 1, s3));
    for &d in &cfg.dilations {
        push(&format!("DASPP 3×3 d{d}"), layer(d3, d3, 3, 1, d, s3));
    }
    push("DASPP global 1×1", layer(d3, d3, 1, 1, 1, [1, 1]));
    push(
        "DASPP fuse 1×1",
        layer(d3 * (cfg.dilations.len() + 2), dim, 1, 1, 1, s3),
    );
    norms.push((dim, s3));
    for (c, size) in norms {
        if let Some((name, kernel)) = norm_of(c, size) {
            push(name, kernel);
        }
    }
}

#[cfg(test)]
mod tests {
    use burn::prelude::*;

    use super::*;
    use crate::flow::model::Mms;

    /// The enumeration walks the real model: its convolutions, one entry per layer with one
    /// update, hold exactly the model's convolution weights (the ConvGRU's split kernels and
    /// the stacked heads add up to the layers they stand for), and every one has an output.
    #[test]
    fn enumerated_layers_hold_the_models_convolution_weights() {
        struct Count(usize);
        impl burn::module::ModuleVisitor for Count {
            fn visit_float<const D: usize>(&mut self, p: &burn::module::Param<Tensor<D>>) {
                if D == 4 {
                    self.0 += p.val().dims().iter().product::<usize>();
                }
            }
        }
        for cfg in [MmsConfig::mms_small(), MmsConfig::mms()] {
            let mut c = Count(0);
            Mms::new(&cfg, &Device::flex()).visit(&mut c);
            let ops = layers(&cfg, 64, 96, 1);
            let enumerated: usize = ops.iter().map(|o| o.kernel.weights()).sum();
            assert_eq!(enumerated, c.0, "{}", cfg.name);
            for o in &ops {
                assert!(o.kernel.flops() > 0.0, "{}: {}", o.name, o.kernel.shape());
            }
        }
    }

    /// Merging keeps the counts: with 4 updates the flow head runs alone 3 times, the update
    /// block's convolutions 4 times, the encoders' on 3 images.
    #[test]
    fn counts_per_pair() {
        let ops = ops(&MmsConfig::mms_small(), 240, 320, 4);
        let count = |name: &str| {
            ops.iter()
                .filter(|o| o.name == name)
                .map(|o| o.count)
                .sum::<usize>()
        };
        assert_eq!(count("flow head 3×3"), 3);
        assert_eq!(count("flow + mask heads 3×3"), 1);
        assert_eq!(count("GRU x → z,r,q 3×3"), 4);
        assert_eq!(count("stem 7×7/2"), 3);
        assert_eq!(count("stage 1 3×3"), 12);
        assert_eq!(count("instance norm"), 2 * 17);
        assert_eq!(count("group norm"), 17);
    }
}
