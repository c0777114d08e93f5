//! Kalman filters for the MTP smoothing of Note S13, in f64 with the Joseph-form covariance
//! update (P = (I − KH) P (I − KH)ᵀ + K R Kᵀ), which keeps P symmetric positive-definite even
//! with stiff settings (process noise 1e-9 against measurement noise 1e3, or the reverse).

/// A constant-velocity filter for one coordinate: state (position, velocity), the time step
/// one frame (`predict`) or any number of frames (`predict_by`).
#[derive(Clone, Debug, PartialEq)]
pub struct ConstantVelocity {
    pub x: [f64; 2],
    pub p: [[f64; 2]; 2],
    /// Process noise (variance of the frame-to-frame velocity change) and measurement noise
    /// variance.
    pub q: f64,
    pub r: f64,
    initialised: bool,
}

impl ConstantVelocity {
    pub fn new(q: f64, r: f64) -> Self {
        Self {
            x: [0.0, 0.0],
            p: [[1e6, 0.0], [0.0, 1e6]],
            q: q.max(0.0),
            r: r.max(1e-12),
            initialised: false,
        }
    }

    /// Advances one frame.
    pub fn predict(&mut self) {
        self.predict_by(1.0);
    }

    /// Advances `dt` frames (a stream processed at uneven gaps): F = [[1, dt], [0, 1]], and the
    /// velocity's variance grows by q per frame.
    pub fn predict_by(&mut self, dt: f64) {
        let [p, v] = self.x;
        self.x = [p + v * dt, v];
        let pm = self.p;
        // F P Fᵀ, plus Q.
        let a = pm[0][0] + dt * pm[0][1] + dt * pm[1][0] + dt * dt * pm[1][1];
        let b = pm[0][1] + dt * pm[1][1];
        let c = pm[1][0] + dt * pm[1][1];
        let d = pm[1][1];
        // Q drives the velocity alone: the velocity is the displacement to the next frame (what
        // an optical flow measures), so x(n + dt) = x(n) + v(n)·dt holds exactly.
        self.p = [[a, b], [c, d + self.q * dt]];
        self.symmetrise();
    }

    /// Fuses a measurement of the position.
    pub fn update(&mut self, z: f64) {
        if !z.is_finite() {
            return;
        }
        if !self.initialised {
            self.x = [z, 0.0];
            self.p = [[self.r, 0.0], [0.0, 1e3 * self.r.max(1.0)]];
            self.initialised = true;
            return;
        }
        self.measure(0, z, self.r);
    }

    /// Fuses a measurement of the velocity (px/frame) with variance `r`, e.g. an object's mean
    /// optical flow; ignored before the first position or when not finite.
    pub fn update_velocity(&mut self, v: f64, r: f64) {
        if !v.is_finite() || !self.initialised {
            return;
        }
        self.measure(1, v, r.max(1e-12));
    }

    /// Scalar update of state component `i` (H = eᵢᵀ) in Joseph form.
    fn measure(&mut self, i: usize, z: f64, r: f64) {
        let s = self.p[i][i] + r;
        let k = [self.p[0][i] / s, self.p[1][i] / s];
        let y = z - self.x[i];
        self.x = [self.x[0] + k[0] * y, self.x[1] + k[1] * y];
        // A = I − K eᵢᵀ; P = A P Aᵀ + K r Kᵀ.
        let mut a = [[1.0, 0.0], [0.0, 1.0]];
        a[0][i] -= k[0];
        a[1][i] -= k[1];
        let p = self.p;
        let mut ap = [[0.0; 2]; 2];
        for (r_, row) in ap.iter_mut().enumerate() {
            for (c, v) in row.iter_mut().enumerate() {
                *v = a[r_][0] * p[0][c] + a[r_][1] * p[1][c];
            }
        }
        let mut np = [[0.0; 2]; 2];
        for (i_, row) in np.iter_mut().enumerate() {
            for (j, v) in row.iter_mut().enumerate() {
                *v = ap[i_][0] * a[j][0] + ap[i_][1] * a[j][1] + k[i_] * r * k[j];
            }
        }
        self.p = np;
        self.symmetrise();
    }

    fn symmetrise(&mut self) {
        let off = 0.5 * (self.p[0][1] + self.p[1][0]);
        self.p[0][1] = off;
        self.p[1][0] = off;
    }

    /// True when P is symmetric positive-definite.
    pub fn covariance_ok(&self) -> bool {
        let p = self.p;
        p[0][1] == p[1][0]
            && p[0][0] > 0.0
            && p[0][0] * p[1][1] - p[0][1] * p[1][0] > 0.0
            && p.iter().flatten().all(|v| v.is_finite())
    }
}

/// A random-walk filter of a scalar (speed, or the sine or cosine of the direction).
#[derive(Clone, Debug, PartialEq)]
pub struct RandomWalk {
    pub x: f64,
    pub p: f64,
    pub q: f64,
    pub r: f64,
    initialised: bool,
}

