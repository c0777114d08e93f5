//! Frame n's foreground against the still camera's background (Note S13's region of
//! interest, measured on the frame): the per-pixel temporal median of the stored frames,
//! leaving out in each the discs where its objects were (`PlaceConfig::mask`), each channel's
//! difference from it in units of the camera's noise at that level (`track::detect::noise_level`),
//! and the mean shift that finds an object's centre (Eq. S17's centroid) on the weight above
//! the frame's noise floor (Comaniciu & Meer 2002), finished at the peak of the weight
//! filtered with the object's disc.

use std::collections::VecDeque;

use super::noise_level::NoiseLevel;
use super::placement::{ColourFrame, PlaceConfig, Placement, disc};
use crate::track::robust;

/// Fewest frames a pixel's median leaves it uncovered in before the covered ones are left
/// out (`PlaceConfig::mask`): the median of fewer is noise.
pub const MIN_UNCOVERED: usize = 3;

/// The discs (centre, radius) a stored frame's objects covered.
pub(super) type Covered = Vec<((f64, f64), f64)>;

/// Frame n against the median of the stored frames: `D` = √(box mean of Σ_c (I_c − B_c)² /
/// s_c²), computed where asked and cached; the weight is max(D − level, 0). `s_c` is the
/// camera's noise at the background's level `B_c` (`NoiseLevel`, measured on the frame's grid
/// of still-background pixels, floored by `PlaceConfig::noise_floor`), or 1 (8-bit levels)
/// when `PlaceConfig::pixel_noise` is off. In levels, a mover over a dark, quiet part of the
/// background (the sensor's noise grows with the signal, Eq. S3) falls below a level set by
/// the bright parts, and the centre leans to the disc's brighter side; in the noise of each
/// pixel's level every pixel counts by how surely it differs.
pub(super) struct Foreground<'a> {
    frames: &'a VecDeque<ColourFrame>,
    /// Where each stored frame's objects were (left out of the median).
    covered: &'a VecDeque<Covered>,
    current: &'a ColourFrame,
    /// Σ_c (I_c − B_c)² / s_c² per pixel, NaN until computed, `[H, W]`.
    sq: std::cell::RefCell<Vec<f32>>,
    radius: usize,
    level: f64,
    /// The camera's noise by level, `None`: D in levels.
    noise: Option<NoiseLevel>,
}

impl<'a> Foreground<'a> {
    pub(super) fn new(
        frames: &'a VecDeque<ColourFrame>,
        covered: &'a VecDeque<Covered>,
        current: &'a ColourFrame,
        window: usize,
        k: f64,
        noise_floor: Option<f64>,
    ) -> Self {
        let (w, h) = (current.width, current.height);
        let mut fg = Self {
            frames,
            covered,
            current,
            sq: std::cell::RefCell::new(vec![f32::NAN; w * h]),
            radius: window / 2,
            level: 0.0,
            noise: None,
        };
        // The frame's noise (by level, then as a floor of D) from a grid of about 32 × 32
        // samples.
        let (sx, sy) = ((w / 32).max(1), (h / 32).max(1));
        let grid: Vec<(usize, usize)> = (0..h)
            .step_by(sy)
            .flat_map(|y| (0..w).step_by(sx).map(move |x| (x, y)))
            .collect();
        if let Some(floor) = noise_floor {
            let samples = grid.iter().flat_map(|&(x, y)| {
                let at = fg.background_at(y * w + x, true);
                (0..current.channels).map(move |c| (c, at[c].0, at[c].1))
            });
            fg.noise = Some(NoiseLevel::fit(samples.collect::<Vec<_>>(), floor as f32));
        }
        let mut d: Vec<f64> = grid.iter().map(|&(x, y)| fg.d(x, y)).collect();
        if let Some((med, mad)) = robust::upper_median_mad(&mut d) {
            fg.level = robust::floor(med, mad, k);
        }
        fg
    }

