//! `pins generate --verify`: checks a dataset folder against its own records without writing
//! anything: every sample's sidecar, the size and SHA-256 of every file it lists, and the manifest.

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::config::{GeneratorConfig, SceneSpec};
use super::folder::read_claim;
use super::generate::sample_seed;
use super::integrity::{Depth, SampleProblem, check_sample};
use super::manifest::{Manifest, SampleMeta};
use crate::error::{Error, Result};
use crate::io;

/// What a verification found.
#[derive(Clone, Debug)]
pub struct VerifyReport {
    pub dir: PathBuf,
    /// Samples the dataset holds when complete.
    pub total: usize,
    /// Samples whose every file matches its record.
    pub good: usize,
    /// Files checked and their bytes, over the good samples.
    pub files: usize,
    pub bytes: u64,
    /// The bad samples, in index order.
    pub problems: Vec<SampleProblem>,
    pub manifest: ManifestCheck,
    /// Temporary files present (an interrupted run's, or those of a run under way).
    pub temporaries: usize,
}

/// What was found of `manifest.json`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ManifestCheck {
    /// Not written yet (it is written once every sample is complete).
    Absent,
    Agrees,
    /// Present but wrong: why.
    Wrong(String),
}

impl VerifyReport {
    /// True when every sample is good and the manifest, if any, agrees.
    pub fn is_ok(&self) -> bool {
        self.problems.is_empty() && !matches!(self.manifest, ManifestCheck::Wrong(_))
    }

    /// One line per bad sample (`00003: 00003_img1.png truncated (412 of 98123 bytes)`), then
    /// the manifest's problem if any.
    pub fn problem_lines(&self) -> Vec<String> {
        let mut lines: Vec<String> = self.problems.iter().map(|p| p.to_string()).collect();
        if let ManifestCheck::Wrong(why) = &self.manifest {
            lines.push(format!("manifest.json: {why}"));
        }
        lines
    }
}

/// Verifies the dataset in `dir`, made with the config in its `config.json`; with `expected`,
/// that config must also be `expected`. Reads only: no file is created, changed or removed.
pub fn verify(dir: &Path, expected: Option<&GeneratorConfig>) -> Result<VerifyReport> {
    if !dir.is_dir() {
        return Err(Error::invalid(
            "--out",
            format!("{} is not a folder", dir.display()),
        ));
    }
    let config = read_claim(dir)?;
    if let Some(e) = expected
        && *e != config
    {
        return Err(Error::invalid(
            "--verify",
            format!(
                "{} was made with another config than the one given by --config/--count/--seed \
                 (see its config.json)",
                dir.display()
            ),
        ));
    }
    let manifest_path = dir.join("manifest.json");
    let manifest = manifest_path
        .exists()
        .then(|| Manifest::read(&manifest_path));
    let total = expected_total(
        dir,
        &config,
        manifest.as_ref().and_then(|m| m.as_ref().ok()),
    )?;
    let checked: Vec<std::result::Result<SampleMeta, SampleProblem>> = (0..total)
        .into_par_iter()
        .map(|i| check_sample(dir, i, sample_seed(config.seed, i), Depth::Hashes))
        .collect();
    let (mut metas, mut problems) = (Vec::new(), Vec::new());
    for c in checked {
        match c {
            Ok(m) => metas.push(m),
            Err(p) => problems.push(p),
        }
    }
    let manifest = match manifest {
        None => ManifestCheck::Absent,
        Some(Err(e)) => ManifestCheck::Wrong(format!("does not parse ({e})")),
        Some(Ok(m)) => check_manifest(&m, &config, total, &metas),
    };
    let temporaries = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .flatten()
        .filter(|e| io::atomic::is_temp_name(&e.file_name().to_string_lossy()))
        .count();
    Ok(VerifyReport {
        dir: dir.to_path_buf(),
        total,
        good: metas.len(),
        files: metas.iter().map(|m| m.files.len()).sum(),
        bytes: metas.iter().flat_map(|m| &m.files).map(|f| f.bytes).sum(),
        problems,
        manifest,
        temporaries,
    })
}

