//! Commands of the optics calculators and image similarity: optics, compare.

use std::path::PathBuf;

use anyhow::Result;
use clap::Subcommand;

use pins::io::{self};

use super::data::ProfileArg;

#[derive(clap::Args)]
pub(crate) struct CompareArgs {
    a: PathBuf,
    b: PathBuf,
    /// Print {"ssim", "mae", "mse"} as JSON.
    #[arg(long)]
    json: bool,
}

#[derive(Subcommand)]
pub(crate) enum OpticsCommand {
    /// Depth of field (Eqs. S5–S8, Table S1) for sensor distances v0 = f + offset.
    Dof {
        /// Offsets v0 − f in µm.
        #[arg(long, value_delimiter = ',', default_value = "0,10,15,20,25")]
        offsets_um: Vec<f64>,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        #[arg(long, default_value_t = 1.0)]
        diameter_mm: f64,
        #[arg(long, default_value_t = 2.2)]
        pixel_um: f64,
        /// Circle of confusion in pixels.
        #[arg(long, default_value_t = 2.0)]
        coc_pixels: f64,
        #[arg(long)]
        json: bool,
    },
    /// Angular pixel size and the smallest detectable displacement and object (Note S12).
    Resolution {
        #[arg(long, default_value_t = 10.0)]
        distance_m: f64,
        #[arg(long, default_value_t = 2.2)]
        pixel_um: f64,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        /// Smallest detectable displacement in pixels (Fig. S10a–c: 3).
        #[arg(long, default_value_t = 3.0)]
        min_shift_px: f64,
        /// Smallest detectable target diameter in pixels (Fig. S10e–g: 5).
        #[arg(long, default_value_t = 5.0)]
        min_target_px: f64,
        #[arg(long)]
        json: bool,
    },
    /// Depth from two image points and a baseline (Eqs. S24–S25).
    Stereo {
        /// Image position in lens 1, mm from its axis.
        #[arg(long, allow_hyphen_values = true)]
        x1_mm: f64,
        /// Image position in lens 2, mm from its axis.
        #[arg(long, allow_hyphen_values = true)]
        x2_mm: f64,
        /// Baseline between the lenses, m.
        #[arg(long)]
        baseline_m: f64,
        #[arg(long, default_value_t = 1.6)]
        focal_mm: f64,
        #[arg(long, value_enum, default_value = "hyperbolic")]
        profile: ProfileArg,
        #[arg(long)]
        json: bool,
    },
    /// Angular sectors, total FoV and overlaps of a tilted array (Note S16), and the focal spot
    /// against the Airy radius across the field of lenses designed for 45° and 80° (Note S2).
    Fov {
        #[arg(
            long,
            value_delimiter = ',',
            default_value = "-45,0,45",
            allow_hyphen_values = true
        )]
        tilts_deg: Vec<f64>,
        #[arg(long, default_value_t = 45.0)]
        fov_deg: f64,
        /// Also sweep the spot size over the field (slow: one diffraction PSF per angle).
        #[arg(long)]
        spots: bool,
        /// FFT grid for the spot sweep (large field angles need a fine grid).
        #[arg(long, default_value_t = 3072)]
        grid: usize,
        #[arg(long)]
        json: bool,
    },
}

pub(crate) fn compare(a: CompareArgs) -> Result<()> {
    let (x, y) = io::read_image_pair(&a.a, &a.b)?;
    let s = pins::imaging::similarity::compare(&x, &y)?;
    if a.json {
        println!("{}", serde_json::to_string(&s)?);
    } else {
        println!("SSIM {:.6}  MAE {:.6}  MSE {:.6}", s.ssim, s.mae, s.mse);
    }
    Ok(())
}

