//! The MMS network end to end on the CPU backend: shapes, padding to any size, stability on
//! extreme inputs (finite outputs and gradients), learning (overfitting one batch), and the
//! weights file round trip with its errors.

use burn::optim::{AdamWConfig, GradientsParams};
use burn::prelude::*;
use burn::tensor::Distribution;

use pins::flow::loss::sequence_loss;
use pins::flow::model::{Mms, MmsConfig, NormKind};
use pins::flow::{infer::predict_flow, weights};
use pins::{Flow, Image};

/// A tiny network so that tests run in seconds.
fn tiny() -> MmsConfig {
    MmsConfig {
        name: "tiny".into(),
        encoder_dims: [8, 16, 24],
        feature_dim: 32,
        hidden_dim: 16,
        context_dim: 16,
        motion_dims: [16, 8, 16],
        head_dim: 16,
        dilations: vec![2, 4],
        corr_levels: 3,
        corr_radius: 3,
        iters: 4,
        feature_norm: NormKind::Instance,
        context_norm: NormKind::Group,
    }
}

fn textured(h: usize, w: usize, shift: (f32, f32)) -> Image {
    let mut img = Image::zeros(3, h, w);
    for c in 0..3 {
        for y in 0..h {
            for x in 0..w {
                let (xf, yf) = (x as f32 - shift.0, y as f32 - shift.1);
                let v = 0.5 + 0.25 * ((xf * 0.37 + c as f32).sin() + (yf * 0.23 + xf * 0.11).cos());
                img.set(c, y, x, v.clamp(0.0, 1.0));
            }
        }
    }
    img
}

#[test]
fn forward_shapes_and_any_input_size() {
    let dev = Device::flex();
    let cfg = tiny();
    let net = Mms::new(&cfg, &dev);
    let a = Tensor::<4>::random([2, 3, 64, 64], Distribution::Default, &dev);
    let preds = net.forward(a.clone(), a, 2, true);
    assert_eq!(preds.len(), 2);
    assert_eq!(preds[1].dims(), [2, 2, 64, 64]);
    // 37×50 is padded to the pyramid minimum and cropped back.
    let flow = predict_flow(
        &net,
        &cfg,
        &textured(37, 50, (0.0, 0.0)),
        &textured(37, 50, (1.0, 0.0)),
        3,
        &dev,
    )
    .unwrap();
    assert_eq!((flow.height(), flow.width()), (37, 50));
    assert!(
        predict_flow(
            &net,
            &cfg,
            &textured(37, 50, (0.0, 0.0)),
            &textured(40, 50, (0.0, 0.0)),
            3,
            &dev
        )
        .is_err()
    );
}

#[test]
fn extreme_inputs_give_finite_flow_and_gradients() {
    let dev = Device::flex().autodiff();
    let cfg = tiny();
    let net = Mms::new(&cfg, &dev);
    let gt_huge = Tensor::<4>::ones([1, 2, 64, 64], &dev).mul_scalar(300.0); // far beyond r·2^levels
    for (v1, v2) in [(0.0f32, 0.0f32), (1.0, 1.0), (0.5, 0.5), (0.0, 1.0)] {
        let a = Tensor::<4>::ones([1, 3, 64, 64], &dev).mul_scalar(v1);
        let b = Tensor::<4>::ones([1, 3, 64, 64], &dev).mul_scalar(v2);
        let preds = net.forward(a, b, 3, true);
        let valid = Tensor::<4>::ones([1, 1, 64, 64], &dev);
        let loss = sequence_loss(&preds, gt_huge.clone(), valid, 0.8);
        let l: f32 = loss.clone().into_scalar();
        assert!(l.is_finite(), "loss {l} for frames {v1}/{v2}");
        let mut grads = GradientsParams::from_grads(loss.backward(), &net);
        let norm = pins::flow::train::clip::clip_global_norm(&net, &mut grads, 1.0);
        assert!(
            norm.is_finite(),
            "gradient norm {norm} for frames {v1}/{v2}"
        );
    }
    // Long iteration counts stay finite.
    let inf = Mms::new(&cfg, &Device::flex());
    let flow = predict_flow(
        &inf,
        &cfg,
        &textured(64, 64, (0.0, 0.0)),
        &textured(64, 64, (3.0, -2.0)),
        32,
        &Device::flex(),
    )
    .unwrap();
    assert!(flow.data().iter().all(|v| v.is_finite()));
}

