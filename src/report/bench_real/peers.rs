//! The peer methods (OpenCV DIS medium/fast/ultrafast, Farneback, zero flow) of the real-data
//! benchmark: `scripts/flow_baselines.py`, compiled into the binary and run by Python as a
//! subprocess on a generated dataset folder; its JSON is read back with per-pair scores.

use std::path::Path;
use std::process::{Command, Stdio};

use serde::Deserialize;

use crate::error::{Error, Result};

/// The script, as shipped with this build (piped to `python3 -`, so no path is needed).
pub const SCRIPT: &str = include_str!("../../../scripts/flow_baselines.py");

/// `python/requirements-peers.txt`: the OpenCV the reports of `experiments/results/` were
/// measured with.
pub const REQUIREMENTS: &str = include_str!("../../../python/requirements-peers.txt");

/// Where [`REQUIREMENTS`] lies in the repository, for messages.
pub const REQUIREMENTS_PATH: &str = "python/requirements-peers.txt";

/// The OpenCV version [`REQUIREMENTS`] pins, as `cv2.__version__` reports it: the wheel's
/// version without its build number (`opencv-python-headless==5.0.0.93` → `5.0.0`).
pub fn pinned_opencv() -> Option<String> {
    REQUIREMENTS.lines().find_map(|l| {
        let v = l.trim().strip_prefix("opencv-python-headless==")?;
        Some(v.split('.').take(3).collect::<Vec<_>>().join("."))
    })
}

/// A warning when `found` (`cv2.__version__`) is not the pinned version: DIS's numbers move with
/// OpenCV's version, so peers compare across reports only at one version.
pub fn version_warning(found: &str) -> Option<String> {
    let pinned = pinned_opencv()?;
    (found.trim() != pinned).then(|| {
        format!(
            "the peers ran on OpenCV {found}, not the {pinned} of {REQUIREMENTS_PATH}; DIS's \
             numbers move with OpenCV's version, so compare them only with reports made on \
             OpenCV {found}"
        )
    })
}

/// One pair of one method.
#[derive(Clone, Debug, Deserialize)]
pub struct PeerPair {
    pub name: String,
    pub pixels: u64,
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    pub ms: f64,
    /// Absent from the JSON of scripts older than the speed classes.
    #[serde(default)]
    pub by_speed: crate::flow::metrics::EpeBySpeed,
}

/// One method over a dataset, with its pairs.
#[derive(Clone, Debug, Deserialize)]
pub struct PeerMethod {
    pub name: String,
    pub epe: f64,
    pub ae_deg: f64,
    pub px1: f64,
    pub px3: f64,
    pub px5: f64,
    pub ms_per_pair: f64,
    #[serde(default)]
    pub by_speed: crate::flow::metrics::EpeBySpeed,
    pub per_pair: Vec<PeerPair>,
}

/// The script's JSON.
#[derive(Clone, Debug, Deserialize)]
pub struct PeersFile {
    pub pairs: usize,
    pub opencv: String,
    pub threads: i64,
    pub methods: Vec<PeerMethod>,
    pub zero_flow: PeerMethod,
}

/// Whether `python` can import OpenCV and numpy: `Ok(version)` of OpenCV, or `Err(why not)`,
/// in words for the report.
pub fn available(python: &str) -> std::result::Result<String, String> {
    let out = Command::new(python)
        .args(["-c", "import numpy, cv2; print(cv2.__version__)"])
        .stdin(Stdio::null())
        .output()
        .map_err(|e| format!("{python} could not be started ({e})"))?;
    if out.status.success() {
        Ok(String::from_utf8_lossy(&out.stdout).trim().to_string())
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let last = err.lines().last().unwrap_or("").trim();
        Err(format!(
            "`{python} -c \"import numpy, cv2\"` failed ({last}); \
             install them with `{python} -m pip install -r {REQUIREMENTS_PATH}`"
        ))
    }
}

/// Runs the baselines on `data` with `threads` OpenCV threads, writing their JSON to `json`,
/// and reads it back. A failure of the script is an error carrying its message.
pub fn run(python: &str, data: &Path, json: &Path, threads: usize) -> Result<PeersFile> {
    let threads = threads.to_string();
    let args: [&std::ffi::OsStr; 6] = [
        "--data".as_ref(),
        data.as_os_str(),
        "--out".as_ref(),
        json.as_os_str(),
        "--threads".as_ref(),
        threads.as_ref(),
    ];
    crate::io::python::run_piped(
        python,
        SCRIPT,
        &format!("scripts/flow_baselines.py on {}", data.display()),
        "peers",
        args,
    )?;
    read(json)
}

/// Reads the script's JSON and checks that every method covers the same pairs.
pub fn read(json: &Path) -> Result<PeersFile> {
    let text = std::fs::read_to_string(json).map_err(|e| Error::io(json, e))?;
    let f: PeersFile =
        serde_json::from_str(&text).map_err(|e| Error::format(json, e.to_string()))?;
    for m in f.methods.iter().chain([&f.zero_flow]) {
        if m.per_pair.len() != f.pairs {
            return Err(Error::format(
                json,
                format!(
                    "{}: {} per-pair rows for {} pairs",
                    m.name,
                    m.per_pair.len(),
                    f.pairs
                ),
            ));
        }
    }
    Ok(f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pinned_opencv_is_read_without_its_build_number() {
        let pinned = pinned_opencv().expect("requirements-peers.txt pins opencv-python-headless");
        assert_eq!(pinned.split('.').count(), 3, "{pinned}");
        assert!(REQUIREMENTS.contains(&format!("opencv-python-headless=={pinned}.")));
        assert_eq!(version_warning(&pinned), None);
        assert_eq!(version_warning(&format!("{pinned}\n")), None);
    }

    #[test]
    fn another_opencv_is_warned_about_by_both_versions() {
        let pinned = pinned_opencv().expect("pinned");
        let w = version_warning("4.14.0").expect("4.14.0 is not the pinned version");
        assert!(
            w.contains("4.14.0") && w.contains(&pinned) && w.contains(REQUIREMENTS_PATH),
            "{w}"
        );
    }

    #[test]
    fn the_script_is_compiled_in_and_a_missing_python_is_explained() {
        assert!(SCRIPT.contains("def zero_flow"));
        let why = available("/nonexistent/python3").unwrap_err();
        assert!(why.contains("could not be started"), "{why}");
    }
}