    /// Per channel (the first `channels`), the median of the stored frames' samples at pixel
    /// `p` and, with `spread`, the median absolute deviation about it (0 without), over the
    /// frames whose objects did not cover it (over all of them where fewer than
    /// `MIN_UNCOVERED` did not).
    fn background_at(&self, p: usize, spread: bool) -> [(f32, f32); 3] {
        let w = self.current.width;
        let (x, y) = ((p % w) as f64, (p / w) as f64);
        let free = |i: usize| {
            self.covered.get(i).is_none_or(|discs| {
                discs
                    .iter()
                    .all(|&((cx, cy), r)| (x - cx).hypot(y - cy) > r)
            })
        };
        let n_all = self.frames.len().min(255);
        let mut use_frame = [true; 255];
        for (i, u) in use_frame.iter_mut().enumerate().take(n_all) {
            *u = free(i);
        }
        if use_frame[..n_all].iter().filter(|&&u| u).count() < MIN_UNCOVERED {
            use_frame = [true; 255];
        }
        let mut out = [(0.0f32, 0.0f32); 3];
        let mut buf = [0u8; 255];
        for (c, o) in out.iter_mut().enumerate().take(self.current.channels) {
            let mut n = 0;
            for (i, f) in self.frames.iter().enumerate().take(n_all) {
                if use_frame[i] {
                    buf[n] = f.plane(c)[p];
                    n += 1;
                }
            }
            let vals = &mut buf[..n];
            vals.sort_unstable();
            let Some(b) = robust::sorted_median(vals, f32::from) else {
                continue;
            };
            *o = (
                b,
                if spread {
                    median_deviation(vals, b)
                } else {
                    0.0
                },
            );
        }
        out
    }

    /// Σ_c (I_c − B_c)² / s_c² at one pixel (`background_at`'s medians).
    fn sq_at(&self, p: usize) -> f32 {
        let cached = self.sq.borrow()[p];
        if !cached.is_nan() {
            return cached;
        }
        let at = self.background_at(p, false);
        let mut s = 0.0f32;
        for (c, &(b, _)) in at.iter().enumerate().take(self.current.channels) {
            let e = self.current.plane(c)[p] as f32 - b;
            let var = self.noise.as_ref().map_or(1.0, |nl| nl.sigma(c, b).powi(2));
            s += e * e / var;
        }
        self.sq.borrow_mut()[p] = s;
        s
    }

    /// The mean shift's weight at (x, y): max(D − level, 0).
    pub(super) fn weight(&self, x: usize, y: usize) -> f64 {
        (self.d(x, y) - self.level).max(0.0)
    }

    /// The box-averaged difference at (x, y) (the box clipped to the frame).
    fn d(&self, x: usize, y: usize) -> f64 {
        let (w, h, r) = (self.current.width, self.current.height, self.radius);
        let (mut s, mut n) = (0.0f64, 0usize);
        for yy in y.saturating_sub(r)..=(y + r).min(h - 1) {
            for xx in x.saturating_sub(r)..=(x + r).min(w - 1) {
                s += self.sq_at(yy * w + xx) as f64;
                n += 1;
            }
        }
        (s / n.max(1) as f64).sqrt()
    }

    /// The foreground's centre near each seed (its prediction, its radius), when every seed
    /// is placed and the centres lie at least `split` × the sum of their radii apart.
    pub(super) fn split(
        &self,
        seeds: &[((f64, f64), f64)],
        cfg: &PlaceConfig,
    ) -> Option<Vec<(f64, f64)>> {
        let mut to = Vec::with_capacity(seeds.len());
        for &(at, radius) in seeds {
            let area = (std::f64::consts::PI * radius * radius).round() as usize;
            // The mean shift's centre: the disc that holds the most foreground there may
            // reach across to the other object (each seed is placed alone).
            match self.mean_shift_jointly(&[(at, area.max(1))], cfg).pop() {
                Some(Placement::Moved { to: p }) => to.push(p),
                _ => return None,
            }
        }
        for (i, (p, (_, ri))) in to.iter().zip(seeds).enumerate() {
            for (q, (_, rj)) in to.iter().zip(seeds).skip(i + 1) {
                if (p.0 - q.0).hypot(p.1 - q.1) < cfg.split * (ri + rj) {
                    return None;
                }
            }
        }
        Some(to)
    }