#[test]
fn overfits_one_batch() {
    // Two pairs with opposite shifts in one batch: no bias can fit both, so falling loss means
    // the matching (correlation lookup), the GRU and the upsampling all carry gradients.
    let dev = Device::flex().autodiff();
    let cfg = tiny();
    let mut net = Mms::new(&cfg, &dev);
    let mut optim = AdamWConfig::new().with_weight_decay(0.0).init();
    let img = |s| {
        Tensor::<4>::from_data(
            TensorData::new(textured(64, 64, s).into_vec(), [1, 3, 64, 64]),
            &dev,
        )
    };
    let a = Tensor::cat(vec![img((0.0, 0.0)), img((0.0, 0.0))], 0);
    let b = Tensor::cat(vec![img((3.0, -2.0)), img((-3.0, 2.0))], 0);
    let gt = Tensor::<4>::ones([2, 2, 64, 64], &dev)
        * Tensor::<2>::from_floats([[3.0, -2.0], [-3.0, 2.0]], &dev).reshape([2, 2, 1, 1]);
    let valid = Tensor::<4>::ones([2, 1, 64, 64], &dev);
    let mut first = None;
    let mut last = 0.0;
    for _ in 0..60 {
        let preds = net.forward(a.clone(), b.clone(), 3, true);
        let loss = sequence_loss(&preds, gt.clone(), valid.clone(), 0.8);
        last = loss.clone().into_scalar::<f32>();
        first.get_or_insert(last);
        let mut grads = GradientsParams::from_grads(loss.backward(), &net);
        pins::flow::train::clip::clip_global_norm(&net, &mut grads, 1.0);
        net = optim.step(1e-3, net, grads);
    }
    let first = first.unwrap();
    assert!(last < 0.4 * first, "loss {first} → {last}");
}

#[test]
fn weights_round_trip_and_reject_bad_files() {
    let dev = Device::flex();
    let cfg = tiny();
    let net = Mms::new(&cfg, &dev);
    let d = tempfile::tempdir().unwrap();
    let p = d.path().join("w.safetensors");
    weights::save(&p, &net, &cfg).unwrap();
    let (loaded, cfg2) = weights::load(&p, &dev).unwrap();
    assert_eq!(cfg2, cfg);
    let (a, b) = (textured(64, 64, (0.0, 0.0)), textured(64, 64, (2.0, 1.0)));
    let f1: Flow = predict_flow(&net, &cfg, &a, &b, 2, &dev).unwrap();
    let f2: Flow = predict_flow(&loaded, &cfg2, &a, &b, 2, &dev).unwrap();
    assert_eq!(f1, f2, "a loaded model computes exactly the same flow");

    // Corrupt: truncated.
    let bytes = std::fs::read(&p).unwrap();
    let bad = d.path().join("truncated.safetensors");
    std::fs::write(&bad, &bytes[..bytes.len() / 2]).unwrap();
    assert!(weights::load(&bad, &dev).is_err());
    // Garbage.
    std::fs::write(&bad, b"not a weights file at all").unwrap();
    let err = weights::load(&bad, &dev).err().unwrap().to_string();
    assert!(err.contains("truncated.safetensors"), "{err}");
    // Weights of another config under this config's name.
    let mut other = tiny();
    other.hidden_dim = 24;
    let other_net = Mms::new(&other, &dev);
    let wrong = d.path().join("wrong.safetensors");
    let bytes = weights::to_bytes(&other_net, &other).unwrap();
    // Swap the metadata config for the tiny one: the tensors no longer fit.
    let tiny_json = serde_json::to_string(&cfg).unwrap();
    let other_json = serde_json::to_string(&other).unwrap();
    let text = String::from_utf8_lossy(&bytes).replace(
        &other_json.replace('"', "\\\""),
        &tiny_json.replace('"', "\\\""),
    );
    let _ = text; // header edits change lengths; build the mismatch directly instead:
    let mixed = weights::to_bytes(&other_net, &cfg);
    if let Ok(mixed) = mixed {
        std::fs::write(&wrong, mixed).unwrap();
        let err = weights::load(&wrong, &dev)
            .expect_err("weights of another config must not load")
            .to_string();
        assert!(err.contains("do not fit"), "{err}");
    }
}

