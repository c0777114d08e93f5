//! Benchmark timing: the median of repeated runs after a warm-up (never used in tests).

use std::time::Instant;

/// Median wall time of `f` over `reps` runs after one warm-up, in ms.
pub fn median_ms<T>(reps: usize, mut f: impl FnMut() -> T) -> f64 {
    std::hint::black_box(f());
    let mut t: Vec<f64> = (0..reps.max(1))
        .map(|_| {
            let s = Instant::now();
            std::hint::black_box(f());
            s.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    t.sort_by(|a, b| a.total_cmp(b));
    t[t.len() / 2]
}