    /// Each region (one, or a crowd: two movers side by side, whose flows' halos join) placed
    /// by the mean shift of the weight from its flow centroid in a disc of its equivalent
    /// radius: in each step every region's disc weighs only the pixels nearer its own centre
    /// than any other's of at least a quarter of its area, in units of each one's radius, so
    /// each converges on its own object rather than on whichever is brighter. Each gets a
    /// verdict: the new centre (`Moved`), a centre too far from its start (`Far`), or why
    /// there is none (`Kept`); two whose centres end on one blob of foreground (no valley
    /// between them, `valley_between`: one object, or two that touch) are both kept at their
    /// flow centroids, since the frame cannot tell them apart there, except that a fragment of
    /// less than a quarter of the other's area leaves the other placed. A placed region's
    /// centre is then the disc's that holds the most weight near the mean shift's.
    pub(super) fn place_jointly(
        &self,
        starts: &[((f64, f64), usize)],
        cfg: &PlaceConfig,
    ) -> Vec<Placement> {
        let mut out = self.mean_shift_jointly(starts, cfg);
        let radii: Vec<f64> = starts.iter().map(|&(_, area)| disc_radius(area)).collect();
        // The mean shift's fixed point leans to the part of a textured object that differs
        // most from the background (a disc half like the background behind it ends centred
        // on the other half); the disc of the same radius that holds the most weight (the
        // peak of the foreground filtered with the disc, a matched filter's) does not: moved
        // off the object, it loses object pixels for background. A placed region's centre is
        // that disc's, sought within `max_shift` of its radius of the mean shift's centre on
        // the pixels nearer it than the other regions' centres (as above); the verdicts stay
        // the mean shift's.
        let centres: Vec<Option<(f64, f64)>> = out
            .iter()
            .map(|p| match p {
                Placement::Moved { to } | Placement::Far { to, .. } => Some(*to),
                _ => None,
            })
            .collect();
        for (i, o) in out.iter_mut().enumerate() {
            let Placement::Moved { to } = o else {
                continue;
            };
            let p = *to;
            let mine = |x: f64, y: f64| owns(i, (x, y), &centres, &radii, starts);
            let reach = (cfg.max_shift * radii[i]).ceil().max(1.0) as i64;
            *to = self.densest_disc(p, radii[i], reach, mine);
        }
        out
    }

    /// `place_jointly`'s mean shift and verdicts, the centres where the mean shift ends.
    fn mean_shift_jointly(
        &self,
        starts: &[((f64, f64), usize)],
        cfg: &PlaceConfig,
    ) -> Vec<Placement> {
        let (w, h) = (self.current.width, self.current.height);
        let radii: Vec<f64> = starts.iter().map(|&(_, area)| disc_radius(area)).collect();
        let mut at: Vec<(f64, f64)> = starts.iter().map(|&(c, _)| c).collect();
        // Per region: Σ weight and the pixels with weight in its final disc.
        let mut last = vec![(0.0f64, 0usize); starts.len()];
        let mut done = vec![false; starts.len()];
        for _ in 0..cfg.iterations {
            let mut next = at.clone();
            let centres: Vec<Option<(f64, f64)>> = at.iter().copied().map(Some).collect();
            for (i, &p) in at.iter().enumerate() {
                if done[i] {
                    continue;
                }
                let mine = |x: f64, y: f64| owns(i, (x, y), &centres, &radii, starts);
                let (mut sw, mut sx, mut sy, mut cover) = (0.0, 0.0, 0.0, 0usize);
                for (x, y) in disc(p, radii[i], w, h) {
                    let wt = self.weight(x, y);
                    if wt > 0.0 && mine(x as f64, y as f64) {
                        sw += wt;
                        sx += wt * x as f64;
                        sy += wt * y as f64;
                        cover += 1;
                    }
                }
                last[i] = (sw, cover);
                if sw <= 0.0 {
                    done[i] = true;
                    continue;
                }
                next[i] = (sx / sw, sy / sw);
                done[i] = (next[i].0 - p.0).hypot(next[i].1 - p.1) < 0.05;
            }
            at = next;
            if done.iter().all(|&d| d) {
                break;
            }
        }
        let mut out: Vec<Placement> = starts
            .iter()
            .zip(&at)
            .zip(radii.iter().zip(&last))
            .map(|((&(start, area), &p), (&radius, &(sw, cover)))| {
                if sw <= 0.0 {
                    return Placement::Kept("no foreground near the region".into());
                }
                if (cover as f64) < cfg.min_cover * area as f64 {
                    return Placement::Kept(format!(
                        "{cover} foreground pixels for a region of {area} (the object joined the \
                         background?)"
                    ));
                }
                let shift = (p.0 - start.0).hypot(p.1 - start.1);
                let limit = cfg.max_shift * radius;
                if shift > limit {
                    return Placement::Far {
                        to: p,
                        shift,
                        limit,
                    };
                }
                Placement::Moved { to: p }
            })
            .collect();
        let centre = |p: &Placement| match p {
            Placement::Moved { to } | Placement::Far { to, .. } => Some(*to),
            _ => None,
        };
        let mut one = vec![false; starts.len()];
        for i in 0..starts.len() {
            for j in i + 1..starts.len() {
                if let (Some(p), Some(q)) = (centre(&out[i]), centre(&out[j]))
                    && !self.valley_between(p, q)
                {
                    // A fragment (less than a quarter of the other's area) on the other's
                    // object leaves that one placed.
                    let (a, b) = (starts[i].1, starts[j].1);
                    one[i] |= 4 * b >= a;
                    one[j] |= 4 * a >= b;
                }
            }
        }
        for (i, o) in out.iter_mut().enumerate() {
            if one[i] {
                let (s, c) = (starts[i].0, at[i]);
                *o = Placement::Kept(format!(
                    "another region shares its foreground (no valley between them: the \
                     mean shift from ({:.1}, {:.1}) ended at ({:.1}, {:.1}))",
                    s.0, s.1, c.0, c.1
                ));
            }
        }
        out
    }

