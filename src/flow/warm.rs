//! RAFT's warm start on video: the previous pair's flow, carried forward along itself, starts
//! the next pair's updates. Each cell of the network's grid moves by its own flow (constant
//! velocity, scaled by the ratio of the two pairs' time gaps) and lands on the nearest cell;
//! where several land on one cell the longest motion wins (a mover passes in front of what it
//! moves over); cells that nothing lands on take the flow of the nearest cell that something
//! did (RAFT's `forward_interpolate`, which fills by nearest-neighbour interpolation).

use std::collections::VecDeque;

/// The flow `flow` (`[2, H, W]` row-major, grid pixels) forward-warped by `ratio` × itself:
/// the flow expected one pair later. A cell that receives several vectors keeps the longest;
/// cells that receive none take the nearest filled cell's (breadth-first, 4-connected); where nothing
/// lands at all (every vector leaves the grid), zero.
pub fn forward_warp(flow: &[f32], h: usize, w: usize, ratio: f32) -> Vec<f32> {
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
    let mut queue = VecDeque::new();
    let mut filled: Vec<bool> = landed.iter().map(|l| l.is_finite()).collect();
    queue.extend((0..n).filter(|&t| filled[t]));
    // Holes take their nearest filled neighbour's vector, in order of distance.
    while let Some(t) = queue.pop_front() {
        let (y, x) = (t / w, t % w);
        let neighbours = [
            (y > 0).then(|| t - w),
            (y + 1 < h).then(|| t + w),
            (x > 0).then(|| t - 1),
            (x + 1 < w).then(|| t + 1),
        ];
        for s in neighbours.into_iter().flatten() {
            if !filled[s] {
                filled[s] = true;
                out[s] = out[t];
                out[n + s] = out[n + t];
                queue.push_back(s);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(h: usize, w: usize, u: f32, v: f32) -> Vec<f32> {
        let mut f = vec![u; h * w];
        f.extend(vec![v; h * w]);
        f
    }

    #[test]
    fn a_uniform_motion_stays_uniform() {
        // Everything moves 2 cells right: the two left columns are holes, filled from the right.
        let out = forward_warp(&uniform(4, 6, 2.0, 0.0), 4, 6, 1.0);
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
        let out = forward_warp(&f, h, w, 1.0);
        for y in 1..3 {
            for x in 3..5 {
                assert_eq!(out[y * w + x], 2.0, "({x}, {y}) should carry the block");
            }
        }
        // Where the block was, nothing landed: the still background beside it fills in.
        assert_eq!(out[w + 1], 0.0);
        assert_eq!(out[w + 7], 0.0);
    }

    #[test]
    fn the_ratio_scales_the_motion_and_where_it_lands() {
        let out = forward_warp(&uniform(3, 9, 1.0, -1.0), 3, 9, 2.0);
        assert!(out[..27].iter().all(|&u| u == 2.0));
        assert!(out[27..].iter().all(|&v| v == -2.0));
    }

    #[test]
    fn everything_leaving_the_grid_gives_zero_and_non_finite_is_skipped() {
        assert!(
            forward_warp(&uniform(2, 2, 50.0, 0.0), 2, 2, 1.0)
                .iter()
                .all(|&v| v == 0.0)
        );
        let mut f = uniform(2, 3, 0.0, 0.0);
        f[0] = f32::NAN;
        assert!(forward_warp(&f, 2, 3, 1.0).iter().all(|v| v.is_finite()));
    }
}
