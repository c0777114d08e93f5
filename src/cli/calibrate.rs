//! Commands that fit the camera model to a real camera: calibrate noise, calibrate psf.

use std::path::PathBuf;

use anyhow::{Context, Result};
use clap::Subcommand;

use pins::imaging::CameraConfig;
use pins::imaging::calibrate::{captures, photon_transfer, point_source};
use pins::io;
use pins::report::noise_fit;

#[derive(Subcommand)]
pub(crate) enum CalibrateCommand {
    /// Eq. S3's noise (σ² = a·y + b, 8-bit DN) by photon transfer (EMVA 1288) from a folder of
    /// flat-field captures named LEVEL_N.png (two or more per exposure or brightness level;
    /// dark_N.png for dark frames). Writes camera.json (the camera config `pins simulate
    /// --config` and the generator's "camera" section take), report.md, report.json and fit.png.
    Noise {
        /// Folder of captures (8- or 16-bit PNG, TIFF or PPM; JPEGs are refused).
        captures: PathBuf,
        /// Eq. S4's exponent the captures were encoded with (1 for linear raw captures).
        #[arg(long, default_value_t = 1.7)]
        gamma: f64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// A PSF from captures of a point source (a pinhole or an LED far away) in a folder named
    /// EXPOSURE_N.png (one or more exposures, two or more captures of each: a longer one that
    /// saturates the core lifts the faint wings out of the noise; dark_N.png for dark
    /// frames). Writes the PSF file (.npy, .exr or 16-bit .png) that `pins simulate --psf` and
    /// the camera's "psf" key take.
    Psf {
        /// Folder of captures.
        captures: PathBuf,
        /// Eq. S4's exponent the captures were encoded with (1 for linear raw captures).
        #[arg(long, default_value_t = 1.7)]
        gamma: f64,
        /// Share of the energy above the noise floor the (odd, square) PSF keeps.
        #[arg(long, default_value_t = 0.99)]
        energy: f64,
        /// The noise floor, in standard deviations of the background.
        #[arg(long, default_value_t = 3.0)]
        floor: f64,
        /// Output PSF file: .npy, .exr (floats) or .png (16 bits).
        #[arg(long)]
        out: PathBuf,
    },
}

pub(crate) fn calibrate(c: CalibrateCommand) -> Result<()> {
    match c {
        CalibrateCommand::Noise {
            captures: dir,
            gamma,
            out,
        } => {
            if !(gamma.is_finite() && gamma > 0.0) {
                anyhow::bail!("--gamma must be finite and > 0, got {gamma}");
            }
            let set = captures::group(&dir)?;
            let levels = captures::measure(&set, gamma)?;
            let fits = photon_transfer::fit(&levels)?;
            let pooled = fits
                .iter()
                .find(|f| f.channel.is_none())
                .context("no pooled fit")?;
            let mut camera = CameraConfig {
                gamma: gamma as f32,
                ..CameraConfig::default()
            };
            camera.noise.a = pooled.line.a.max(0.0) as f32;
            camera.noise.b = pooled.line.b.max(0.0) as f32;
            camera.validate()?;
            let md = format!(
                "# Photon transfer\n\n`pins {}`\n\n{}",
                std::env::args().skip(1).collect::<Vec<_>>().join(" "),
                noise_fit::markdown(&fits, &levels)
            );
            let chart = noise_fit::chart(&fits, &levels);
            // Everything is computed: only now is the output written.
            std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
            chart.write_png(&out.join("fit.png"), 900, 600)?;
            io::write_bytes_atomic(
                &out.join("camera.json"),
                serde_json::to_string_pretty(&camera)?.as_bytes(),
            )?;
            let json = serde_json::json!({"captures": dir, "gamma": gamma, "fits": fits, "levels": levels});
            io::write_bytes_atomic(
                &out.join("report.json"),
                serde_json::to_string_pretty(&json)?.as_bytes(),
            )?;
            io::write_bytes_atomic(&out.join("report.md"), md.as_bytes())?;
            let l = &pooled.line;
            println!(
                "a = {:.4} ({:.4} – {:.4}), b = {:.3} ({:.3} – {:.3}) over {} levels; {}",
                l.a,
                l.a_ci[0],
                l.a_ci[1],
                l.b,
                l.b_ci[0],
                l.b_ci[1],
                l.points,
                out.join("camera.json").display()
            );
            Ok(())
        }
        CalibrateCommand::Psf {
            captures: dir,
            gamma,
            energy,
            floor,
            out,
        } => {
            let set = captures::group(&dir)?;
            let read = |paths: &[PathBuf]| -> Result<Vec<pins::types::Image>> {
                paths.iter().map(|p| Ok(io::read_image(p)?)).collect()
            };
            let exposures = set
                .levels
                .values()
                .map(|paths| read(paths))
                .collect::<Result<Vec<_>>>()?;
            let dark = read(&set.dark)?;
            let opts = point_source::PointOptions {
                gamma,
                energy,
                floor_k: floor,
            };
            let est = point_source::estimate(&exposures, &dark, opts)?;
            let ext = out
                .extension()
                .map(|e| e.to_string_lossy().to_lowercase())
                .unwrap_or_default();
            let mut image = est.psf.image().clone();
            if !matches!(ext.as_str(), "npy" | "exr" | "pfm") {
                // Integer files hold the PSF at its own peak (readers normalise it again).
                let top = image.data().iter().fold(0.0f32, |m, &v| m.max(v));
                image.data_mut().iter_mut().for_each(|v| *v /= top);
            }
            io::write_image(&out, &image, io::BitDepth::Sixteen)?;
            if est.saturated > 0 {
                eprintln!(
                    "warning: {} samples are saturated in every exposure; their energy is \
                     underestimated (add a shorter exposure)",
                    est.saturated
                );
            }
            let (h, w) = est.psf.size();
            println!(
                "{}: {}×{}×{} PSF, centre ({:.2}, {:.2}) in the captures, 80 % of the energy \
                 within {:.2} px",
                out.display(),
                est.psf.channels(),
                h,
                w,
                est.centre.0,
                est.centre.1,
                est.ee80_radius
            );
            Ok(())
        }
    }
}
