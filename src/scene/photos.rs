//! Photographic textures for scene layers: real image statistics (FlyingChairs' Flickr
//! backgrounds, AutoFlow's texture study) mixed with the procedural ones. A folder of photos is
//! read once per process; each layer cuts a random, zoomed, possibly mirrored window from one.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, OnceLock};

use rand::RngExt;
use serde::{Deserialize, Serialize};

use super::texture::add_bilinear;
use crate::error::{Error, Result};
use crate::rng;
use crate::types::Image;

/// Where photographic textures come from and how often they are used.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PhotoTextures {
    /// Folders of photographs (PNG, JPEG, PPM/PGM, TIFF), read in file-name order; a relative
    /// path is relative to the config file.
    pub dirs: Vec<PathBuf>,
    /// Share of layer textures cut from a photo; the others are procedural.
    pub fraction: f64,
    /// Range of the zoom, texture pixels per photo pixel (drawn log-uniformly).
    pub zoom: [f64; 2],
}

impl Default for PhotoTextures {
    fn default() -> Self {
        Self {
            dirs: Vec::new(),
            fraction: 0.5,
            zoom: [0.5, 2.0],
        }
    }
}

/// The window a texture was cut from, for the sample's metadata.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhotoCrop {
    /// The photo's file name.
    pub photo: String,
    /// Top-left corner of the window in photo pixels.
    pub x: f64,
    pub y: f64,
    pub zoom: f64,
    /// Mirrored left to right.
    pub flip: bool,
}

/// One photograph, always three channels in [0, 1].
#[derive(Debug)]
pub struct Photo {
    pub name: String,
    pub image: Image,
}

/// Libraries read so far, by their folders.
type Cache = HashMap<Vec<PathBuf>, Arc<Vec<Photo>>>;

const EXTENSIONS: [&str; 8] = ["png", "jpg", "jpeg", "ppm", "pgm", "pnm", "tif", "tiff"];

impl PhotoTextures {
    /// Checks the fields (the folders are read by [`PhotoTextures::library`]).
    pub fn validate(&self) -> Result<()> {
        if self.dirs.is_empty() {
            return Err(Error::invalid(
                "scene.photos.dirs",
                "must name at least one folder of photographs",
            ));
        }
        if !(0.0..=1.0).contains(&self.fraction) {
            return Err(Error::invalid(
                "scene.photos.fraction",
                format!("must be in [0, 1], got {}", self.fraction),
            ));
        }
        let [a, b] = self.zoom;
        if !(a.is_finite() && b.is_finite() && 0.05 <= a && a <= b && b <= 20.0) {
            return Err(Error::invalid(
                "scene.photos.zoom",
                format!("expected 0.05 <= min <= max <= 20, got {:?}", self.zoom),
            ));
        }
        Ok(())
    }

    /// Makes relative folders relative to `base` (the config file's folder).
    pub fn resolve_paths(&mut self, base: &Path) {
        for d in &mut self.dirs {
            if d.is_relative() {
                *d = base.join(&*d);
            }
        }
    }

    /// The photographs of every folder, read once per process and shared.
    pub fn library(&self) -> Result<Arc<Vec<Photo>>> {
        static CACHE: OnceLock<Mutex<Cache>> = OnceLock::new();
        let cache = CACHE.get_or_init(|| Mutex::new(HashMap::new()));
        if let Some(lib) = cache
            .lock()
            .map_err(|_| Error::invalid("photo library", "a reader thread panicked"))?
            .get(&self.dirs)
        {
            return Ok(lib.clone());
        }
        let lib = Arc::new(read_photos(&self.dirs)?);
        cache
            .lock()
            .map_err(|_| Error::invalid("photo library", "a reader thread panicked"))?
            .insert(self.dirs.clone(), lib.clone());
        Ok(lib)
    }

