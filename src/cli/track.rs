//! The tracking command: track.

use std::path::PathBuf;

use anyhow::Result;

use pins::io::{self};

#[derive(clap::Args)]
pub(crate) struct TrackArgs {
    /// Folder of .flo files, in frame order by name.
    #[arg(long)]
    flows: PathBuf,
    /// Output folder (tracks.json).
    #[arg(long)]
    out: PathBuf,
    /// Fitting window L in frames.
    #[arg(long, default_value_t = 30)]
    window: usize,
    /// Polynomial order n.
    #[arg(long, default_value_t = 2)]
    order: usize,
    /// Prediction horizons in frames.
    #[arg(long, value_delimiter = ',', default_value = "1,15,30")]
    horizons: Vec<usize>,
    /// Flow magnitude (px/frame) above which a pixel is moving.
    #[arg(long, default_value_t = 0.5)]
    threshold: f64,
    /// Smallest region (pixels) that is an object.
    #[arg(long, default_value_t = 20)]
    min_area: usize,
}

pub(crate) fn track(a: TrackArgs) -> Result<()> {
    use pins::track::{mtp::MtpConfig, multi::TrackerConfig, run};
    let tracker = TrackerConfig {
        mtp: MtpConfig {
            window: a.window,
            order: a.order,
            ..MtpConfig::default()
        },
        ..TrackerConfig::default()
    };
    let opts = run::TrackOptions {
        tracker,
        horizons: a.horizons,
        threshold: a.threshold,
        min_area: a.min_area,
    };
    let files = run::flow_files(&a.flows)?;
    let started = std::time::Instant::now();
    let tracks = run::track_flows(&files, &opts)?;
    let ms = started.elapsed().as_secs_f64() * 1e3 / files.len() as f64;
    let out = a.out.join("tracks.json");
    io::write_bytes_atomic(&out, serde_json::to_string_pretty(&tracks)?.as_bytes())?;
    println!(
        "{}: {} objects over {} frames, {ms:.1} ms per frame",
        out.display(),
        tracks.objects.len(),
        files.len()
    );
    Ok(())
}
