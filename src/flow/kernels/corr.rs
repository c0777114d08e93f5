//! The all-pairs correlation volume of Note S9 on host values: `C[p, q] = f1[:, p] · f2[:, q] / √C`
//! for every 1/8-resolution pixel p of frame 1 and q of frame 2, one matrix product per image
//! written straight into level 0, then the 2×2 average pooling of each level into the next.

use rayon::prelude::*;

/// The correlation pyramid on host memory: level 0 is one matrix product per image,
/// `corr[p, q] = f1[:, p] · f2[:, q] / √C`, written straight into the level; every further level
/// is the 2×2 average of the one before (1 cell wide sides are kept), as `avg_pool2d` gives.
///
/// # Shapes
/// `f1`, `f2`: `[B, C, H, W]` → levels `[B·H·W, h_l, w_l]` with their `(h_l, w_l)`
pub fn pyramid(
    f1: &[f32],
    f2: &[f32],
    [b, c, h, w]: [usize; 4],
    num_levels: usize,
) -> (Vec<Vec<f32>>, Vec<(usize, usize)>) {
    let hw = h * w;
    let mut level = vec![0f32; b * hw * hw];
    for bi in 0..b {
        let (a, bb) = (
            &f1[bi * c * hw..(bi + 1) * c * hw],
            &f2[bi * c * hw..(bi + 1) * c * hw],
        );
        let dst = &mut level[bi * hw * hw..(bi + 1) * hw * hw];
        if hw == 0 {
            continue;
        }
        // SAFETY: dst is [HW, HW] row-major; lhs reads f1 as its transpose [HW, C] (row stride
        // 1, column stride HW) and rhs f2 as [C, HW]; all three stay inside their slices.
        unsafe {
            gemm::gemm(
                hw,
                hw,
                c,
                dst.as_mut_ptr(),
                1,
                hw as isize,
                false,
                a.as_ptr(),
                hw as isize,
                1,
                bb.as_ptr(),
                1,
                hw as isize,
                0.0f32,
                1.0 / (c as f32).sqrt(),
                false,
                false,
                false,
                gemm::Parallelism::Rayon(0),
            );
        }
    }
    let n = b * hw;
    let mut levels = Vec::with_capacity(num_levels);
    let mut sizes = Vec::with_capacity(num_levels);
    let (mut hl, mut wl) = (h, w);
    for l in 0..num_levels {
        sizes.push((hl, wl));
        if l + 1 < num_levels {
            let (kh, kw) = (2.min(hl), 2.min(wl));
            let (h2, w2) = (hl / kh, wl / kw);
            let mut next = vec![0f32; n * h2 * w2];
            let inv = 1.0 / (kh * kw) as f32;
            if h2 * w2 > 0 {
                next.par_chunks_mut(h2 * w2)
                    .zip(level.par_chunks(hl * wl))
                    .for_each(|(dst, src)| {
                        for y in 0..h2 {
                            for x in 0..w2 {
                                let mut sum = 0.0;
                                for dy in 0..kh {
                                    let row = &src[(y * kh + dy) * wl + x * kw..];
                                    sum += row[..kw].iter().sum::<f32>();
                                }
                                dst[y * w2 + x] = sum * inv;
                            }
                        }
                    });
            }
            levels.push(std::mem::replace(&mut level, next));
            (hl, wl) = (h2, w2);
        } else {
            levels.push(std::mem::take(&mut level));
        }
    }
    (levels, sizes)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::kernels::testing::{Tol, assert_close, cases, values};
    use rand::RngExt;

    /// Property: on random sizes (seeded), level 0 is the scaled dot product of every pair and
    /// each further level the 2×2 mean of the one before (odd sides drop their last row or
    /// column, 1-wide sides are kept).
    #[test]
    fn levels_are_scaled_dot_products_and_their_means() {
        for case in 0..20 {
            let mut r = cases("corr pyramid", case);
            let (b, c, h, w) = (
                r.random_range(1..=2),
                r.random_range(1..=5),
                r.random_range(1..=7),
                r.random_range(1..=7),
            );
            let levels = r.random_range(1..=4);
            let f1 = values(&mut r, b * c * h * w, 1.0);
            let f2 = values(&mut r, b * c * h * w, 1.0);
            let (got, sizes) = pyramid(&f1, &f2, [b, c, h, w], levels);
            let hw = h * w;
            let mut want = vec![0f32; b * hw * hw];
            for bi in 0..b {
                for p in 0..hw {
                    for q in 0..hw {
                        let dot: f32 = (0..c)
                            .map(|k| f1[(bi * c + k) * hw + p] * f2[(bi * c + k) * hw + q])
                            .sum();
                        want[(bi * hw + p) * hw + q] = dot / (c as f32).sqrt();
                    }
                }
            }
            assert_eq!(sizes[0], (h, w));
            for l in 0..levels {
                let what = format!("case {case} level {l} of {b}x{c}x{h}x{w}");
                assert_close(&got[l], &want, Tol::Scaled(1e-5), &what);
                let (hl, wl) = sizes[l];
                let (kh, kw) = (2.min(hl), 2.min(wl));
                let (h2, w2) = (hl / kh, wl / kw);
                let mut next = vec![0f32; b * hw * h2 * w2];
                for n in 0..b * hw {
                    for y in 0..h2 {
                        for x in 0..w2 {
                            let mut s = 0.0;
                            for dy in 0..kh {
                                for dx in 0..kw {
                                    s += want[n * hl * wl + (y * kh + dy) * wl + x * kw + dx];
                                }
                            }
                            next[n * h2 * w2 + y * w2 + x] = s / (kh * kw) as f32;
                        }
                    }
                }
                if l + 1 < levels {
                    assert_eq!(sizes[l + 1], (h2, w2));
                }
                want = next;
            }
        }
    }
}
