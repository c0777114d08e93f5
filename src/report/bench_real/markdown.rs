//! `report.md` of the real-data benchmark: the summary (EPE and the 1-px fraction, a row per
//! set and camera, a column per method), MMS against DIS medium and across iterations
//! (`verdict.rs`), then a table per set and camera, then per pair.

use std::fmt::Write;

use super::report::{BenchRealReport, MethodScores, SetRun};
use crate::flow::metrics::{EpeBySpeed, SPEED_CLASS_NAMES};

/// The whole report as markdown; `command` is the command line that made it.
pub fn markdown(r: &BenchRealReport, command: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# MMS on real images\n");
    let _ = writeln!(s, "Made by `{command}`.\n");
    let _ = writeln!(
        s,
        "MMS: {} ({} parameters, weights {}{}) on {} thread(s). Peers: {}. Unknown ground truth \
         is left out of every score. A set's scores are means over its known pixels; the \
         \"mean of sets\" rows weigh every set the same, the \"all known pixels\" rows pool the \
         pixels of every set; ms per pair is wall time of the flow call alone.\n",
        r.model,
        r.parameters,
        r.weights,
        if r.start.is_empty() {
            String::new()
        } else {
            format!(", from a {} start", r.start)
        },
        r.threads,
        if r.peers.ran {
            format!(
                "OpenCV {} on {} thread(s) (scripts/flow_baselines.py)",
                r.peers.opencv.as_deref().unwrap_or("?"),
                r.peers.threads
            )
        } else {
            format!(
                "not run: {}",
                r.peers.skipped_because.as_deref().unwrap_or("?")
            )
        }
    );
    if let Some(w) = &r.peers.version_warning {
        let _ = writeln!(s, "**Warning:** {w}.\n");
    }
    for k in &r.skipped {
        let _ = writeln!(s, "- set **{}** skipped: {}", k.set, k.reason);
    }
    if !r.skipped.is_empty() {
        s.push('\n');
    }
    for (title, pick) in [
        (
            "EPE (px)",
            (|m: &MethodScores| m.epe) as fn(&MethodScores) -> f64,
        ),
        ("Fraction of pixels within 1 px", |m: &MethodScores| m.px1),
    ] {
        let _ = writeln!(s, "## {title}\n");
        summary_table(&mut s, r, pick);
    }
    speed_table(&mut s, r);
    super::verdict::markdown(&mut s, r);
    let _ = writeln!(s, "## Sets\n");
    for run in &r.runs {
        let _ = writeln!(
            s,
            "### {}, {}: {} pairs, {} known pixels, mean |flow| {:.2} px\n",
            run.set, run.camera, run.pairs, run.pixels, run.mean_gt
        );
        method_table(&mut s, &run.methods, true);
    }
    let _ = writeln!(s, "## Pairs\n");
    for run in &r.runs {
        for p in &run.per_pair {
            let _ = writeln!(
                s,
                "### {}, {}: {} ({}×{}, {} known pixels, mean |flow| {:.2} px)\n",
                run.set, run.camera, p.source, p.width, p.height, p.pixels, p.mean_gt
            );
            method_table(&mut s, &p.methods, false);
        }
    }
    s
}

/// Rows: each set through each camera, then the mean of the sets per camera; columns: methods.
fn summary_table(s: &mut String, r: &BenchRealReport, pick: fn(&MethodScores) -> f64) {
    let Some(first) = r.runs.first() else {
        let _ = writeln!(s, "(no set ran)\n");
        return;
    };
    let labels: Vec<String> = first.methods.iter().map(short_label).collect();
    let _ = writeln!(s, "| set | camera | {} |", labels.join(" | "));
    let _ = writeln!(s, "|---|---|{}", "---|".repeat(labels.len()));
    let cell = |methods: &[MethodScores], m: &MethodScores| {
        methods
            .iter()
            .find(|x| x.label() == m.label())
            .map(|x| format!("{:.3}", pick(x)))
            .unwrap_or_else(|| "–".into())
    };
    for cam in &r.cameras {
        let runs: Vec<&SetRun> = r.runs.iter().filter(|x| &x.camera == cam).collect();
        for run in &runs {
            let cells: Vec<String> = first
                .methods
                .iter()
                .map(|m| cell(&run.methods, m))
                .collect();
            let _ = writeln!(s, "| {} | {} | {} |", run.set, cam, cells.join(" | "));
        }
        let sums: Vec<MethodScores> = r
            .summary
            .iter()
            .filter(|x| &x.camera == cam)
            .map(|x| x.scores.clone())
            .collect();
        let cells: Vec<String> = first.methods.iter().map(|m| cell(&sums, m)).collect();
        let _ = writeln!(
            s,
            "| **mean of {} sets** | {} | {} |",
            runs.len(),
            cam,
            cells.join(" | ")
        );
        let pooled: Vec<MethodScores> = r
            .summary
            .iter()
            .filter(|x| &x.camera == cam)
            .map(|x| x.pooled.clone())
            .collect();
        let cells: Vec<String> = first.methods.iter().map(|m| cell(&pooled, m)).collect();
        let pixels: u64 = runs.iter().map(|x| x.pixels).sum();
        let _ = writeln!(
            s,
            "| **all {pixels} known pixels** | {cam} | {} |",
            cells.join(" | ")
        );
    }
    s.push('\n');
}