    /// The centre, within `reach` px of `from` in x and y, of the disc of `radius` that holds
    /// the most weight over the pixels `mine` admits: the best of the whole-pixel centres,
    /// moved by a parabola through its neighbours on each axis (at most half a pixel);
    /// `from` where no disc there holds any.
    fn densest_disc(
        &self,
        from: (f64, f64),
        radius: f64,
        reach: i64,
        mine: impl Fn(f64, f64) -> bool,
    ) -> (f64, f64) {
        let (w, h) = (self.current.width as i64, self.current.height as i64);
        let (bx, by) = (from.0.round() as i64, from.1.round() as i64);
        let r = radius.floor() as i64;
        // The weights of the pixels any disc can reach, 0 outside the frame or not `mine`.
        let m = reach + r + 1;
        let side = (2 * m + 1) as usize;
        let mut patch = vec![0.0f64; side * side];
        for (k, v) in patch.iter_mut().enumerate() {
            let (x, y) = (bx - m + (k % side) as i64, by - m + (k / side) as i64);
            if x >= 0 && y >= 0 && x < w && y < h && mine(x as f64, y as f64) {
                *v = self.weight(x as usize, y as usize);
            }
        }
        let offsets: Vec<(i64, i64)> = (-r..=r)
            .flat_map(|dy| (-r..=r).map(move |dx| (dx, dy)))
            .filter(|&(dx, dy)| ((dx * dx + dy * dy) as f64) <= radius * radius)
            .collect();
        let sum = |ox: i64, oy: i64| -> f64 {
            offsets
                .iter()
                .map(|&(dx, dy)| patch[((m + oy + dy) as usize) * side + (m + ox + dx) as usize])
                .sum()
        };
        let n = (2 * reach + 1) as usize;
        let sums: Vec<f64> = (0..n * n)
            .map(|k| sum((k % n) as i64 - reach, (k / n) as i64 - reach))
            .collect();
        let Some((best, &top)) = sums
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .filter(|(_, v)| **v > 0.0)
        else {
            return from;
        };
        let (ix, iy) = (best % n, best / n);
        let at = |x: usize, y: usize| sums[y * n + x];
        let vertex = |lo: f64, hi: f64| {
            let den = lo - 2.0 * top + hi;
            if den < 0.0 {
                (0.5 * (lo - hi) / den).clamp(-0.5, 0.5)
            } else {
                0.0
            }
        };
        let sx = if ix > 0 && ix + 1 < n {
            vertex(at(ix - 1, iy), at(ix + 1, iy))
        } else {
            0.0
        };
        let sy = if iy > 0 && iy + 1 < n {
            vertex(at(ix, iy - 1), at(ix, iy + 1))
        } else {
            0.0
        };
        (
            (bx + ix as i64 - reach) as f64 + sx,
            (by + iy as i64 - reach) as f64 + sy,
        )
    }

