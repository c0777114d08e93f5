//! Commands of the wide-angle array: render, calibrate, bench, stitch.

use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Subcommand;

use pins::imaging::{Camera, CameraConfig, psf_source};
use pins::io::{self, BitDepth};

#[derive(Subcommand)]
pub(crate) enum ArrayCommand {
    /// Render the raw 1600×1200 sensor frame of an ideal 480×1440 (135°) scene, or of the dot grid.
    Render {
        /// The ideal wide scene (height 480, width 1440 for the default layout).
        #[arg(long = "in")]
        input: Option<PathBuf>,
        /// Render the dot-grid calibration target instead of a scene.
        #[arg(long)]
        grid: bool,
        /// Dots per tile side of the grid.
        #[arg(long, default_value_t = 11)]
        dots: usize,
        #[arg(long)]
        out: PathBuf,
        /// Array layout (JSON); the paper's default when absent.
        #[arg(long)]
        config: Option<PathBuf>,
        /// default: the camera model of the generator (PSF, noise, gamma); none: the ideal frame.
        #[arg(long, default_value = "default")]
        camera: String,
        #[arg(long, default_value_t = 0)]
        seed: u64,
    },
    /// Fit each lens's distortion polynomials from a raw dot-grid frame.
    Calibrate {
        #[arg(long)]
        grid: PathBuf,
        #[arg(long)]
        out: PathBuf,
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long, default_value_t = 11)]
        dots: usize,
        /// Polynomial order (2…6); chosen by held-out error when absent.
        #[arg(long)]
        order: Option<usize>,
    },
    /// Reprojection error and stitch time per frame for polynomial orders 2…6.
    Bench {
        #[arg(long)]
        grid: PathBuf,
        #[arg(long)]
        config: Option<PathBuf>,
        #[arg(long, default_value_t = 11)]
        dots: usize,
        #[arg(long, default_value_t = 5)]
        reps: usize,
    },
    /// Rectify and join a raw frame (or a folder of frames) into the 480×1440 image.
    Stitch {
        #[arg(long)]
        calib: PathBuf,
        /// A raw frame, or a folder of raw frames.
        #[arg(long = "in")]
        input: PathBuf,
        /// Output image, or folder when --in is a folder.
        #[arg(long)]
        out: PathBuf,
    },
}

pub(crate) fn array(c: ArrayCommand) -> Result<()> {
    use pins::wide::{ArrayLayout, Calibration, Stitcher, calibrate, render};
    let layout_of = |p: &Option<PathBuf>| -> Result<ArrayLayout> {
        let l = match p {
            Some(p) => serde_json::from_str::<ArrayLayout>(
                &std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?,
            )
            .with_context(|| format!("array layout {}", p.display()))?,
            None => ArrayLayout::default(),
        };
        render::check_layout(&l)?;
        Ok(l)
    };
    match c {
        ArrayCommand::Render {
            input,
            grid,
            dots,
            out,
            config,
            camera,
            seed,
        } => {
            let layout = layout_of(&config)?;
            let scene = match (input, grid) {
                (Some(p), false) => io::read_image(&p)?,
                (None, true) => render::dot_grid_target(&layout, dots)?.0,
                _ => bail!("give either --in WIDE.png or --grid"),
            };
            let mut raw = render::render_raw(&layout, &scene)?;
            match camera.as_str() {
                "none" => {}
                "default" => {
                    let cfg = CameraConfig::default();
                    let (psf, _) = psf_source::load(&cfg.psf)?;
                    raw = Camera::new(&cfg, psf)?.apply(&raw, seed)?;
                }
                other => bail!("--camera {other:?}: use default or none"),
            }
            io::write_image(&out, &raw, BitDepth::Eight)?;
            println!(
                "{}: {}x{} raw frame of {} lenses",
                out.display(),
                raw.width(),
                raw.height(),
                layout.lenses.len()
            );
        }
        ArrayCommand::Calibrate {
            grid,
            out,
            config,
            dots,
            order,
        } => {
            let layout = layout_of(&config)?;
            if let Some(o) = order
                && !(2..=6).contains(&o)
            {
                bail!("--order must be 2..=6, got {o}");
            }
            let raw = io::read_image(&grid)?;
            let calib = calibrate(&layout, &raw, dots, order)?;
            io::write_bytes_atomic(&out, serde_json::to_string_pretty(&calib)?.as_bytes())?;
            println!(
                "| lens | dots | order | RMS (px) | max (px) | held-out RMS by order |\n|---|---|---|---|---|---|"
            );
            for (i, l) in calib.lenses.iter().enumerate() {
                let ho: Vec<String> = l
                    .held_out
                    .iter()
                    .map(|(o, r)| format!("{o}: {r:.3}"))
                    .collect();
                println!(
                    "| {} | {} | {} | {:.3} | {:.3} | {} |",
                    i + 1,
                    l.dots,
                    l.fx.order,
                    l.rms_px,
                    l.max_px,
                    ho.join(", ")
                );
            }
        }
        ArrayCommand::Bench {
            grid,
            config,
            dots,
            reps,
        } => {
            let layout = layout_of(&config)?;
            let raw = io::read_image(&grid)?;
            let rows = pins::report::array_bench::orders_table(&layout, &raw, dots, reps.max(1))?;
            println!(
                "| order | RMS (px) | max (px) | held-out RMS (px) | stitch ms (1 core) | frames/s |\n|---|---|---|---|---|---|"
            );
            for r in rows {
                println!(
                    "| {} | {:.3} | {:.3} | {:.3} | {:.1} | {:.0} |",
                    r.order, r.rms_px, r.max_px, r.held_out_rms_px, r.stitch_ms, r.frames_per_s
                );
            }
        }
        ArrayCommand::Stitch { calib, input, out } => {
            let text = std::fs::read_to_string(&calib)
                .with_context(|| format!("reading {}", calib.display()))?;
            let calib: Calibration = serde_json::from_str(&text)
                .with_context(|| format!("calibration {}", calib.display()))?;
            let stitcher = Stitcher::new(&calib)?;
            let jobs: Vec<(PathBuf, PathBuf)> = if input.is_dir() {
                let v = pins::io::image_files(&input)?;
                if v.is_empty() {
                    bail!("{}: no image files to stitch", input.display());
                }
                v.into_iter()
                    .map(|p| {
                        (
                            p.clone(),
                            out.join(p.file_name().unwrap_or_default())
                                .with_extension("png"),
                        )
                    })
                    .collect()
            } else {
                vec![(input, out)]
            };
            for (src, dst) in jobs {
                let raw = io::read_image(&src)?;
                let started = std::time::Instant::now();
                let wide = stitcher.apply(&raw)?;
                let ms = started.elapsed().as_secs_f64() * 1e3;
                io::write_image(&dst, &wide, BitDepth::Eight)?;
                println!(
                    "{} → {} ({}x{}) in {ms:.1} ms",
                    src.display(),
                    dst.display(),
                    wide.width(),
                    wide.height()
                );
            }
        }
    }
    Ok(())
}
