//! The EPE-against-time plots of the real-data benchmark, one per camera: MMS at each iteration
//! count as a line, each peer and the zero flow as a point, all over the known pixels of every
//! set pooled (the "all known pixels" rows of the summary).

use std::path::{Path, PathBuf};

use super::report::BenchRealReport;
use crate::error::Result;
use crate::io::chart::{Chart, Series};

/// `DIR/epe_vs_ms_CAMERA.png` for each camera with results; returns the files written.
pub fn write(r: &BenchRealReport, dir: &Path) -> Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    for cam in &r.cameras {
        let rows: Vec<_> = r
            .summary
            .iter()
            .filter(|s| &s.camera == cam)
            .map(|s| &s.pooled)
            .collect();
        if rows.is_empty() {
            continue;
        }
        // One line per MMS method (the network alone, and refined), through its iteration
        // counts.
        let mut methods: Vec<&str> = Vec::new();
        for m in rows.iter().filter(|m| m.iters.is_some()) {
            if !methods.contains(&m.method.as_str()) {
                methods.push(&m.method);
            }
        }
        let mut series = Vec::new();
        for name in methods {
            let of: Vec<_> = rows
                .iter()
                .filter(|m| m.iters.is_some() && m.method == name)
                .collect();
            let points: Vec<(f64, f64)> = of.iter().map(|m| (m.ms_per_pair, m.epe)).collect();
            let iters: Vec<usize> = of.iter().filter_map(|m| m.iters).collect();
            series.extend(crate::report::eval_plot::iteration_series(
                name, points, &iters,
            ));
        }
        for m in rows.iter().filter(|m| m.iters.is_none()) {
            series.push(Series {
                name: m.method.clone(),
                points: vec![(m.ms_per_pair, m.epe)],
                markers: true,
            });
        }
        let sets = r.runs.iter().filter(|x| &x.camera == cam).count();
        let pixels: u64 = r
            .runs
            .iter()
            .filter(|x| &x.camera == cam)
            .map(|x| x.pixels)
            .sum();
        let png = dir.join(format!("epe_vs_ms_{cam}.png"));
        Chart {
            title: format!("EPE against run time, {cam}: {pixels} known pixels of {sets} sets"),
            x_label: "ms per pair".into(),
            y_label: "EPE (px)".into(),
            series,
            log_y: true,
        }
        .write_png(&png, 800, 500)?;
        written.push(png);
    }
    Ok(written)
}