pub(crate) fn optics(c: OpticsCommand) -> Result<()> {
    use pins::optics::{Lens, Profile, dof::DofParams, fov, resolution::resolution, stereo};
    match c {
        OpticsCommand::Dof {
            offsets_um,
            focal_mm,
            diameter_mm,
            pixel_um,
            coc_pixels,
            json,
        } => {
            let p = DofParams {
                focal_mm,
                diameter_mm,
                pixel_um,
                coc_pixels,
            };
            let rows = offsets_um
                .iter()
                .map(|&o| p.range(o))
                .collect::<pins::Result<Vec<_>>>()?;
            if json {
                println!("{}", serde_json::json!({ "rows": rows }));
            } else {
                println!(
                    "Δv_max = c·F/# = {:.2} µm\n\n| v0 − f (µm) | u_near (m) | u_far (m) |\n|---|---|---|",
                    p.max_shift_m() * 1e6
                );
                for r in rows {
                    let far = r
                        .u_far_m
                        .map(|v| format!("{v:.2}"))
                        .unwrap_or_else(|| "∞".into());
                    println!("| {} | {:.2} | {} |", r.v0_minus_f_um, r.u_near_m, far);
                }
            }
        }
        OpticsCommand::Resolution {
            distance_m,
            pixel_um,
            focal_mm,
            min_shift_px,
            min_target_px,
            json,
        } => {
            let r = resolution(pixel_um, focal_mm, distance_m, min_shift_px, min_target_px)?;
            if json {
                println!("{}", serde_json::to_string(&r)?);
            } else {
                println!(
                    "one pixel: {:.3} mrad ({:.4}°), {:.2} cm at {} m\nsmallest displacement ({min_shift_px} px): {:.2} cm\nsmallest object ({min_target_px} px): {:.2} cm",
                    r.pixel_angle_mrad,
                    r.pixel_angle_deg,
                    r.pixel_footprint_m * 100.0,
                    r.distance_m,
                    r.min_displacement_m * 100.0,
                    r.min_object_m * 100.0
                );
            }
        }
        OpticsCommand::Stereo {
            x1_mm,
            x2_mm,
            baseline_m,
            focal_mm,
            profile,
            json,
        } => {
            let p = match profile {
                ProfileArg::Hyperbolic => Profile::Hyperbolic,
                ProfileArg::Quadratic => Profile::Quadratic,
            };
            let z = stereo::depth(p, x1_mm, x2_mm, focal_mm, baseline_m)?;
            let (a, b) = (
                stereo::incident_angle(p, x1_mm, focal_mm)?,
                stereo::incident_angle(p, x2_mm, focal_mm)?,
            );
            if json {
                println!(
                    "{}",
                    serde_json::json!({"depth_m": z, "alpha_deg": a.to_degrees(), "beta_deg": b.to_degrees()})
                );
            } else {
                println!(
                    "α = {:.4}°, β = {:.4}°, depth Z = {z:.4} m",
                    a.to_degrees(),
                    b.to_degrees()
                );
            }
        }
        OpticsCommand::Fov {
            tilts_deg,
            fov_deg,
            spots,
            grid,
            json,
        } => {
            let cov = fov::coverage(&tilts_deg, fov_deg)?;
            let mut sweeps = Vec::new();
            if spots {
                for design in [45.0, 80.0] {
                    sweeps.push((design, fov::spot_sweep(&Lens::default(), design, 4, grid)?));
                }
            }
            if json {
                let s: Vec<_> = sweeps
                    .iter()
                    .map(|(d, r)| serde_json::json!({"designed_fov_deg": d, "rows": r}))
                    .collect();
                println!("{}", serde_json::json!({"coverage": cov, "spots": s}));
            } else {
                for (i, s) in cov.sectors.iter().enumerate() {
                    println!("lens {}: {:.1}° … {:.1}°", i + 1, s[0], s[1]);
                }
                println!(
                    "total field of view {:.1}°; neighbour overlaps {:?}°",
                    cov.total_deg, cov.overlaps_deg
                );
                for (design, rows) in sweeps {
                    println!(
                        "\nlens designed for {design}° (hyperbolic, 532 nm): spot radius / Airy radius"
                    );
                    for r in rows {
                        println!(
                            "  {:5.1}°: {:8.2} µm / {:.2} µm = {:.1}",
                            r.field_angle_deg,
                            r.spot_radius_um,
                            r.airy_radius_um,
                            r.spot_radius_um / r.airy_radius_um
                        );
                    }
                }
            }
        }
    }
    Ok(())
}
