//! `Image`: planar f32 `[C, H, W]`, linear intensity nominally in [0, 1].

use crate::error::{Error, Result};

/// A planar image `[C, H, W]` of `f32`, channel-major, row-major within a channel.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    channels: usize,
    height: usize,
    width: usize,
    data: Vec<f32>,
}

impl Image {
    /// A zero-filled image `[channels, height, width]`.
    pub fn zeros(channels: usize, height: usize, width: usize) -> Self {
        Self::filled(channels, height, width, 0.0)
    }

    /// An image with every sample equal to `value`.
    pub fn filled(channels: usize, height: usize, width: usize, value: f32) -> Self {
        Self {
            channels,
            height,
            width,
            data: vec![value; channels * height * width],
        }
    }

    /// Wraps planar data; the length must be `channels * height * width`.
    pub fn from_vec(channels: usize, height: usize, width: usize, data: Vec<f32>) -> Result<Self> {
        let expected = channels * height * width;
        if data.len() != expected {
            return Err(Error::shape(
                "image data length",
                format!("{expected} ({channels}x{height}x{width})"),
                data.len(),
            ));
        }
        Ok(Self {
            channels,
            height,
            width,
            data,
        })
    }

    pub fn channels(&self) -> usize {
        self.channels
    }
    pub fn height(&self) -> usize {
        self.height
    }
    pub fn width(&self) -> usize {
        self.width
    }
    /// `(channels, height, width)`.
    pub fn shape(&self) -> (usize, usize, usize) {
        (self.channels, self.height, self.width)
    }
    pub fn data(&self) -> &[f32] {
        &self.data
    }
    pub fn data_mut(&mut self) -> &mut [f32] {
        &mut self.data
    }
    pub fn into_vec(self) -> Vec<f32> {
        self.data
    }

    /// One channel plane `[H, W]`.
    pub fn plane(&self, c: usize) -> &[f32] {
        let n = self.height * self.width;
        &self.data[c * n..(c + 1) * n]
    }

    /// One channel plane `[H, W]`, mutable.
    pub fn plane_mut(&mut self, c: usize) -> &mut [f32] {
        let n = self.height * self.width;
        &mut self.data[c * n..(c + 1) * n]
    }

    /// Sample at channel `c`, row `y`, column `x`.
    #[inline]
    pub fn get(&self, c: usize, y: usize, x: usize) -> f32 {
        self.data[(c * self.height + y) * self.width + x]
    }

    /// Sets the sample at channel `c`, row `y`, column `x`.
    #[inline]
    pub fn set(&mut self, c: usize, y: usize, x: usize, v: f32) {
        self.data[(c * self.height + y) * self.width + x] = v;
    }

    /// True when every channel holds the same values (a grey image stored as colour).
    pub fn is_grey(&self) -> bool {
        let n = self.height * self.width;
        (1..self.channels).all(|c| self.data[c * n..(c + 1) * n] == self.data[..n])
    }

    /// The first channel alone, `[1, H, W]`.
    pub fn first_channel(&self) -> Image {
        Image {
            channels: 1,
            height: self.height,
            width: self.width,
            data: self.plane(0).to_vec(),
        }
    }

    /// Fails when a side or the channel count is zero: such an image holds no pixel to process.
    pub fn check_nonempty(&self, what: &str) -> Result<()> {
        if self.channels == 0 || self.height == 0 || self.width == 0 {
            return Err(Error::invalid(
                what,
                format!(
                    "empty image ({} channels, {}x{} pixels): every side must be at least 1",
                    self.channels, self.width, self.height
                ),
            ));
        }
        Ok(())
    }

    /// Fails unless every sample is finite.
    pub fn check_finite(&self, what: &str) -> Result<()> {
        match self.data.iter().position(|v| !v.is_finite()) {
            None => Ok(()),
            Some(i) => {
                let n = self.height * self.width;
                let (c, y, x) = (i / n, (i % n) / self.width, i % self.width);
                Err(Error::invalid(
                    what,
                    format!(
                        "non-finite value {} at channel {c}, row {y}, column {x}",
                        self.data[i]
                    ),
                ))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn from_vec_checks_length() {
        assert!(Image::from_vec(3, 2, 2, vec![0.0; 11]).is_err());
        let im = Image::from_vec(3, 2, 2, (0..12).map(|v| v as f32).collect()).unwrap();
        assert_eq!(im.get(1, 1, 0), 6.0);
        assert_eq!(im.plane(2), &[8.0, 9.0, 10.0, 11.0]);
    }

    #[test]
    fn empty_images_are_named() {
        for (c, h, w) in [(3, 0, 16), (1, 16, 0), (0, 4, 4)] {
            let err = Image::zeros(c, h, w).check_nonempty("img").unwrap_err();
            assert!(err.to_string().contains("empty image"), "{err}");
        }
        assert!(Image::zeros(1, 1, 1).check_nonempty("img").is_ok());
    }

    #[test]
    fn grey_detection_and_finiteness() {
        let mut im = Image::filled(3, 4, 4, 0.5);
        assert!(im.is_grey());
        im.set(2, 3, 3, 0.25);
        assert!(!im.is_grey());
        im.set(0, 1, 2, f32::NAN);
        let err = im.check_finite("test image").unwrap_err().to_string();
        assert!(err.contains("row 1, column 2"), "{err}");
    }
}
