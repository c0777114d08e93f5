//! The one-cycle learning-rate schedule RAFT trains with (linear annealing): from lr/25 up to lr
//! over the first `pct_start` of the steps, then linearly down to lr/1e4 at the last step.
//! Burn 0.22 has no OneCycle scheduler, and a pure function of the step resumes exactly.

/// Learning rate at `step` (0-based) of `total`.
pub fn one_cycle(step: usize, total: usize, max_lr: f64, pct_start: f64) -> f64 {
    let warm = ((total as f64 * pct_start).round() as usize).max(1);
    let (start, end) = (max_lr / 25.0, max_lr / 1e4);
    if step < warm {
        start + (max_lr - start) * step as f64 / warm as f64
    } else {
        let span = (total.saturating_sub(warm)).max(1) as f64;
        let t = ((step - warm) as f64 / span).min(1.0);
        max_lr + (end - max_lr) * t
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rises_then_falls() {
        let lr = |s| one_cycle(s, 100, 4e-4, 0.05);
        assert!((lr(0) - 1.6e-5).abs() < 1e-12);
        assert!((lr(5) - 4e-4).abs() < 1e-12);
        assert!(lr(50) < lr(5) && lr(50) > lr(99));
        assert!((lr(100) - 4e-8).abs() < 1e-12);
    }
}
