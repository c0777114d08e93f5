//! The training log: one CSV row per step (kept exact across `--resume`: rows past the resumed
//! step are dropped) and the PNG of the training and validation curves.

use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};
use crate::io::chart::{Chart, Series};

/// One step's numbers.
#[derive(Clone, Debug)]
pub struct LogRow {
    pub step: usize,
    pub lr: f64,
    pub loss: f64,
    pub epe: f64,
    pub grad_norm: f64,
    pub ms_per_step: f64,
    pub val_epe: Option<f64>,
    pub val_px1: Option<f64>,
}

const HEADER: &str = "step,lr,loss,epe,grad_norm,ms_per_step,val_epe,val_px1";

/// An append-only CSV with the rows in memory for plotting.
pub struct TrainLog {
    path: PathBuf,
    rows: Vec<LogRow>,
}

fn parse_row(line: &str) -> Option<LogRow> {
    let f: Vec<&str> = line.split(',').collect();
    if f.len() != 8 {
        return None;
    }
    let opt = |s: &str| if s.is_empty() { None } else { s.parse().ok() };
    Some(LogRow {
        step: f[0].parse().ok()?,
        lr: f[1].parse().ok()?,
        loss: f[2].parse().ok()?,
        epe: f[3].parse().ok()?,
        grad_norm: f[4].parse().ok()?,
        ms_per_step: f[5].parse().ok()?,
        val_epe: opt(f[6]),
        val_px1: opt(f[7]),
    })
}

fn format_row(r: &LogRow) -> String {
    let opt = |v: Option<f64>| v.map(|x| format!("{x:.5}")).unwrap_or_default();
    format!(
        "{},{:.6e},{:.5},{:.5},{:.4},{:.1},{},{}",
        r.step,
        r.lr,
        r.loss,
        r.epe,
        r.grad_norm,
        r.ms_per_step,
        opt(r.val_epe),
        opt(r.val_px1)
    )
}

impl TrainLog {
    /// Opens the log, keeping the rows up to `keep_until` (the resumed step) and rewriting it.
    pub fn open(path: &Path, keep_until: usize) -> Result<Self> {
        let rows: Vec<LogRow> = match std::fs::read_to_string(path) {
            Ok(text) => text
                .lines()
                .skip(1)
                .filter_map(parse_row)
                .filter(|r| r.step <= keep_until)
                .collect(),
            Err(_) => Vec::new(),
        };
        let mut text = String::from(HEADER);
        text.push('\n');
        for r in &rows {
            text += &format_row(r);
            text.push('\n');
        }
        crate::io::write_bytes_atomic(path, text.as_bytes())?;
        Ok(Self {
            path: path.to_path_buf(),
            rows,
        })
    }

    /// Appends one row to the file and to memory.
    pub fn append(&mut self, row: &LogRow) -> Result<()> {
        let mut f = std::fs::OpenOptions::new()
            .append(true)
            .open(&self.path)
            .map_err(|e| Error::io(&self.path, e))?;
        writeln!(f, "{}", format_row(row)).map_err(|e| Error::io(&self.path, e))?;
        self.rows.push(row.clone());
        Ok(())
    }

    pub fn rows(&self) -> &[LogRow] {
        &self.rows
    }

    /// Training loss and EPE (smoothed over 50 steps) and validation EPE against the step.
    pub fn plot(&self, path: &Path) -> Result<()> {
        if self.rows.is_empty() {
            return Ok(());
        }
        let smooth = |f: &dyn Fn(&LogRow) -> f64| -> Vec<(f64, f64)> {
            let w = 50usize;
            (0..self.rows.len())
                .map(|i| {
                    let lo = i.saturating_sub(w - 1);
                    let win = &self.rows[lo..=i];
                    (
                        self.rows[i].step as f64,
                        win.iter().map(f).sum::<f64>() / win.len() as f64,
                    )
                })
                .collect()
        };
        let val: Vec<(f64, f64)> = self
            .rows
            .iter()
            .filter_map(|r| r.val_epe.map(|v| (r.step as f64, v)))
            .collect();
        let mut series = vec![
            Series {
                name: "train loss (Eq. S16)".into(),
                points: smooth(&|r| r.loss),
                markers: false,
            },
            Series {
                name: "train EPE (px)".into(),
                points: smooth(&|r| r.epe),
                markers: false,
            },
        ];
        if !val.is_empty() {
            series.push(Series {
                name: "validation EPE (px)".into(),
                points: val,
                markers: true,
            });
        }
        Chart {
            title: "MMS training".into(),
            x_label: "step".into(),
            y_label: "loss / EPE".into(),
            series,
            log_y: true,
        }
        .write_png(path, 800, 500)
    }
}