    /// Whether the foreground on the straight path from `p` to `q` falls below half the
    /// weight at the lower of the two (a valley between two modes, as two peaks are told apart
    /// at half maximum): two objects, where one blob of foreground is one object or two that
    /// touch. The camera's PSF spreads a bright object's light into the background beside it,
    /// so the path between two near objects need not reach zero.
    fn valley_between(&self, p: (f64, f64), q: (f64, f64)) -> bool {
        let (w, h) = (self.current.width, self.current.height);
        let at = |x: f64, y: f64| {
            let x = x.round().clamp(0.0, (w - 1) as f64) as usize;
            let y = y.round().clamp(0.0, (h - 1) as f64) as usize;
            self.weight(x, y)
        };
        let floor = 0.5 * at(p.0, p.1).min(at(q.0, q.1));
        let n = (p.0 - q.0).hypot(p.1 - q.1).ceil() as usize;
        (1..n).any(|k| {
            let t = k as f64 / n as f64;
            at(p.0 + t * (q.0 - p.0), p.1 + t * (q.1 - p.1)) < floor
        })
    }
}

/// Whether pixel `at` counts for region `i` of a crowd (`starts`, each placed at `centres`
/// with a disc of `radii`): it lies no nearer, in units of each one's radius, to any other
/// placed region of at least a quarter of `i`'s area (a smaller one, a fragment beside its
/// object or of its halo, takes nothing from it).
fn owns(
    i: usize,
    at: (f64, f64),
    centres: &[Option<(f64, f64)>],
    radii: &[f64],
    starts: &[((f64, f64), usize)],
) -> bool {
    let Some(p) = centres[i] else {
        return true;
    };
    let own = (at.0 - p.0).hypot(at.1 - p.1) / radii[i];
    centres
        .iter()
        .zip(radii)
        .zip(starts)
        .enumerate()
        .all(|(j, ((q, r), s))| match q {
            Some(q) if j != i && 4 * s.1 >= starts[i].1 => {
                (at.0 - q.0).hypot(at.1 - q.1) / r >= own
            }
            _ => true,
        })
}

/// The radius of the disc a region of `area` pixels is placed with: its equivalent radius,
/// at least 2 px.
fn disc_radius(area: usize) -> f64 {
    (area as f64 / std::f64::consts::PI).sqrt().max(2.0)
}

/// The median of |v − b| over the 8-bit `samples` (at most 255; 0 for none), the two middle
/// ones averaged for an even count as for the median itself.
fn median_deviation(samples: &[u8], b: f32) -> f32 {
    let n = samples.len().min(255);
    if n == 0 {
        return 0.0;
    }
    let mut dev = [0.0f32; 255];
    for (d, &v) in dev.iter_mut().zip(&samples[..n]) {
        *d = (v as f32 - b).abs();
    }
    robust::median(&mut dev[..n]).unwrap_or(0.0)
}

#[cfg(test)]
mod tests {
    use super::median_deviation;

    #[test]
    fn the_median_deviation_is_the_median_of_the_distances_from_the_median() {
        // Sorted 1 2 4 9 20 about 4: distances 3 2 0 5 16 → median 3.
        assert_eq!(median_deviation(&[1, 2, 4, 9, 20], 4.0), 3.0);
        // An even count about 3.5: distances 2.5 1.5 0.5 5.5 → the middle two averaged, 2.
        assert_eq!(median_deviation(&[1, 2, 4, 9], 3.5), 2.0);
        // A flat pixel spreads by nothing (the floor takes over), and no sample is no spread.
        assert_eq!(median_deviation(&[7; 30], 7.0), 0.0);
        assert_eq!(median_deviation(&[], 0.0), 0.0);
    }
}
