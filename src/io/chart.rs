//! Line and scatter charts written as PNG (plotters on an in-memory RGB buffer, then the PNG
//! encoder of this crate), with the shipped DejaVu Sans font so no system font is needed. It
//! sits in `io` because training, evaluation and reports all write charts.

use std::path::Path;
use std::sync::Once;

use plotters::prelude::*;

use crate::error::{Error, Result};
use crate::io::{BitDepth, write_image};
use crate::types::Image;

static FONT: &[u8] = include_bytes!("../../datasets/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Makes the shipped font the "sans-serif" family of plotters (once per process).
pub fn register_font() {
    REGISTER.call_once(|| {
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One named series of (x, y) points.
#[derive(Clone, Debug)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Draw markers (and a label) at each point instead of a line.
    pub markers: bool,
}

/// A chart: title, axis labels, series; `log_y` plots y on a log scale.
#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub log_y: bool,
}

const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// A plotters error as this crate's error.
pub fn plot_err(e: impl std::fmt::Display) -> Error {
    Error::invalid("chart", e.to_string())
}

impl Chart {
    /// Renders to a `width × height` PNG at `path` (atomically).
    pub fn write_png(&self, path: &Path, width: u32, height: u32) -> Result<()> {
        register_font();
        let pts: Vec<(f64, f64)> = self
            .series
            .iter()
            .flat_map(|s| s.points.iter().copied())
            .filter(|(x, y)| x.is_finite() && y.is_finite() && (!self.log_y || *y > 0.0))
            .collect();
        if pts.is_empty() {
            return Err(Error::invalid(
                "chart",
                format!("{}: no finite points to plot", self.title),
            ));
        }
        let (mut x0, mut x1) = pts
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
        let (mut y0, mut y1) = pts
            .iter()
            .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
        if x1 <= x0 {
            x1 = x0 + 1.0;
            x0 -= 1.0;
        }
        if y1 <= y0 {
            y1 = y0 * 1.5 + 1e-3;
            y0 = if self.log_y { y0 / 1.5 } else { y0 - (y1 - y0) };
        }
        let pad = (x1 - x0) * 0.05;
        let (x0, x1) = (x0 - pad, x1 + pad);
        let mut buf = vec![255u8; (width * height * 3) as usize];
        {
            let root = BitMapBackend::with_buffer(&mut buf, (width, height)).into_drawing_area();
            root.fill(&WHITE).map_err(plot_err)?;
            let mut builder = ChartBuilder::on(&root);
            builder
                .caption(&self.title, ("sans-serif", 20))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60);
            macro_rules! draw {
                ($chart:expr) => {{
                    let mut chart = $chart;
                    chart
                        .configure_mesh()
                        .x_desc(self.x_label.as_str())
                        .y_desc(self.y_label.as_str())
                        .label_style(("sans-serif", 13))
                        .draw()
                        .map_err(plot_err)?;
                    for (i, s) in self.series.iter().enumerate() {
                        let colour = PALETTE[i % PALETTE.len()];
                        let points: Vec<(f64, f64)> = s
                            .points
                            .iter()
                            .copied()
                            .filter(|(x, y)| {
                                x.is_finite() && y.is_finite() && (!self.log_y || *y > 0.0)
                            })
                            .collect();
                        if s.markers {
                            chart
                                .draw_series(
                                    points.iter().map(|&p| Circle::new(p, 5, colour.filled())),
                                )
                                .map_err(plot_err)?
                                .label(s.name.as_str())
                                .legend(move |(x, y)| Circle::new((x + 10, y), 5, colour.filled()));
                        } else {
                            chart
                                .draw_series(LineSeries::new(points, colour.stroke_width(2)))
                                .map_err(plot_err)?
                                .label(s.name.as_str())
                                .legend(move |(x, y)| {
                                    PathElement::new(
                                        vec![(x, y), (x + 20, y)],
                                        colour.stroke_width(2),
                                    )
                                });
                        }
                    }
                    chart
                        .configure_series_labels()
                        .background_style(WHITE.mix(0.85))
                        .border_style(BLACK)
                        .label_font(("sans-serif", 13))
                        .draw()
                        .map_err(plot_err)?;
                }};
            }
            if self.log_y {
                draw!(
                    builder
                        .build_cartesian_2d(x0..x1, (y0 * 0.8..y1 * 1.25).log_scale())
                        .map_err(plot_err)?
                );
            } else {
                let pad = (y1 - y0) * 0.08;
                draw!(
                    builder
                        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
                        .map_err(plot_err)?
                );
            }
            root.present().map_err(plot_err)?;
        }
        write_rgb_png(path, &buf, width, height)
    }
}

/// Writes an interleaved 8-bit RGB buffer (what plotters draws into) as a PNG, atomically.
pub fn write_rgb_png(path: &Path, buf: &[u8], width: u32, height: u32) -> Result<()> {
    let (w, h) = (width as usize, height as usize);
    if buf.len() != 3 * w * h {
        return Err(Error::shape("RGB buffer", 3 * w * h, buf.len()));
    }
    // Interleaved RGB → planar [3, H, W] in [0, 1].
    let mut planar = vec![0.0f32; 3 * w * h];
    for (i, px) in buf.chunks_exact(3).enumerate() {
        for c in 0..3 {
            planar[c * w * h + i] = px[c] as f32 / 255.0;
        }
    }
    write_image(path, &Image::from_vec(3, h, w, planar)?, BitDepth::Eight)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_a_png_and_rejects_empty_charts() {
        let d = tempfile::tempdir().unwrap();
        let chart = Chart {
            title: "loss".into(),
            x_label: "step".into(),
            y_label: "L1".into(),
            series: vec![Series {
                name: "train".into(),
                points: (1..50).map(|i| (i as f64, 10.0 / i as f64)).collect(),
                markers: false,
            }],
            log_y: true,
        };
        let p = d.path().join("c.png");
        chart.write_png(&p, 320, 240).unwrap();
        let img = crate::io::read_image(&p).unwrap();
        assert_eq!((img.width(), img.height()), (320, 240));
        assert!(img.data().iter().any(|&v| v < 0.5), "something was drawn");
        let empty = Chart {
            series: vec![],
            ..chart
        };
        assert!(empty.write_png(&d.path().join("e.png"), 100, 100).is_err());
        assert!(!d.path().join("e.png").exists());
    }
}
