//! The plot of flow error against run time: MMS at each iteration count, the zero-flow
//! baseline, and peer methods (OpenCV DIS, Farneback) measured on the same data.

use std::path::Path;

use serde::Deserialize;

use crate::error::{Error, Result};
use crate::flow::eval::EvalReport;
use crate::io::chart::{Chart, Series};

/// One peer method's result, as written by `scripts/flow_baselines.py`.
#[derive(Clone, Debug, Deserialize)]
pub struct PeerRow {
    pub name: String,
    pub epe: f64,
    pub ms_per_pair: f64,
}

/// Reads `{"methods": [{"name", "epe", "ms_per_pair", ...}]}`.
pub fn read_peers(path: &Path) -> Result<Vec<PeerRow>> {
    #[derive(Deserialize)]
    struct File {
        methods: Vec<PeerRow>,
    }
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let f: File = serde_json::from_str(&text).map_err(|e| Error::format(path, e.to_string()))?;
    Ok(f.methods)
}

/// An MMS method through its iteration counts: a line, and its points marked.
pub fn iteration_series(name: &str, points: Vec<(f64, f64)>, iters: &[usize]) -> [Series; 2] {
    let iters: Vec<String> = iters.iter().map(|n| n.to_string()).collect();
    [
        Series {
            name: format!("{name} (iterations {})", iters.join(", ")),
            points: points.clone(),
            markers: false,
        },
        Series {
            name: format!("{name} points"),
            points,
            markers: true,
        },
    ]
}

/// Writes the EPE-against-time PNG.
pub fn write(report: &EvalReport, peers: Option<&Path>, png: &Path) -> Result<()> {
    // One line for the network alone and one for the refined flow, through the iteration counts.
    let mut series = Vec::new();
    for refined in [false, true] {
        let rows: Vec<_> = report
            .rows
            .iter()
            .filter(|r| r.refined == refined)
            .collect();
        if rows.is_empty() {
            continue;
        }
        let name = crate::flow::eval::mms_method(&report.model, refined);
        let points: Vec<(f64, f64)> = rows.iter().map(|r| (r.ms_per_pair, r.epe)).collect();
        let iters: Vec<usize> = rows.iter().map(|r| r.iters).collect();
        series.extend(iteration_series(&name, points, &iters));
    }
    if let Some(p) = peers {
        for peer in read_peers(p)? {
            series.push(Series {
                name: peer.name.clone(),
                points: vec![(peer.ms_per_pair, peer.epe)],
                markers: true,
            });
        }
    }
    series.push(Series {
        name: "zero flow".into(),
        points: vec![(0.0, report.zero_flow.epe)],
        markers: true,
    });
    Chart {
        title: format!("EPE against run time, {} pairs", report.pairs),
        x_label: "ms per pair".into(),
        y_label: "EPE (px)".into(),
        series,
        log_y: true,
    }
    .write_png(png, 800, 500)
}
