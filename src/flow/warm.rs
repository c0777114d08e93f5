//! RAFT's warm start on video: the previous pair's flow, carried forward along itself, starts
//! the next pair's updates. Each cell of the network's grid moves by its own flow (constant
//! velocity, scaled by the ratio of the two pairs' time gaps) and lands on the nearest cell;
//! where several land on one cell the longest motion wins (a mover passes in front of what it
//! moves over); cells that nothing lands on (background a mover uncovers) take the background's
//! motion. (RAFT's `forward_interpolate` fills them from the nearest landed vector instead; on
//! a textureless background the network then never corrects a mover's motion left in its trail,
//! and the trail grows from pair to pair.)
//!
//! Before it is carried, the background is made one motion ([`settle_background`]): the cells
//! whose vector lies within the flow's own noise of its median vector take the median. An
//! estimate's noise differs from pair to pair; carried forward unchanged it would be added to
//! the next pair's and grow along the video, while a mover's motion and the background's
//! common motion (a still or panning camera) carry over.

/// The flow `flow` (`[2, H, W]` row-major, grid pixels) forward-warped by `ratio` × itself:
/// the flow expected one pair later. A cell that receives several vectors keeps the longest;
/// cells that receive none take `ratio` × `hole` (the background's motion).
pub fn forward_warp(flow: &[f32], h: usize, w: usize, ratio: f32, hole: (f32, f32)) -> Vec<f32> {
    let n = h * w;
    assert_eq!(flow.len(), 2 * n, "forward_warp: flow is not [2, {h}, {w}]");
    let mut out = vec![0.0f32; 2 * n];
    let mut landed = vec![f32::NEG_INFINITY; n]; // squared length of the kept vector
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (flow[y * w + x] * ratio, flow[n + y * w + x] * ratio);
            if !(u.is_finite() && v.is_finite()) {
                continue;
            }
            let (tx, ty) = ((x as f32 + u).round(), (y as f32 + v).round());
            if tx < 0.0 || ty < 0.0 || tx >= w as f32 || ty >= h as f32 {
                continue;
            }
            let t = ty as usize * w + tx as usize;
            if u * u + v * v > landed[t] {
                landed[t] = u * u + v * v;
                out[t] = u;
                out[n + t] = v;
            }
        }
    }
    for t in 0..n {
        if landed[t] == f32::NEG_INFINITY {
            out[t] = hole.0 * ratio;
            out[n + t] = hole.1 * ratio;
        }
    }
    out
}

/// `flow` (`[2, H, W]`) with every vector within the noise of the median vector replaced by
/// it, and the median vector (the background's motion): the noise is a robust spread of the
/// vectors' distances d to the median vector (median(d) + 3 · 1.4826 · MAD(d)); vectors
/// farther away (movers) are kept.
pub fn settle_background(flow: &[f32], h: usize, w: usize) -> (Vec<f32>, (f32, f32)) {
    let n = h * w;
    assert_eq!(
        flow.len(),
        2 * n,
        "settle_background: flow is not [2, {h}, {w}]"
    );
    let (u, v) = flow.split_at(n);
    let (Some(mu), Some(mv)) = (median(u.to_vec()), median(v.to_vec())) else {
        return (flow.to_vec(), (0.0, 0.0));
    };
    let dist: Vec<f32> = u
        .iter()
        .zip(v)
        .map(|(a, b)| (a - mu).hypot(b - mv))
        .collect();
    let Some(md) = median(dist.clone()) else {
        return (flow.to_vec(), (mu, mv));
    };
    let mad = median(dist.iter().map(|d| (d - md).abs()).collect()).unwrap_or(0.0);
    let noise = md + 3.0 * 1.4826 * mad;
    let mut out = flow.to_vec();
    for (i, d) in dist.iter().enumerate() {
        if *d <= noise {
            out[i] = mu;
            out[n + i] = mv;
        }
    }
    (out, (mu, mv))
}

