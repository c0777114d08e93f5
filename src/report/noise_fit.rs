//! The photon-transfer report (Note S4's Eq. S3 fitted to a camera): the fits with their
//! intervals, every level's mean and variance with why a level was left out, and the chart of
//! variance against signal with the fitted lines.

use crate::imaging::calibrate::photon_transfer::{Level, NoiseFit};
use crate::io::chart::{Chart, Series};

/// The fits and the levels as markdown.
pub fn markdown(fits: &[NoiseFit], levels: &[Level]) -> String {
    let mut s = String::from(
        "| channel | a (DN/DN) | 95 % interval | b (DN²) | 95 % interval | levels | residual RMS |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for f in fits {
        let l = &f.line;
        s += &format!(
            "| {} | {:.4} | {:.4} – {:.4} | {:.3} | {:.3} – {:.3} | {} | {:.2} % |\n",
            f.channel.map_or("pooled".to_string(), |c| c.to_string()),
            l.a,
            l.a_ci[0],
            l.a_ci[1],
            l.b,
            l.b_ci[0],
            l.b_ci[1],
            l.points,
            100.0 * l.relative_rms
        );
    }
    s += "\n| level | channel | captures | mean (DN) | variance (DN²) | quantisation (DN²) | clipped | used |\n\
          |---|---|---|---|---|---|---|---|\n";
    for l in levels {
        s += &format!(
            "| {} | {} | {} | {:.3} | {:.4} | {:.4} | {:.4} % | {} |\n",
            l.name,
            l.channel,
            l.captures,
            l.mean,
            l.variance,
            l.quantisation,
            100.0 * l.clipped,
            l.excluded.as_deref().unwrap_or("yes")
        );
    }
    s
}

/// Variance against mean signal: each channel's levels as markers, each fit as a line.
pub fn chart(fits: &[NoiseFit], levels: &[Level]) -> Chart {
    let top = levels
        .iter()
        .map(|l| l.mean)
        .fold(0.0f64, f64::max)
        .max(1.0);
    let mut series = Vec::new();
    for f in fits {
        let name = f
            .channel
            .map_or("pooled fit".to_string(), |c| format!("channel {c} fit"));
        series.push(Series {
            name,
            points: vec![(0.0, f.line.b), (top, f.line.a * top + f.line.b)],
            markers: false,
        });
    }
    let channels = levels.iter().map(|l| l.channel + 1).max().unwrap_or(0);
    for c in 0..channels {
        for used in [true, false] {
            let points: Vec<(f64, f64)> = levels
                .iter()
                .filter(|l| l.channel == c && l.excluded.is_none() == used)
                .map(|l| (l.mean, l.variance))
                .collect();
            if !points.is_empty() {
                series.push(Series {
                    name: format!("channel {c}{}", if used { "" } else { " (left out)" }),
                    points,
                    markers: true,
                });
            }
        }
    }
    Chart {
        title: "Photon transfer: temporal variance against signal".into(),
        x_label: "mean signal (8-bit linear DN)".into(),
        y_label: "temporal variance (DN²)".into(),
        series,
        log_y: false,
    }
}
