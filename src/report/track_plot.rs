//! Fig. S11-style plots of one tracked object. Left (Output I): the true path (black), the
//! tracked centre at frame N (black dot), the predicted path N+1 … N+K (red) with a star at
//! N+K. Right (Output II): the all-time prediction trajectory (the N+K prediction made at
//! every frame, placed at N+K) against the true path. Image coordinates, y pointing down.

use std::path::Path;

use plotters::prelude::*;

use crate::error::Result;
use crate::io::chart::{plot_err, register_font, write_rgb_png};
use crate::scene::truth::TruthObject;
use crate::track::tracker::tracks::ObjectTrack;

const RED: RGBColor = RGBColor(214, 39, 40);
const BLUE: RGBColor = RGBColor(31, 119, 180);

/// A five-pointed star of outer radius `r` pixels, as offsets from its centre.
fn star(r: f64) -> Vec<(i32, i32)> {
    (0..10)
        .map(|k| {
            let a = std::f64::consts::PI * (k as f64 / 5.0 - 0.5);
            let rad = if k % 2 == 0 { r } else { 0.4 * r };
            (
                (rad * a.cos()).round() as i32,
                (rad * a.sin()).round() as i32,
            )
        })
        .collect()
}

/// The runs of consecutive points inside `[0, w] × [0, h]`.
fn in_frame_segments(points: &[(f64, f64)], w: f64, h: f64) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for &(x, y) in points {
        if (0.0..=w).contains(&x) && (0.0..=h).contains(&y) {
            if let Some(last) = out.last_mut() {
                last.push((x, y));
            }
        } else if out.last().is_some_and(|l| !l.is_empty()) {
            out.push(Vec::new());
        }
    }
    out.retain(|s| !s.is_empty());
    out
}

/// The snapshot frame of a track: K frames before its last observed frame when it is long
/// enough (so the prediction can be compared with the path then taken), else its last frame.
pub fn snapshot_index(track: &ObjectTrack, horizon: usize) -> Option<usize> {
    let last = track.frames.iter().rposition(|f| f.observed)?;
    let back = track.frames[..=last]
        .iter()
        .rposition(|f| f.observed && f.frame + horizon <= track.frames[last].frame);
    Some(back.unwrap_or(last))
}

/// Writes the two-panel plot of `track` for horizon `horizon` (a key of its predictions),
/// with the true path of `truth` when given, in a `width × height` frame.
pub fn plot_track(
    path: &Path,
    track: &ObjectTrack,
    horizon: usize,
    truth: Option<&TruthObject>,
    frame_size: (usize, usize),
    fps: f64,
) -> Result<()> {
    register_font();
    let (pw, ph) = (1200u32, 520u32);
    let mut buf = vec![255u8; (pw * ph * 3) as usize];
    let key = horizon.to_string();
    let snap = snapshot_index(track, horizon);
    {
        let root = BitMapBackend::with_buffer(&mut buf, (pw, ph)).into_drawing_area();
        root.fill(&WHITE).map_err(plot_err)?;
        let panels = root.split_evenly((1, 2));
        let (w, h) = (frame_size.0 as f64, frame_size.1 as f64);
        let truth_path: Vec<(f64, f64)> = truth
            .map(|t| {
                t.centroids
                    .iter()
                    .zip(&t.visible)
                    .filter(|(_, v)| **v)
                    .map(|(c, _)| (c[0], c[1]))
                    .collect()
            })
            .unwrap_or_default();
        let tracked: Vec<(f64, f64)> = track
            .frames
            .iter()
            .filter(|f| f.observed)
            .map(|f| (f.centroid[0], f.centroid[1]))
            .collect();
        for (k, panel) in panels.iter().enumerate() {
            let title = if k == 0 {
                match snap.map(|i| &track.frames[i]) {
                    Some(f) => format!(
                        "ID {}: frame N = {}, v = {:.0} px/s, prediction to N+{horizon}",
                        track.id,
                        f.frame,
                        f.speed * fps
                    ),
                    None => format!("ID {}", track.id),
                }
            } else {
                format!(
                    "ID {}: all-time prediction, {horizon} frames ahead",
                    track.id
                )
            };
            let mut chart = ChartBuilder::on(panel)
                .caption(title, ("sans-serif", 16))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(45)
                .build_cartesian_2d(0.0..w, h..0.0)
                .map_err(plot_err)?;
            chart
                .configure_mesh()
                .x_desc("x (px)")
                .y_desc("y (px)")
                .label_style(("sans-serif", 12))
                .draw()
                .map_err(plot_err)?;
            if !truth_path.is_empty() {
                chart
                    .draw_series(LineSeries::new(truth_path.clone(), BLACK.stroke_width(2)))
                    .map_err(plot_err)?
                    .label("ground truth")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK));
            }
            if k == 0 {
                chart
                    .draw_series(LineSeries::new(tracked.clone(), BLUE.mix(0.6)))
                    .map_err(plot_err)?
                    .label("tracked centre")
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
                if let Some(f) = snap.map(|i| &track.frames[i]) {
                    // The full path when it was kept, else the horizons' points.
                    let mut pred: Vec<(f64, f64)> = vec![(f.centroid[0], f.centroid[1])];
                    if f.path.is_empty() {
                        pred.extend(f.predicted.values().map(|p| (p[0], p[1])));
                    } else {
                        pred.extend(f.path.iter().take(horizon).map(|p| (p[0], p[1])));
                    }
                    chart
                        .draw_series(LineSeries::new(pred, RED.stroke_width(2)))
                        .map_err(plot_err)?
                        .label("predicted path")
                        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
                    if let Some(p) = f.predicted.get(&key) {
                        chart
                            .draw_series([EmptyElement::at((p[0], p[1]))
                                + Polygon::new(star(11.0), RED.filled())])
                            .map_err(plot_err)?;
                    }
                    chart
                        .draw_series([Circle::new(
                            (f.centroid[0], f.centroid[1]),
                            5,
                            BLACK.filled(),
                        )])
                        .map_err(plot_err)?;
                }
            } else {
                let all_time: Vec<(f64, f64)> = track
                    .frames
                    .iter()
                    .filter_map(|f| f.predicted.get(&key).map(|p| (p[0], p[1])))
                    .collect();
                // Predictions outside the frame break the line instead of running along the edge.
                for (i, seg) in in_frame_segments(&all_time, w, h).into_iter().enumerate() {
                    let series = chart
                        .draw_series(LineSeries::new(seg, RED.stroke_width(2)))
                        .map_err(plot_err)?;
                    if i == 0 {
                        series
                            .label(format!("prediction at N+{horizon}"))
                            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
                    }
                }
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(plot_err)?;
        }
        root.present().map_err(plot_err)?;
    }
    write_rgb_png(path, &buf, pw, ph)
}
