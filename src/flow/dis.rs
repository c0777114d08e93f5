//! The peer flow of a frame sequence: OpenCV's DIS (medium preset, one thread) between each
//! consecutive pair, by `scripts/dis_flows.py`, compiled into the binary and piped to Python as
//! the real-data benchmark runs its baselines. The frames travel as 8-bit PNGs (what a camera
//! writes and what the script would read from a clip folder) and the flows come back as .flo.

use std::ffi::OsStr;
use std::time::Instant;

use crate::error::{Error, Result};
use crate::io::{BitDepth, read_flo, write_image};
use crate::types::{Flow, Image};

/// DIS's presets, fastest last.
pub const PRESETS: [&str; 3] = ["medium", "fast", "ultrafast"];

/// The script, as shipped with this build (piped to `python3 -`).
pub const SCRIPT: &str = include_str!("../../scripts/dis_flows.py");

/// DIS's flow (`preset`: `medium`, `fast` or `ultrafast`) from each frame to the next
/// (`frames.len() − 1` flows) and DIS's own time per pair in ms (reading and writing the
/// frames and flows excluded, as the network's time excludes them). `python` must import OpenCV and numpy; the error says so when it cannot.
pub fn sequence_flows(python: &str, frames: &[Image], preset: &str) -> Result<(Vec<Flow>, f64)> {
    if frames.len() < 2 {
        return Err(Error::invalid("frames", "DIS needs at least two frames"));
    }
    if !PRESETS.contains(&preset) {
        return Err(Error::invalid(
            "DIS preset",
            format!("expected one of {PRESETS:?}, got {preset:?}"),
        ));
    }
    let dir = ScratchDir::new()?;
    let (frame_dir, flow_dir) = (dir.0.join("frames"), dir.0.join("flows"));
    std::fs::create_dir(&frame_dir).map_err(|e| Error::io(&frame_dir, e))?;
    for (n, f) in frames.iter().enumerate() {
        write_image(&frame_dir.join(format!("{n:05}.png")), f, BitDepth::Eight)?;
    }
    let started = Instant::now();
    let out = crate::io::python::run_piped(
        python,
        SCRIPT,
        "scripts/dis_flows.py",
        "dis",
        [
            OsStr::new("--frames"),
            frame_dir.as_os_str(),
            OsStr::new("--out"),
            flow_dir.as_os_str(),
            OsStr::new("--preset"),
            OsStr::new(preset),
        ],
    )?;
    let wall = started.elapsed().as_secs_f64() * 1e3 / (frames.len() - 1) as f64;
    let ms = String::from_utf8_lossy(&out.stdout)
        .split("DIS ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|t| t.parse::<f64>().ok())
        .unwrap_or(wall);
    let flows = (0..frames.len() - 1)
        .map(|n| read_flo(&flow_dir.join(format!("{n:05}.flo"))))
        .collect::<Result<Vec<_>>>()?;
    Ok((flows, ms))
}

/// A folder of its own under the system's temporary directory, removed when dropped (on
/// success and on error alike).
struct ScratchDir(std::path::PathBuf);

impl ScratchDir {
    fn new() -> Result<Self> {
        static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("pins-dis-{}-{n}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
        Ok(Self(dir))
    }
}

impl Drop for ScratchDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured frame shifted by whole pixels: DIS finds the shift (where Python has
    /// OpenCV; elsewhere the test says so and checks only the error's wording).
    #[test]
    fn dis_finds_a_whole_pixel_shift() {
        let (w, h) = (96, 64);
        let tex = |x: usize, y: usize| {
            let (x, y) = (x as f32, y as f32);
            0.5 + 0.2 * (x * 0.31).sin() * (y * 0.23).cos() + 0.15 * ((x + 2.0 * y) * 0.11).sin()
        };
        let frame = |dx: usize| {
            let mut img = Image::zeros(3, h, w);
            for c in 0..3 {
                for y in 0..h {
                    for x in 0..w {
                        img.set(c, y, x, tex(x + 10 - dx, y));
                    }
                }
            }
            img
        };
        let frames = [frame(0), frame(3)];
        match sequence_flows("python3", &frames, "medium") {
            Ok((flows, ms)) => {
                // DIS's own time, parsed from the script's last line.
                assert!(ms > 0.0 && ms.is_finite(), "{ms} ms");
                assert_eq!(flows.len(), 1);
                let f = &flows[0];
                // The mean u over the inner frame (away from the uncovered border) is +3 px.
                let (mut su, mut sv, mut n) = (0.0, 0.0, 0.0);
                for y in 8..h - 8 {
                    for x in 8..w - 8 {
                        let (u, v) = f.get(y, x);
                        su += u as f64;
                        sv += v as f64;
                        n += 1.0;
                    }
                }
                assert!((su / n - 3.0).abs() < 0.3, "mean u {}", su / n);
                assert!((sv / n).abs() < 0.3, "mean v {}", sv / n);
            }
            Err(e) => {
                let msg = e.to_string();
                eprintln!("DIS not checked: {msg}");
                assert!(msg.contains("dis"), "{msg}");
            }
        }
        assert!(sequence_flows("python3", &frames[..1], "medium").is_err());
        let preset = sequence_flows("python3", &frames, "slow")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(preset.contains("slow"), "{preset}");
    }
}
