//! `pins bench-real`: MMS against OpenCV's DIS and Farneback and the zero flow on real image
//! pairs with exact ground truth (and any set the generator can make), clean and through the
//! camera, per set and per pair, with EPE-against-time plots (with Table S4's measures).

pub mod config;
pub mod markdown;
pub mod peers;
pub mod plot;
pub mod report;
pub mod run;
pub mod verdict;

use std::path::{Path, PathBuf};

pub use report::BenchRealReport;
pub use run::{BenchOptions, run};

use crate::error::{Error, Result};

/// Writes `report.json`, `report.md` and the plots into `out` (each file atomically); returns
/// their paths.
pub fn write_outputs(r: &BenchRealReport, out: &Path, command: &str) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let json = out.join("report.json");
    let text =
        serde_json::to_string_pretty(r).map_err(|e| Error::invalid("report", e.to_string()))?;
    let md = out.join("report.md");
    let mut files = plot::write(r, out)?;
    crate::io::write_bytes_atomic(&md, markdown::markdown(r, command).as_bytes())?;
    crate::io::write_bytes_atomic(&json, text.as_bytes())?;
    files.insert(0, md);
    files.insert(0, json);
    Ok(files)
}