    /// Cuts a `channels × height × width` texture from a photo drawn with `r`.
    pub fn cut(
        &self,
        library: &[Photo],
        r: &mut rng::Rng,
        channels: usize,
        height: usize,
        width: usize,
    ) -> (Image, PhotoCrop) {
        let photo = &library[r.random_range(0..library.len())];
        let (ph, pw) = (photo.image.height() as f64, photo.image.width() as f64);
        let [lo, hi] = self.zoom;
        let mut zoom = if lo == hi {
            lo
        } else {
            (r.random_range(lo.ln()..=hi.ln())).exp()
        };
        // A window larger than the photo is not possible: zoom in until it fits.
        zoom = zoom.max(width as f64 / pw).max(height as f64 / ph);
        let (ww, wh) = (width as f64 / zoom, height as f64 / zoom);
        let x = r.random_range(0.0..=(pw - ww).max(0.0));
        let y = r.random_range(0.0..=(ph - wh).max(0.0));
        let flip = r.random::<bool>();
        let crop = PhotoCrop {
            photo: photo.name.clone(),
            x,
            y,
            zoom,
            flip,
        };
        (resample(&photo.image, &crop, channels, height, width), crop)
    }
}

/// Samples the window `crop` of `photo` onto a `height × width` grid; when shrinking, each
/// output pixel averages a square of bilinear samples one photo pixel apart (no aliasing).
fn resample(
    photo: &Image,
    crop: &PhotoCrop,
    channels: usize,
    height: usize,
    width: usize,
) -> Image {
    let n = height * width;
    let taps = (1.0 / crop.zoom).ceil().clamp(1.0, 8.0) as usize;
    let mut data = vec![0.0f32; channels * n];
    let mut rgb = [0.0f32; 3];
    for yo in 0..height {
        for xo in 0..width {
            rgb.fill(0.0);
            for j in 0..taps {
                for i in 0..taps {
                    let u = (xo as f64 + (i as f64 + 0.5) / taps as f64) / crop.zoom;
                    let v = (yo as f64 + (j as f64 + 0.5) / taps as f64) / crop.zoom;
                    let u = if crop.flip {
                        width as f64 / crop.zoom - u
                    } else {
                        u
                    };
                    let (px, py) = ((crop.x + u - 0.5) as f32, (crop.y + v - 0.5) as f32);
                    add_bilinear(photo, px, py, &mut rgb);
                }
            }
            let k = (taps * taps) as f32;
            let i = yo * width + xo;
            if channels == 1 {
                data[i] = (0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]) / k;
            } else {
                for c in 0..3 {
                    data[c * n + i] = rgb[c] / k;
                }
            }
        }
    }
    // Lengths match by construction.
    Image::from_vec(channels, height, width, data)
        .unwrap_or_else(|_| Image::zeros(channels, height, width))
}