impl RandomWalk {
    pub fn new(q: f64, r: f64) -> Self {
        Self {
            x: 0.0,
            p: 1e6,
            q: q.max(0.0),
            r: r.max(1e-12),
            initialised: false,
        }
    }

    /// Predicts one frame ahead and fuses `z` (skipped when not finite); returns the estimate.
    pub fn step(&mut self, z: f64) -> f64 {
        self.step_by(z, 1.0)
    }

    /// Predicts `dt` frames ahead (the variance grows by q per frame) and fuses `z`.
    pub fn step_by(&mut self, z: f64, dt: f64) -> f64 {
        if !z.is_finite() {
            self.p += self.q * dt;
            return self.x;
        }
        if !self.initialised {
            (self.x, self.p, self.initialised) = (z, self.r, true);
            return self.x;
        }
        self.p += self.q * dt;
        let k = self.p / (self.p + self.r);
        self.x += k * (z - self.x);
        // Joseph form in one dimension.
        self.p = (1.0 - k) * (1.0 - k) * self.p + k * k * self.r;
        self.x
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tracks_constant_velocity_and_stays_positive_definite_when_stiff() {
        for (q, r) in [(1e-9, 1e3), (1e3, 1e-9), (0.01, 1.0)] {
            let mut f = ConstantVelocity::new(q, r);
            for n in 0..200 {
                f.predict();
                f.update(3.0 + 2.0 * n as f64 + if n % 2 == 0 { 0.5 } else { -0.5 });
                assert!(f.covariance_ok(), "q {q} r {r} step {n}: {:?}", f.p);
            }
            assert!(f.x.iter().all(|v| v.is_finite()));
            // Only a sensible ratio is expected to estimate well: with q ≫ r the model itself
            // says the measurements' jitter is real acceleration.
            if q < r {
                assert!(
                    (f.x[1] - 2.0).abs() < 0.2,
                    "q {q} r {r}: velocity {}",
                    f.x[1]
                );
            }
        }
        // A velocity measurement removes the lag of a position-only filter on accelerating motion.
        let (mut pos, mut both) = (
            ConstantVelocity::new(0.5, 1.0),
            ConstantVelocity::new(0.5, 1.0),
        );
        for n in 0..60 {
            let t = n as f64;
            for f in [&mut pos, &mut both] {
                f.predict();
                f.update(0.05 * t * t);
            }
            // The flow of frame n: the displacement to frame n + 1.
            both.update_velocity(0.1 * t + 0.05, 0.25);
            assert!(both.covariance_ok());
        }
        let truth = 0.05 * 59.0 * 59.0;
        assert!((both.x[0] - truth).abs() < 0.5 * (pos.x[0] - truth).abs());
        let mut s = RandomWalk::new(1e-9, 1e3);
        for _ in 0..100 {
            s.step(5.0);
        }
        assert!((s.x - 5.0).abs() < 1e-6 && s.p > 0.0);
        assert!(s.step(f64::NAN).is_finite());
    }

    #[test]
    fn a_step_of_k_frames_is_k_steps_of_one_without_noise_and_grows_the_variance_with_k() {
        // Without process noise, predicting 3 frames at once is predicting 1 frame 3 times.
        let (mut one, mut three) = (
            ConstantVelocity::new(0.0, 1.0),
            ConstantVelocity::new(0.0, 1.0),
        );
        for f in [&mut one, &mut three] {
            f.update(10.0);
            f.update_velocity(2.0, 0.5);
        }
        for _ in 0..3 {
            one.predict();
        }
        three.predict_by(3.0);
        for i in 0..2 {
            assert!((one.x[i] - three.x[i]).abs() < 1e-12);
            for j in 0..2 {
                assert!((one.p[i][j] - three.p[i][j]).abs() < 1e-9 * one.p[i][j].abs().max(1.0));
            }
        }
        assert!((three.x[0] - 16.0).abs() < 0.5, "{:?}", three.x);
        // With it, the velocity's variance grows by q per frame, and a longer step trusts the
        // next measurement more.
        let (mut a, mut b) = (
            ConstantVelocity::new(0.3, 1.0),
            ConstantVelocity::new(0.3, 1.0),
        );
        for f in [&mut a, &mut b] {
            f.update(0.0);
            f.update_velocity(1.0, 0.5);
        }
        let p11 = a.p[1][1];
        a.predict_by(1.0);
        b.predict_by(4.0);
        assert!((b.p[1][1] - p11 - 4.0 * 0.3).abs() < 1e-12 && b.p[0][0] > a.p[0][0]);
        assert!(a.covariance_ok() && b.covariance_ok());
        let mut w = RandomWalk::new(0.2, 1.0);
        w.step(1.0);
        let p = w.p;
        w.step_by(f64::NAN, 5.0);
        assert!((w.p - p - 1.0).abs() < 1e-12);
    }
}