/// The median of the finite values (the upper one of an even count); `None` when there are
/// none.
fn median(mut v: Vec<f32>) -> Option<f32> {
    v.retain(|x| x.is_finite());
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_background_settles_on_its_median_and_movers_stay() {
        // A still background with ±0.3 px noise, a 2×2 mover at 4 px.
        let (h, w) = (8, 8);
        let mut f = vec![0.0f32; 2 * h * w];
        for i in 0..h * w {
            let s = 0.3 * (i as f32 * 1.7).sin();
            f[i] = s;
            f[h * w + i] = 0.3 * (i as f32 * 0.9 + 1.0).cos();
        }
        for (y, x) in [(3, 3), (3, 4), (4, 3), (4, 4)] {
            f[y * w + x] = 4.0;
            f[h * w + y * w + x] = 1.0;
        }
        let (out, (mu, mv)) = settle_background(&f, h, w);
        assert!(mu.abs() <= 0.3 && mv.abs() <= 0.3, "median ({mu}, {mv})");
        for i in 0..h * w {
            let mover = [(3, 3), (3, 4), (4, 3), (4, 4)].contains(&(i / w, i % w));
            if mover {
                assert_eq!((out[i], out[h * w + i]), (4.0, 1.0));
            } else {
                assert_eq!((out[i], out[h * w + i]), (mu, mv), "cell {i}");
            }
        }
        // A uniform pan stays the pan.
        let pan: Vec<f32> = [vec![2.5; 16], vec![-1.0; 16]].concat();
        assert_eq!(settle_background(&pan, 4, 4), (pan, (2.5, -1.0)));
    }

    fn uniform(h: usize, w: usize, u: f32, v: f32) -> Vec<f32> {
        let mut f = vec![u; h * w];
        f.extend(vec![v; h * w]);
        f
    }

    #[test]
    fn a_uniform_motion_stays_uniform() {
        // Everything moves 2 cells right: the two left columns are holes, the background's.
        let out = forward_warp(&uniform(4, 6, 2.0, 0.0), 4, 6, 1.0, (2.0, 0.0));
        assert!(out[..24].iter().all(|&u| u == 2.0), "{out:?}");
        assert!(out[24..].iter().all(|&v| v == 0.0));
    }

    #[test]
    fn a_moving_block_is_carried_along_its_motion() {
        // A 2×2 block at x = 1..3 moving +2 cells in x on a still background.
        let (h, w) = (4, 8);
        let mut f = uniform(h, w, 0.0, 0.0);
        for y in 1..3 {
            for x in 1..3 {
                f[y * w + x] = 2.0;
            }
        }
        let out = forward_warp(&f, h, w, 1.0, (0.0, 0.0));
        for y in 1..3 {
            for x in 3..5 {
                assert_eq!(out[y * w + x], 2.0, "({x}, {y}) should carry the block");
            }
        }
        // Where the block was, nothing landed: the still background's motion fills in.
        assert_eq!(out[w + 1], 0.0);
        assert_eq!(out[w + 7], 0.0);
    }

    #[test]
    fn the_ratio_scales_the_motion_and_where_it_lands() {
        let out = forward_warp(&uniform(3, 9, 1.0, -1.0), 3, 9, 2.0, (1.0, -1.0));
        assert!(out[..27].iter().all(|&u| u == 2.0));
        assert!(out[27..].iter().all(|&v| v == -2.0));
    }

    #[test]
    fn everything_leaving_the_grid_gives_zero_and_non_finite_is_skipped() {
        assert!(
            forward_warp(&uniform(2, 2, 50.0, 0.0), 2, 2, 1.0, (0.0, 0.0))
                .iter()
                .all(|&v| v == 0.0)
        );
        let mut f = uniform(2, 3, 0.0, 0.0);
        f[0] = f32::NAN;
        assert!(
            forward_warp(&f, 2, 3, 1.0, (0.0, 0.0))
                .iter()
                .all(|v| v.is_finite())
        );
    }
}