/// The sequence runner gives, for frames in memory and for image files alike, the flow of every
/// consecutive pair in order, exactly as the network gives it pair by pair; a frame of another
/// size is an error naming both files.
#[test]
fn sequence_runner_gives_every_consecutive_pair() {
    use pins::flow::infer::Predictor;
    use pins::flow::sequence::pair_flows;
    let dev = Device::flex();
    let cfg = tiny();
    let predictor = Predictor {
        model: Mms::new(&cfg, &dev),
        config: cfg.clone(),
        device: dev.clone(),
        refine: None,
        coarse_start: false,
    };
    let frames: Vec<Image> = (0..4)
        .map(|n| textured(40, 48, (n as f32, -0.5 * n as f32)))
        .collect();
    let flows: Vec<_> = pair_flows(&predictor, frames.as_slice(), 2)
        .collect::<pins::Result<_>>()
        .unwrap();
    assert_eq!(flows.len(), 3);
    for (n, pair) in flows.iter().enumerate() {
        assert_eq!(pair.index, n);
        assert!(pair.ms >= 0.0);
        let want =
            predict_flow(&predictor.model, &cfg, &frames[n], &frames[n + 1], 2, &dev).unwrap();
        assert_eq!(pair.flow, want, "pair {n}");
    }
    // The same frames as files.
    let d = tempfile::tempdir().unwrap();
    let mut files: Vec<std::path::PathBuf> = frames
        .iter()
        .enumerate()
        .map(|(n, f)| {
            let p = d.path().join(format!("f{n}.png"));
            pins::io::write_image(&p, f, pins::io::BitDepth::Sixteen).unwrap();
            p
        })
        .collect();
    let from_files: Vec<_> = pair_flows(&predictor, files.as_slice(), 2)
        .collect::<pins::Result<_>>()
        .unwrap();
    assert_eq!(from_files.len(), 3);
    // One frame, no pair; a frame of another size stops the sequence with both names.
    assert_eq!(pair_flows(&predictor, &frames[..1], 2).count(), 0);
    let odd = d.path().join("odd.png");
    pins::io::write_image(
        &odd,
        &textured(24, 48, (0.0, 0.0)),
        pins::io::BitDepth::Eight,
    )
    .unwrap();
    files[2] = odd;
    let results: Vec<_> = pair_flows(&predictor, files.as_slice(), 2).collect();
    assert!(results[0].is_ok());
    let err = results[1]
        .as_ref()
        .err()
        .map(|e| e.to_string())
        .unwrap_or_default();
    assert!(err.contains("f1.png") && err.contains("odd.png"), "{err}");
}

/// The warm start: from a zero flow the network gives exactly its flow from no start, and from
/// a start the result depends on it (the start is used, not ignored); a start of another size
/// is an error naming it.
#[test]
fn warm_start_is_used_and_zero_start_changes_nothing() {
    use pins::flow::infer::predict_flow_from;
    let dev = Device::flex();
    let cfg = tiny();
    let model = Mms::new(&cfg, &dev);
    let (a, b) = (textured(40, 56, (0.0, 0.0)), textured(40, 56, (3.0, -1.0)));
    let plain = predict_flow(&model, &cfg, &a, &b, 3, &dev).unwrap();
    let zero = Flow::zeros(40, 56);
    let from_zero = predict_flow_from(&model, &cfg, &a, &b, 3, &dev, Some(&zero)).unwrap();
    assert_eq!(plain, from_zero);
    let mut start = Flow::zeros(40, 56);
    for y in 0..40 {
        for x in 0..56 {
            start.set(y, x, 8.0, -4.0);
        }
    }
    let from_start = predict_flow_from(&model, &cfg, &a, &b, 3, &dev, Some(&start)).unwrap();
    // An untrained update adds small steps: the start's (8, -4) px stay in the estimate. Only
    // pixels whose 1/8 cell has all eight neighbours count: convex upsampling (RAFT's) pads
    // the coarse grid with zeros, and an untrained mask, near uniform, shrinks the flow of the
    // border cells by up to a half (over the whole 40×56 image the mean comes out ~0.78 × 8).
    // Over 60 initialisations the interior mean moved by 7.5..8.4 px.
    let (mut du, mut dv, mut n) = (0.0f32, 0.0f32, 0.0f32);
    for y in 8..32 {
        for x in 8..48 {
            let (s, p) = (from_start.get(y, x), plain.get(y, x));
            du += s.0 - p.0;
            dv += s.1 - p.1;
            n += 1.0;
        }
    }
    let (du, dv) = (du / n, dv / n);
    assert!(
        (du - 8.0).abs() < 1.5 && (dv + 4.0).abs() < 1.5,
        "the start moved the interior by ({du}, {dv}), not about (8, -4)"
    );
    let e = predict_flow_from(&model, &cfg, &a, &b, 3, &dev, Some(&Flow::zeros(40, 55)))
        .unwrap_err()
        .to_string();
    assert!(e.contains("initial flow"), "{e}");
}
