//! `Flow`: a dense displacement field `[2, H, W]` in pixels, u = +x (right), v = +y (down).

use crate::error::{Error, Result};

/// Dense optical flow `[2, H, W]`: plane 0 is u (horizontal), plane 1 is v (vertical).
/// Unknown vectors are NaN only as produced by readers; metrics take an explicit mask.
#[derive(Clone, Debug, PartialEq)]
pub struct Flow {
    height: usize,
    width: usize,
    data: Vec<f32>,
}

impl Flow {
    /// A zero flow of the given size.
    pub fn zeros(height: usize, width: usize) -> Self {
        Self {
            height,
            width,
            data: vec![0.0; 2 * height * width],
        }
    }

    /// Wraps planar data `[u plane, v plane]` of length `2 * height * width`.
    pub fn from_vec(height: usize, width: usize, data: Vec<f32>) -> Result<Self> {
        if data.len() != 2 * height * width {
            return Err(Error::shape(
                "flow data length",
                format!("{} (2x{height}x{width})", 2 * height * width),
                data.len(),
            ));
        }
        Ok(Self {
            height,
            width,
            data,
        })
    }

    pub fn height(&self) -> usize {
        self.height
    }
    pub fn width(&self) -> usize {
        self.width
    }
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    pub fn u(&self) -> &[f32] {
        &self.data[..self.height * self.width]
    }
    pub fn v(&self) -> &[f32] {
        &self.data[self.height * self.width..]
    }

    /// `(u, v)` at row `y`, column `x`.
    #[inline]
    pub fn get(&self, y: usize, x: usize) -> (f32, f32) {
        let i = y * self.width + x;
        (self.data[i], self.data[self.height * self.width + i])
    }

    /// Sets `(u, v)` at row `y`, column `x`.
    #[inline]
    pub fn set(&mut self, y: usize, x: usize, u: f32, v: f32) {
        let i = y * self.width + x;
        let n = self.height * self.width;
        self.data[i] = u;
        self.data[n + i] = v;
    }

    /// Mutable `(u plane, v plane)`.
    pub fn planes_mut(&mut self) -> (&mut [f32], &mut [f32]) {
        let n = self.height * self.width;
        self.data.split_at_mut(n)
    }

    /// True where both components are finite.
    pub fn valid_mask(&self) -> Vec<bool> {
        let (u, v) = (self.u(), self.v());
        u.iter()
            .zip(v)
            .map(|(a, b)| a.is_finite() && b.is_finite())
            .collect()
    }

    /// Largest magnitude over finite vectors (0 for an empty or all-unknown field).
    pub fn max_magnitude(&self) -> f32 {
        self.u()
            .iter()
            .zip(self.v())
            .filter(|(a, b)| a.is_finite() && b.is_finite())
            .map(|(a, b)| (a * a + b * b).sqrt())
            .fold(0.0, f32::max)
    }

    /// True when every vector is exactly zero.
    pub fn is_zero(&self) -> bool {
        self.data.iter().all(|&v| v == 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn planes_and_magnitude() {
        let mut f = Flow::zeros(2, 3);
        assert!(f.is_zero());
        f.set(1, 2, 3.0, 4.0);
        assert_eq!(f.get(1, 2), (3.0, 4.0));
        assert_eq!(f.max_magnitude(), 5.0);
        f.set(0, 0, f32::NAN, 0.0);
        assert_eq!(f.valid_mask().iter().filter(|&&m| !m).count(), 1);
        assert_eq!(f.max_magnitude(), 5.0);
        assert!(Flow::from_vec(2, 2, vec![0.0; 7]).is_err());
    }
}
