//! TEMPORARY stand-in for the Psf type (replaced by the optics branch).
use crate::error::{Error, Result};
use crate::types::Image;
#[derive(Clone, Debug, PartialEq)]
pub struct Psf { image: Image }
impl Psf {
    pub fn from_image(img: Image, what: &str) -> Result<Psf> {
        let (c, h, w) = img.shape();
        let mut img = img;
        for ch in 0..c {
            let s: f64 = img.plane(ch).iter().map(|&v| v as f64).sum();
            if !(s > 0.0) { return Err(Error::invalid(what, "zero sum")); }
            for v in img.plane_mut(ch) { *v = (*v as f64 / s) as f32; }
        }
        let _ = (h, w);
        Ok(Psf { image: img })
    }
    pub fn delta(channels: usize) -> Psf { let mut i = Image::zeros(channels, 1, 1); for c in 0..channels { i.set(c, 0, 0, 1.0);} Psf { image: i } }
    pub fn gaussian(channels: usize, sigma: f64, size: usize) -> Psf {
        let r = (size / 2) as f64;
        let mut i = Image::zeros(channels, size, size);
        for c in 0..channels { for y in 0..size { for x in 0..size {
            let d2 = (y as f64 - r).powi(2) + (x as f64 - r).powi(2);
            i.set(c, y, x, (-d2 / (2.0 * sigma * sigma)).exp() as f32);
        }}}
        Psf::from_image(i, "gaussian").unwrap()
    }
    pub fn is_delta(&self) -> bool { let (c, _, _) = self.image.shape(); (0..c).all(|ch| self.image.plane(ch).iter().filter(|&&v| v != 0.0).count() == 1 && self.image.plane(ch)[self.image.plane(ch).len()/2] == 1.0) }
    pub fn channels(&self) -> usize { self.image.channels() }
    pub fn size(&self) -> (usize, usize) { (self.image.height(), self.image.width()) }
    pub fn image(&self) -> &Image { &self.image }
    pub fn channel(&self, c: usize) -> &[f32] { self.image.plane(c) }
    pub fn to_mono(&self) -> Psf {
        let (c, h, w) = self.image.shape();
        let mut m = Image::zeros(1, h, w);
        for ch in 0..c { for (o, v) in m.plane_mut(0).iter_mut().zip(self.image.plane(ch)) { *o += v / c as f32; } }
        Psf::from_image(m, "mono").unwrap()
    }
}
