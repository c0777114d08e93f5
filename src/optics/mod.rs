//! The metalens itself (Notes S2, S6, S12, S17): phase profiles, PSF by scalar diffraction,
//! depth of field, detection limits, stereo depth.

pub mod psf;

pub use psf::Psf;
