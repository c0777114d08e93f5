//! A tracking experiment's result (`track::experiment`): its rows per clip, predictor, object
//! and horizon, the clip-level counts (ID switches, spurious and second tracks, missed objects,
//! coverage), and the text table a reader compares across.

use serde::{Deserialize, Serialize};

use super::FlowSource;
use crate::track::detect::static_flow::BackgroundFlow;
use crate::track::eval::HorizonError;
use crate::track::eval::coverage::Coverage;
use crate::track::eval::points::{OperatingPoint, PointRow};

/// One row of the result: a clip, a predictor, one tracked object (or `all`), one horizon.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub clip: String,
    pub predictor: String,
    /// The true object index, or null for the pooled row.
    pub object: Option<usize>,
    pub track_id: Option<usize>,
    #[serde(flatten)]
    pub error: HorizonError,
    pub ms_per_frame: f64,
    /// The operating point (MMS flow; absent for exact flow).
    #[serde(default)]
    pub point: Option<OperatingPoint>,
}

/// The whole result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ExperimentReport {
    pub flow: FlowSource,
    /// Flow estimation time per frame (estimated flow only).
    pub flow_ms_per_frame: Option<f64>,
    pub rows: Vec<Row>,
    /// (clip, predictor) → ID switches.
    pub id_switches: Vec<(String, String, usize)>,
    /// (clip, predictor) → tracks that follow no object.
    #[serde(default)]
    pub spurious: Vec<(String, String, usize)>,
    /// (clip, predictor) → second tracks: on an object another track follows (picked up
    /// again under a new ID).
    #[serde(default)]
    pub second: Vec<(String, String, usize)>,
    /// (clip, predictor) → true objects followed by no track.
    #[serde(default)]
    pub missed: Vec<(String, String, Vec<usize>)>,
    /// (clip, predictor) → how much of the objects the tracks cover and IDF1.
    #[serde(default)]
    pub coverage: Vec<(String, String, Coverage)>,
    /// Clip → background-flow magnitude of its flows.
    #[serde(default)]
    pub background_flow: Vec<(String, BackgroundFlow)>,
    /// MMS flow: one row per clip, operating point and predictor.
    #[serde(default)]
    pub points: Vec<PointRow>,
}

/// The report as a text table.
pub fn table(r: &ExperimentReport) -> String {
    let mut s = format!(
        "{:<12} {:<22} {:>6} {:>7} {:>6} {:>9} {:>9} {:>9} {:>8}\n",
        "clip",
        "predictor",
        "object",
        "horizon",
        "count",
        "RMSE_X",
        "RMSE_Y",
        "RMSE_2D",
        "ms/frame"
    );
    for row in &r.rows {
        let obj = row.object.map_or("all".to_string(), |o| o.to_string());
        s += &format!(
            "{:<12} {:<22} {:>6} {:>7} {:>6} {:>9.2} {:>9.2} {:>9.2} {:>8.3}\n",
            row.clip,
            row.predictor,
            obj,
            row.error.horizon,
            row.error.count,
            row.error.rmse_x,
            row.error.rmse_y,
            row.error.rmse_2d,
            row.ms_per_frame
        );
    }
    for (c, p, n) in &r.id_switches {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} ID switches\n");
        }
    }
    for (c, p, n) in &r.spurious {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} tracks follow no object\n");
        }
    }
    for (c, p, n) in &r.second {
        if *n > 0 {
            s += &format!("{c} / {p}: {n} second tracks on an object another track follows\n");
        }
    }
    for (c, p, m) in &r.missed {
        if !m.is_empty() {
            s += &format!("{c} / {p}: missed objects {m:?}\n");
        }
    }
    for (c, p, v) in &r.coverage {
        s += &format!(
            "{c} / {p}: coverage {:.1} % (mostly tracked {}, partially {}, mostly lost {}), IDF1 {:.3}\n",
            100.0 * v.recall,
            v.mostly_tracked,
            v.partially_tracked,
            v.mostly_lost,
            v.idf1
        );
    }
    for (c, b) in &r.background_flow {
        s += &format!(
            "{c}: background flow mean {:.3} px, p99 {:.3} px\n",
            b.mean, b.p99
        );
    }
    if let Some(ms) = r.flow_ms_per_frame {
        let name = if r.flow == FlowSource::Dis {
            "DIS"
        } else {
            "MMS"
        };
        s += &format!("{name} flow: {ms:.0} ms per frame\n");
    }
    s
}
