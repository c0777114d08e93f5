//! `pins refine`: the variational refinement (the last stage of DIS, `flow::refine`) on a flow
//! from anywhere — another method's, the network's saved flow, or the ground truth to see where
//! the energy's own minimum lies — as OpenCV offers its VariationalRefinement on its own.

use std::path::PathBuf;

use anyhow::{Result, bail};

use pins::io::{self, BitDepth};

#[derive(clap::Args)]
pub(crate) struct RefineArgs {
    /// First image.
    #[arg(long)]
    img1: PathBuf,
    /// Second image (the same size).
    #[arg(long)]
    img2: PathBuf,
    /// The flow to refine, from the first image to the second (.flo, KITTI .png, .pfm or
    /// .exr; every vector known, the images' size).
    #[arg(long)]
    flow: PathBuf,
    /// Output flow file (.flo, .png, .pfm or .exr).
    #[arg(long)]
    out: PathBuf,
    /// Also write the Middlebury colour-wheel visualisation (PNG).
    #[arg(long)]
    viz: Option<PathBuf>,
    /// The refinement: variational (the flow commands' settings) or a .json file of settings
    /// (scales, alpha, delta, gamma, fixed_point_iters, sor_iters, omega, kappa).
    #[arg(long, default_value = "variational")]
    refine: String,
}

pub(crate) fn refine(a: RefineArgs) -> Result<()> {
    use pins::flow::refine::{Refine, refine};
    let Some(cfg) = Refine::parse(&a.refine)?.config() else {
        bail!("--refine none leaves nothing to do; give variational or a .json file of settings");
    };
    let (img1, img2) = io::read_image_pair(&a.img1, &a.img2)?;
    let flow = io::read_flow(&a.flow)?;
    if (flow.width(), flow.height()) != (img1.width(), img1.height()) {
        bail!(
            "the flow {} is {}x{}, the images {}x{}: the flow must be the images' size",
            a.flow.display(),
            flow.width(),
            flow.height(),
            img1.width(),
            img1.height()
        );
    }
    let unknown = flow.u().iter().filter(|x| !x.is_finite()).count();
    if unknown > 0 {
        bail!(
            "the flow {} has {unknown} unknown vectors (of {}); the refinement needs a dense flow",
            a.flow.display(),
            flow.u().len()
        );
    }
    let t = std::time::Instant::now();
    let out = refine(&img1, &img2, &flow, &cfg)?;
    let ms = t.elapsed().as_secs_f64() * 1e3;
    io::write_flow(&a.out, &out)?;
    if let Some(v) = &a.viz {
        let viz = pins::flow::viz::flow_to_image(&out, None);
        if let Err(e) = io::write_image(v, &viz, BitDepth::Eight) {
            // No partial output: the flow goes too when its picture cannot be written.
            let _ = std::fs::remove_file(&a.out);
            return Err(e.into());
        }
    }
    // The mean change is the refined flow's end-point error against the flow it started from.
    let mut change = pins::flow::metrics::FlowErrorSums::default();
    change.add(&out, &flow, None)?;
    println!(
        "{} → {}: {}x{}, mean change {:.3} px, max |flow| {:.2} px, {ms:.0} ms",
        a.flow.display(),
        a.out.display(),
        out.width(),
        out.height(),
        change.scores().epe,
        out.max_magnitude(),
    );
    Ok(())
}
