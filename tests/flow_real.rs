//! The flow commands' two stages around the network on real pairs with exact ground truth from
//! `../shared/data`, with the shipped weights, scored over the known pixels: the variational
//! refinement must recover the sub-pixel accuracy the 1/8-resolution network lacks
//! (Middlebury RubberWhale, Sintel alley_1), and the coarse start the large motions it misses
//! from zero (KITTI 2015 000000, mean |flow| 51 px).

mod common;
use common::{ok, pins, shared_data};

use std::path::Path;

/// Mean end-point error over the pixels whose ground truth is known.
fn epe(pred: &Path, gt: &Path) -> f64 {
    let (p, g) = (
        pins::io::read_flow(pred).unwrap(),
        pins::io::read_flow(gt).unwrap(),
    );
    let (mut sum, mut n) = (0.0f64, 0usize);
    for i in 0..g.u().len() {
        let (gu, gv) = (g.u()[i], g.v()[i]);
        if gu.is_finite() && gv.is_finite() {
            sum += ((p.u()[i] - gu).powi(2) as f64 + (p.v()[i] - gv).powi(2) as f64).sqrt();
            n += 1;
        }
    }
    assert!(n > 1000, "{} known pixels", n);
    sum / n as f64
}

/// `pins infer` at 12 iterations with `extra` flags.
fn infer(a: &Path, b: &Path, out: &Path, extra: &[&str]) {
    let mut args = vec![
        "infer",
        "--img1",
        a.to_str().unwrap(),
        "--img2",
        b.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--iters",
        "12",
    ];
    args.extend_from_slice(extra);
    ok(&pins(&args));
}

#[test]
fn refinement_recovers_sub_pixel_accuracy_on_real_pairs() {
    let Some(data) = shared_data() else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for (set, a, b, gt) in [
        (
            "middlebury_rubberwhale",
            "frame10.png",
            "frame11.png",
            "flow10.flo",
        ),
        (
            "sintel_alley1",
            "frame_0001.png",
            "frame_0002.png",
            "frame_0001.flo",
        ),
    ] {
        let dir = data.join(set);
        let mut scores = Vec::new();
        for refine in ["none", "variational"] {
            let out = tmp.path().join(format!("{set}-{refine}.flo"));
            infer(
                &dir.join(a),
                &dir.join(b),
                &out,
                &["--refine", refine, "--start", "zero"],
            );
            scores.push(epe(&out, &dir.join(gt)));
        }
        let (network, refined) = (scores[0], scores[1]);
        // Measured with stage 5 from zero: Middlebury 0.97 → 0.27 px, Sintel 0.93 → 0.27 px
        // (DIS medium: 0.23, 0.30).
        assert!(
            refined < 0.5 * network && refined < 0.4,
            "{set}: EPE {network:.3} (network) → {refined:.3} (refined)"
        );
    }
}

#[test]
fn coarse_start_finds_large_motions_on_a_real_pair() {
    let Some(data) = shared_data() else {
        return;
    };
    let dir = data.join("kitti2015_000000");
    let tmp = tempfile::tempdir().unwrap();
    let mut scores = Vec::new();
    for start in ["zero", "coarse"] {
        let out = tmp.path().join(format!("{start}.flo"));
        let flags = ["--refine", "none", "--start", start];
        infer(
            &dir.join("frame1.png"),
            &dir.join("frame2.png"),
            &out,
            &flags,
        );
        scores.push(epe(&out, &dir.join("flow_gt.png")));
    }
    let (zero, coarse) = (scores[0], scores[1]);
    // Measured with stage 5: 25.9 px from zero, 14.8 px from the coarse start (DIS medium 38.5);
    // with stage 8, whose network alone learnt larger motions in the campaign: 15.8 and 12.9;
    // with stage 9: 11.7 and 11.6, the network from zero now finding the road's motion itself.
    // The coarse start loses nothing, and the flow stays far below DIS medium's on the road.
    assert!(
        coarse <= 1.02 * zero && coarse < 20.0,
        "KITTI: EPE {zero:.2} from zero, {coarse:.2} from the coarse start"
    );
}
