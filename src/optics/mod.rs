//! The metalens itself (Notes S2, S6, S12, S17): phase profiles, PSF by scalar diffraction,
//! depth of field, detection limits, stereo depth.

pub mod diffraction;
pub mod dof;
pub mod fov;
pub mod lens;
pub mod phase;
mod propagate;
pub mod psf;
pub mod resolution;
mod sampling;
pub mod spectrum;
pub mod stereo;

pub use diffraction::{PsfParams, PsfResult, compute_psf, spot_radius_um};
pub use lens::{Lens, Profile};
pub use psf::Psf;
pub use spectrum::{Band, default_bands};
