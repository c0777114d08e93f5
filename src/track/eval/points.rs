//! The whole system's error against run time (Notes S13–S15): operating points of the MMS
//! flow (resolution and iterations) and, per clip, what each costs per frame and scores.

use serde::{Deserialize, Serialize};

use crate::track::detect::static_flow::BackgroundFlow;

/// One point of the whole system's error against run time: MMS at `scale` of the frame size
/// (`crate::flow::scale`) after `iters` refinements.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OperatingPoint {
    pub scale: f64,
    pub iters: usize,
}

impl OperatingPoint {
    /// A short label, e.g. `scale 0.50, 4 it`.
    pub fn label(&self) -> String {
        format!("scale {:.2}, {} it", self.scale, self.iters)
    }
}

/// One clip at one operating point with one predictor: what the whole system costs per frame
/// and what it scores (the error-against-run-time table).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointRow {
    pub clip: String,
    pub predictor: String,
    pub point: OperatingPoint,
    /// MMS time per frame (the network alone) and tracking time per frame.
    pub flow_ms_per_frame: f64,
    pub track_ms_per_frame: f64,
    /// Pooled RMSE_2D per horizon, in `horizons` order.
    pub rmse_2d: Vec<(usize, f64)>,
    pub tracks: usize,
    pub id_switches: usize,
    pub spurious: usize,
    pub missed: usize,
    pub background_flow: Option<BackgroundFlow>,
}

/// The error-against-run-time table of the operating points (empty for exact flow).
pub fn points_table(points: &[PointRow]) -> String {
    if points.is_empty() {
        return String::new();
    }
    let horizons: Vec<usize> = points[0].rmse_2d.iter().map(|&(h, _)| h).collect();
    let mut s = format!(
        "{:<12} {:<22} {:>5} {:>5} {:>9} {:>9} {:>9}",
        "clip", "predictor", "scale", "iters", "flow ms", "track ms", "total ms"
    );
    for h in &horizons {
        s += &format!(" {:>9}", format!("RMSE@{h}"));
    }
    s += &format!(
        " {:>6} {:>5} {:>5} {:>6} {:>8} {:>8}\n",
        "tracks", "IDsw", "spur", "missed", "bg mean", "bg p99"
    );
    for p in points {
        s += &format!(
            "{:<12} {:<22} {:>5.2} {:>5} {:>9.0} {:>9.2} {:>9.0}",
            p.clip,
            p.predictor,
            p.point.scale,
            p.point.iters,
            p.flow_ms_per_frame,
            p.track_ms_per_frame,
            p.flow_ms_per_frame + p.track_ms_per_frame
        );
        for (_, e) in &p.rmse_2d {
            s += &format!(" {e:>9.2}");
        }
        let (bm, bp) = p
            .background_flow
            .as_ref()
            .map_or((f64::NAN, f64::NAN), |b| (b.mean, b.p99));
        s += &format!(
            " {:>6} {:>5} {:>5} {:>6} {:>8.3} {:>8.3}\n",
            p.tracks, p.id_switches, p.spurious, p.missed, bm, bp
        );
    }
    s
}

/// The error-against-run-time chart: per clip and predictor, RMSE_2D at `horizon` against
/// the whole system's milliseconds per frame (flow + tracking), one marker per operating point.
pub fn points_chart(points: &[PointRow], horizon: usize) -> Option<crate::io::chart::Chart> {
    use crate::io::chart::{Chart, Series};
    if points.is_empty() {
        return None;
    }
    let mut series: Vec<Series> = Vec::new();
    for p in points {
        let Some(&(_, e)) = p.rmse_2d.iter().find(|(h, _)| *h == horizon) else {
            continue;
        };
        let name = format!("{} / {}", p.clip, p.predictor);
        let x = p.flow_ms_per_frame + p.track_ms_per_frame;
        match series.iter_mut().find(|s| s.name == name) {
            Some(s) => s.points.push((x, e)),
            None => series.push(Series {
                name,
                points: vec![(x, e)],
                markers: true,
            }),
        }
    }
    Some(Chart {
        title: format!("Whole system: RMSE_2D {horizon} frame(s) ahead against run time"),
        x_label: "ms per frame (MMS flow + tracking)".into(),
        y_label: format!("RMSE_2D at {horizon} frame(s) (px)"),
        series,
        log_y: true,
    })
}