/// Reads every photograph of `dirs` (sorted by name within each folder) as three channels.
fn read_photos(dirs: &[PathBuf]) -> Result<Vec<Photo>> {
    let mut photos = Vec::new();
    for dir in dirs {
        let entries = std::fs::read_dir(dir).map_err(|e| {
            Error::invalid(
                "scene.photos.dirs",
                format!("cannot read folder {}: {e}", dir.display()),
            )
        })?;
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.is_file()
                    && p.extension()
                        .and_then(|e| e.to_str())
                        .is_some_and(|e| EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
            })
            .collect();
        paths.sort();
        for p in paths {
            let img = crate::io::read_image(&p)?;
            let image = match img.channels() {
                3 => img,
                1 | 2 => {
                    let (_, h, w) = img.shape();
                    let grey = img.plane(0).to_vec();
                    let data = [grey.clone(), grey.clone(), grey].concat();
                    Image::from_vec(3, h, w, data)?
                }
                _ => {
                    // RGBA and the like: the colour channels.
                    let (_, h, w) = img.shape();
                    Image::from_vec(3, h, w, img.data()[..3 * h * w].to_vec())?
                }
            };
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            photos.push(Photo { name, image });
        }
    }
    if photos.is_empty() {
        return Err(Error::invalid(
            "scene.photos.dirs",
            format!(
                "no photographs ({}) in {}",
                EXTENSIONS.join(", "),
                dirs.iter()
                    .map(|d| d.display().to_string())
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        ));
    }
    Ok(photos)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Photo {
        // 3 × 20 × 30, channel 0 = x, channel 1 = y, channel 2 = 0.5.
        let (h, w) = (20, 30);
        let mut data = Vec::new();
        data.extend((0..h * w).map(|i| (i % w) as f32 / w as f32));
        data.extend((0..h * w).map(|i| (i / w) as f32 / h as f32));
        data.extend(std::iter::repeat_n(0.5, h * w));
        Photo {
            name: "ramp".into(),
            image: Image::from_vec(3, h, w, data).unwrap(),
        }
    }

    #[test]
    fn a_unit_zoom_window_copies_the_photo() {
        let p = ramp();
        let crop = PhotoCrop {
            photo: "ramp".into(),
            x: 4.0,
            y: 3.0,
            zoom: 1.0,
            flip: false,
        };
        let t = resample(&p.image, &crop, 3, 10, 12);
        for (y, x) in [(0, 0), (5, 7), (9, 11)] {
            for c in 0..3 {
                assert!((t.get(c, y, x) - p.image.get(c, y + 3, x + 4)).abs() < 1e-6);
            }
        }
        let flipped = resample(&p.image, &PhotoCrop { flip: true, ..crop }, 3, 10, 12);
        assert!((flipped.get(0, 2, 0) - t.get(0, 2, 11)).abs() < 1e-6);
    }

    #[test]
    fn cuts_fit_inside_the_photo_and_are_deterministic() {
        let cfg = PhotoTextures {
            dirs: vec!["x".into()],
            zoom: [0.25, 4.0],
            ..PhotoTextures::default()
        };
        let lib = vec![ramp()];
        for s in 0..50 {
            let (a, ca) = cfg.cut(&lib, &mut rng::stream(s, &[1]), 3, 16, 24);
            let (b, cb) = cfg.cut(&lib, &mut rng::stream(s, &[1]), 3, 16, 24);
            assert_eq!((a, &ca), (b, &cb));
            assert!(
                ca.x >= 0.0 && ca.x + 24.0 / ca.zoom <= 30.0 + 1e-9,
                "{ca:?}"
            );
            assert!(
                ca.y >= 0.0 && ca.y + 16.0 / ca.zoom <= 20.0 + 1e-9,
                "{ca:?}"
            );
        }
        let (g, _) = cfg.cut(&lib, &mut rng::stream(1, &[1]), 1, 8, 8);
        assert_eq!(g.channels(), 1);
    }

    #[test]
    fn bad_settings_and_empty_folders_are_errors() {
        let ok = PhotoTextures {
            dirs: vec!["x".into()],
            ..PhotoTextures::default()
        };
        assert!(ok.validate().is_ok());
        for bad in [
            PhotoTextures {
                dirs: vec![],
                ..ok.clone()
            },
            PhotoTextures {
                fraction: 1.5,
                ..ok.clone()
            },
            PhotoTextures {
                zoom: [2.0, 1.0],
                ..ok.clone()
            },
        ] {
            assert!(bad.validate().is_err());
        }
        let empty = std::env::temp_dir().join(format!("pins-photos-empty-{}", std::process::id()));
        std::fs::create_dir_all(&empty).unwrap();
        let err = read_photos(std::slice::from_ref(&empty))
            .unwrap_err()
            .to_string();
        assert!(err.contains("no photographs"), "{err}");
        std::fs::remove_dir_all(&empty).ok();
    }

    #[test]
    fn the_shipped_photos_load() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("datasets/photos/train");
        let lib = read_photos(&[dir]).unwrap();
        assert_eq!(lib.len(), 9);
        assert!(lib.iter().all(|p| p.image.channels() == 3));
    }
}