/// The EPE by ground-truth speed over all known pixels of each camera's sets: a row per method,
/// MPI-Sintel's three classes per camera.
fn speed_table(s: &mut String, r: &BenchRealReport) {
    let Some(first) = r.runs.first() else {
        return;
    };
    let _ = writeln!(
        s,
        "## EPE by ground-truth speed (px), all known pixels\n\nMPI-Sintel's classes: pixels \
         whose true motion is below 10 px ({}), 10 to 40 px ({}), 40 px or more ({}); – where \
         no pixel moves so.\n",
        SPEED_CLASS_NAMES[0], SPEED_CLASS_NAMES[1], SPEED_CLASS_NAMES[2]
    );
    let pooled = |cam: &String, m: &MethodScores| {
        r.summary
            .iter()
            .find(|x| &x.camera == cam && x.pooled.label() == m.label())
            .map(|x| x.pooled.by_speed)
    };
    let mut head = String::from("| method |");
    for cam in &r.cameras {
        let pixels = first
            .methods
            .first()
            .and_then(|m| pooled(cam, m))
            .unwrap_or_default()
            .pixels;
        for (name, n) in SPEED_CLASS_NAMES.iter().zip(pixels) {
            let _ = write!(head, " {cam} {name} ({n} px) |");
        }
    }
    let _ = writeln!(s, "{head}\n|---|{}", "---|".repeat(3 * r.cameras.len()));
    for m in &first.methods {
        let mut row = format!("| {} |", short_label(m));
        for cam in &r.cameras {
            let b: EpeBySpeed = pooled(cam, m).unwrap_or_default();
            for c in 0..3 {
                let cell = b.get(c).map_or_else(|| "–".into(), |v| format!("{v:.3}"));
                let _ = write!(row, " {cell} |");
            }
        }
        let _ = writeln!(s, "{row}");
    }
    s.push('\n');
}

/// "4 it" for MMS rows, the peer's name without "OpenCV ".
fn short_label(m: &MethodScores) -> String {
    match m.iters {
        Some(n) => format!("{} {n} it", m.method),
        None => m.method.trim_start_matches("OpenCV ").to_string(),
    }
}

fn method_table(s: &mut String, methods: &[MethodScores], with_ae: bool) {
    if with_ae {
        let _ = writeln!(
            s,
            "| method | EPE | AE (°) | 1 px | 3 px | 5 px | ms per pair |\n|---|---|---|---|---|---|---|"
        );
    } else {
        let _ = writeln!(
            s,
            "| method | EPE | 1 px | 3 px | 5 px | ms |\n|---|---|---|---|---|---|"
        );
    }
    for m in methods {
        let ae = if with_ae {
            format!(" {:.2} |", m.ae_deg)
        } else {
            String::new()
        };
        let _ = writeln!(
            s,
            "| {} | {:.3} |{ae} {:.3} | {:.3} | {:.3} | {} |",
            m.label(),
            m.epe,
            m.px1,
            m.px3,
            m.px5,
            ms(m.ms_per_pair)
        );
    }
    s.push('\n');
}

/// Milliseconds: one decimal below 10 ms, none above.
fn ms(v: f64) -> String {
    if v < 10.0 {
        format!("{v:.1}")
    } else {
        format!("{v:.0}")
    }
}