/// The number of samples: the config's count, or for a dataset scene the pairs found (at most
/// the count), or, if its source is gone, what the manifest says.
fn expected_total(
    dir: &Path,
    config: &GeneratorConfig,
    manifest: Option<&Manifest>,
) -> Result<usize> {
    let SceneSpec::Dataset { path, layout } = &config.scene else {
        return Ok(config.count);
    };
    match crate::scene::readers::discover(path, *layout) {
        Ok(pairs) => Ok(config.count.min(pairs.len())),
        Err(e) => manifest.map(|m| m.count).ok_or_else(|| {
            Error::invalid(
                "--verify",
                format!(
                    "{}: cannot tell how many samples to expect: no manifest.json, and its \
                     source dataset cannot be read ({e})",
                    dir.display()
                ),
            )
        }),
    }
}

/// The manifest must hold this config, the right count, and the sidecars of the good samples
/// (the bad ones are reported on their own).
fn check_manifest(
    m: &Manifest,
    config: &GeneratorConfig,
    total: usize,
    metas: &[SampleMeta],
) -> ManifestCheck {
    if m.config != *config {
        return ManifestCheck::Wrong("holds another config than config.json".into());
    }
    if m.count != total || m.samples.len() != total {
        return ManifestCheck::Wrong(format!(
            "lists {} samples (count {}), expected {total}",
            m.samples.len(),
            m.count
        ));
    }
    let bad: Vec<String> = metas
        .iter()
        .filter(|meta| {
            !m.samples
                .get(meta.index)
                .is_some_and(|s| same_meta(s, meta))
        })
        .map(|meta| format!("{:05}", meta.index))
        .collect();
    if !bad.is_empty() {
        return ManifestCheck::Wrong(format!(
            "disagrees with the metadata of sample{} {}",
            if bad.len() > 1 { "s" } else { "" },
            abbreviate(&bad)
        ));
    }
    ManifestCheck::Agrees
}

/// Equal sidecars, up to the last bits of floating-point numbers: serde_json (without its
/// `float_roundtrip` feature) may read a printed `f64` back one unit in the last place off, and
/// the manifest holds the sidecars after one more such trip.
fn same_meta(a: &SampleMeta, b: &SampleMeta) -> bool {
    match (serde_json::to_value(a), serde_json::to_value(b)) {
        (Ok(a), Ok(b)) => same_json(&a, &b),
        _ => false,
    }
}

fn same_json(a: &serde_json::Value, b: &serde_json::Value) -> bool {
    use serde_json::Value;
    match (a, b) {
        (Value::Number(x), Value::Number(y)) if x.is_f64() || y.is_f64() => {
            match (x.as_f64(), y.as_f64()) {
                (Some(x), Some(y)) => {
                    x == y || (x - y).abs() <= 4.0 * f64::EPSILON * x.abs().max(y.abs())
                }
                _ => false,
            }
        }
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| same_json(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| same_json(v, w)))
        }
        _ => a == b,
    }
}

fn abbreviate(items: &[String]) -> String {
    const SHOWN: usize = 10;
    if items.len() <= SHOWN {
        items.join(", ")
    } else {
        format!(
            "{}, … ({} more)",
            items[..SHOWN].join(", "),
            items.len() - SHOWN
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_compares_floats_to_the_last_bits_only() {
        let v = |s: &str| serde_json::from_str::<serde_json::Value>(s).unwrap();
        let x = 0.983_085_159_250_726_9_f64;
        let next = f64::from_bits(x.to_bits() + 1);
        let (a, b) = (
            serde_json::json!({"a": [x, 1], "s": "0"}),
            serde_json::json!({"a": [next, 1], "s": "0"}),
        );
        assert!(same_json(&a, &b));
        assert!(!same_json(
            &a,
            &serde_json::json!({"a": [x * 1.000_001, 1], "s": "0"})
        ));
        assert!(!same_json(&a, &serde_json::json!({"a": [x, 2], "s": "0"})));
        assert!(!same_json(&a, &serde_json::json!({"a": [x, 1], "s": "1"})));
        assert!(!same_json(&v(r#"{"n": 1}"#), &v(r#"{"n": 1, "m": 2}"#)));
        assert!(!same_json(&v("12345678901234567"), &v("12345678901234568")));
    }
}
