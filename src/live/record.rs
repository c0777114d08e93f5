//! `--record DIR` and `--replay DIR`. A recording is `frames/NNNNNN.jpg` (each written
//! atomically), `frames.jsonl` (one complete line per frame, written after its JPEG: seq,
//! file, camera and arrival time) and `processed.jsonl` (the seq of every frame the live
//! pipeline took), so a replay processes exactly the frames the live run did, with the same
//! time stamps, and gives the same tracks.

use std::collections::BTreeSet;
use std::fs::{File, OpenOptions};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::jpeg::{Bad, decode_frame};
use super::reader::Frame;
use crate::error::{Error, Result};
use crate::io::write_bytes_atomic;

/// One line of `frames.jsonl`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RecordedFrame {
    pub seq: u64,
    /// Relative to the recording folder.
    pub file: String,
    pub camera_s: Option<f64>,
    pub received_s: f64,
}

/// One line of `processed.jsonl`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Processed {
    pub seq: u64,
}

/// Appends complete lines to a file (one `write` per line).
pub struct Lines {
    file: File,
    path: PathBuf,
}

impl Lines {
    pub fn create(path: &Path) -> Result<Self> {
        let file = OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)
            .map_err(|e| Error::io(path, e))?;
        Ok(Self {
            file,
            path: path.to_path_buf(),
        })
    }

    pub fn push<T: Serialize>(&mut self, value: &T) -> Result<()> {
        let mut line =
            serde_json::to_string(value).map_err(|e| Error::invalid("JSON line", e.to_string()))?;
        line.push('\n');
        self.file
            .write_all(line.as_bytes())
            .map_err(|e| Error::io(&self.path, e))
    }
}

/// The writer of a recording.
pub struct Recorder {
    dir: PathBuf,
    frames: Lines,
}

impl Recorder {
    /// Starts a recording in `dir` (created); a folder that already holds one is refused.
    pub fn create(dir: &Path) -> Result<Self> {
        let index = dir.join("frames.jsonl");
        if index.exists() {
            return Err(Error::invalid(
                "--record",
                format!("{} already holds a recording", dir.display()),
            ));
        }
        std::fs::create_dir_all(dir.join("frames")).map_err(|e| Error::io(dir, e))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            frames: Lines::create(&index)?,
        })
    }

    /// Saves one frame: its JPEG first, then its line.
    pub fn save(&mut self, f: &Frame) -> Result<()> {
        let file = format!("frames/{:06}.jpg", f.seq);
        write_bytes_atomic(&self.dir.join(&file), &f.jpeg)?;
        self.frames.push(&RecordedFrame {
            seq: f.seq,
            file,
            camera_s: f.camera_s,
            received_s: f.received_s,
        })
    }

    /// The writer of `processed.jsonl` (used by the pipeline's thread).
    pub fn processed(dir: &Path) -> Result<Lines> {
        Lines::create(&dir.join("processed.jsonl"))
    }
}

/// A recording opened for replay.
pub struct Replay {
    dir: PathBuf,
    pub frames: Vec<RecordedFrame>,
}

impl Replay {
    /// Reads `frames.jsonl`; with `all` false and a `processed.jsonl` present, keeps only the
    /// frames the live run processed.
    pub fn open(dir: &Path, all: bool) -> Result<Self> {
        let index = dir.join("frames.jsonl");
        let mut frames: Vec<RecordedFrame> = read_lines(&index)?;
        let processed = dir.join("processed.jsonl");
        if !all && processed.exists() {
            let keep: BTreeSet<u64> = read_lines::<Processed>(&processed)?
                .into_iter()
                .map(|p| p.seq)
                .collect();
            frames.retain(|f| keep.contains(&f.seq));
        }
        for f in &frames {
            let p = Path::new(&f.file);
            if p.is_absolute()
                || p.components()
                    .any(|c| matches!(c, std::path::Component::ParentDir))
            {
                return Err(Error::format(
                    &index,
                    format!("file {:?} leaves the recording", f.file),
                ));
            }
        }
        if frames.is_empty() {
            return Err(Error::format(&index, "no frames to replay"));
        }
        Ok(Self {
            dir: dir.to_path_buf(),
            frames,
        })
    }

    /// A folder of images (any format the image reader knows, in name order) as a recording
    /// taken at `fps`: frame k has the time stamp k / fps.
    pub fn from_images(dir: &Path, fps: f64) -> Result<Self> {
        if !(fps.is_finite() && fps > 0.0 && fps <= 1000.0) {
            return Err(Error::invalid(
                "--fps",
                format!("must be in (0, 1000], got {fps}"),
            ));
        }
        let files = crate::io::frame_files(dir)?;
        let frames = files
            .iter()
            .enumerate()
            .filter_map(|(k, p)| {
                let name = p.file_name()?.to_str()?.to_string();
                let t = k as f64 / fps;
                Some(RecordedFrame {
                    seq: k as u64,
                    file: name,
                    camera_s: Some(t),
                    received_s: t,
                })
            })
            .collect();
        Ok(Self {
            dir: dir.to_path_buf(),
            frames,
        })
    }

    /// Reads and decodes one recorded frame (a bad JPEG is the caller's to count and skip).
    pub fn load(&self, r: &RecordedFrame) -> Result<std::result::Result<Frame, Bad>> {
        let path = self.dir.join(&r.file);
        let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
        let jpeg = bytes.starts_with(&[0xFF, 0xD8]);
        let image = if jpeg {
            decode_frame(&bytes)
        } else {
            crate::io::decode_image(&bytes, &path).map_err(|e| Bad::Corrupt(e.to_string()))
        };
        Ok(image.map(|image| Frame {
            seq: r.seq,
            jpeg: Arc::new(bytes),
            image: Arc::new(image),
            camera_s: r.camera_s,
            received_s: r.received_s,
            arrived: Instant::now(),
        }))
    }
}

/// Every line of a JSON-lines file; a bad line is an error naming its number.
fn read_lines<T: for<'de> Deserialize<'de>>(path: &Path) -> Result<Vec<T>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            serde_json::from_str(l).map_err(|e| Error::format(path, format!("line {}: {e}", i + 1)))
        })
        .collect()
}
