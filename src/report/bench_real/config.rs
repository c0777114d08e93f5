//! The real-data benchmark's config: which sets (each a scene of the generator: a dataset folder,
//! a procedural scene, or a whole `pins generate` config file), through which cameras, with which
//! weights and iteration counts. Relative paths are relative to the config file.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::dataset::{GeneratorConfig, SceneSpec};
use crate::error::{Error, Result};
use crate::imaging::CameraConfig;

/// `experiments/bench_real.json`. Unknown keys are rejected.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BenchRealConfig {
    /// Weights file, or "default" for the shipped ones.
    #[serde(default = "default_weights")]
    pub weights: String,
    /// MMS iteration counts.
    #[serde(default = "default_iters")]
    pub iters: Vec<usize>,
    /// Camera variants; every set is passed through each.
    #[serde(default = "default_cameras")]
    pub cameras: Vec<CameraSpec>,
    /// OpenCV threads of the peer methods.
    #[serde(default = "one")]
    pub peer_threads: usize,
    pub sets: Vec<SetSpec>,
}

/// A named camera: `"ideal"` (no dimming, blur, noise or gamma: the clean pairs), `"default"`
/// (the paper's metalens camera) or a camera config object as in `pins generate`.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    pub name: String,
    pub camera: serde_json::Value,
}

/// One set: `scene` inline (a dataset folder: `{"kind": "dataset", "path": ..., "layout": ...}`,
/// or a procedural scene with `count`), or `generate`: a `pins generate` config file whose
/// camera is replaced by each of the benchmark's. `count` and `seed` override the scene's.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetSpec {
    pub name: String,
    #[serde(default)]
    pub scene: Option<SceneSpec>,
    #[serde(default)]
    pub generate: Option<PathBuf>,
    #[serde(default)]
    pub count: Option<usize>,
    #[serde(default)]
    pub seed: Option<u64>,
}

/// A set ready to generate: its name and generator config (camera still to be set), or why it
/// is skipped.
#[derive(Clone, Debug)]
pub struct ResolvedSet {
    pub name: String,
    pub generator: GeneratorConfig,
    /// Set when the set's data folder is missing: the set is reported and skipped.
    pub missing: Option<String>,
}

/// A resolved camera variant.
#[derive(Clone, Debug)]
pub struct ResolvedCamera {
    pub name: String,
    pub camera: CameraConfig,
}

/// Everything the benchmark runs, checked.
#[derive(Clone, Debug)]
pub struct BenchPlan {
    pub weights: String,
    pub iters: Vec<usize>,
    pub cameras: Vec<ResolvedCamera>,
    pub sets: Vec<ResolvedSet>,
    pub peer_threads: usize,
}

/// Dataset scenes take every pair of their folder unless `count` says fewer.
const ALL_PAIRS: usize = 10_000_000;

fn default_weights() -> String {
    "default".into()
}
fn default_iters() -> Vec<usize> {
    vec![4, 8, 12, 16]
}
fn one() -> usize {
    1
}
fn default_cameras() -> Vec<CameraSpec> {
    vec![
        CameraSpec {
            name: "clean".into(),
            camera: "ideal".into(),
        },
        CameraSpec {
            name: "camera".into(),
            camera: "default".into(),
        },
    ]
}

/// Reads and checks the config at `path`; the error names the file and the offending value.
pub fn load(path: &Path) -> Result<BenchPlan> {
    let cfg: BenchRealConfig = crate::io::read_json(path)?;
    let base = path.parent().unwrap_or(Path::new(""));
    cfg.resolve(base).map_err(|e| crate::io::in_config(path, e))
}

impl BenchRealConfig {
    /// Resolves paths against `base` and checks every value.
    pub fn resolve(&self, base: &Path) -> Result<BenchPlan> {
        check_iters(&self.iters)?;
        if self.peer_threads > 256 {
            return Err(Error::invalid(
                "peer_threads",
                format!("must be 0..=256, got {}", self.peer_threads),
            ));
        }
        if self.cameras.is_empty() {
            return Err(Error::invalid("cameras", "empty list"));
        }
        if self.sets.is_empty() {
            return Err(Error::invalid("sets", "empty list"));
        }
        check_names("cameras", self.cameras.iter().map(|c| c.name.as_str()))?;
        check_names("sets", self.sets.iter().map(|s| s.name.as_str()))?;
        let cameras = self
            .cameras
            .iter()
            .map(|c| resolve_camera(c, base))
            .collect::<Result<_>>()?;
        let sets = self
            .sets
            .iter()
            .map(|s| resolve_set(s, base))
            .collect::<Result<_>>()?;
        let weights = if crate::flow::infer::is_builtin(&self.weights)
            || Path::new(&self.weights).is_absolute()
        {
            self.weights.clone()
        } else {
            base.join(&self.weights).to_string_lossy().into_owned()
        };
        Ok(BenchPlan {
            weights,
            iters: self.iters.clone(),
            cameras,
            sets,
            peer_threads: self.peer_threads,
        })
    }
}

/// Iteration counts: a non-empty list of 1..=256 without repeats.
pub fn check_iters(iters: &[usize]) -> Result<()> {
    if iters.is_empty() {
        return Err(Error::invalid("iters", "empty list"));
    }
    if let Some(n) = iters.iter().find(|&&n| n == 0 || n > 256) {
        return Err(Error::invalid(
            "iters",
            format!("each must be 1..=256, got {n}"),
        ));
    }
    let mut sorted = iters.to_vec();
    sorted.sort_unstable();
    sorted.dedup();
    if sorted.len() != iters.len() {
        return Err(Error::invalid(
            "iters",
            format!("repeated count in {iters:?}"),
        ));
    }
    Ok(())
}

/// Names become folder names and table labels: unique, 1–64 of `[A-Za-z0-9_.-]`, not starting
/// with a dot.
fn check_names<'a>(what: &str, names: impl Iterator<Item = &'a str>) -> Result<()> {
    let mut seen = std::collections::BTreeSet::new();
    for n in names {
        let ok = !n.is_empty()
            && n.len() <= 64
            && !n.starts_with('.')
            && n.chars()
                .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'));
        if !ok {
            return Err(Error::invalid(
                format!("{what}[].name"),
                format!(
                    "{n:?}: use 1 to 64 letters, digits, '_', '-' or '.', not starting with '.'"
                ),
            ));
        }
        if !seen.insert(n) {
            return Err(Error::invalid(
                format!("{what}[].name"),
                format!("{n:?} appears twice"),
            ));
        }
    }
    Ok(())
}

fn resolve_camera(c: &CameraSpec, base: &Path) -> Result<ResolvedCamera> {
    let what = format!("cameras[{}].camera", c.name);
    let mut camera = match &c.camera {
        serde_json::Value::String(s) if s == "ideal" => CameraConfig::ideal(),
        serde_json::Value::String(s) if s == "default" => CameraConfig::default(),
        serde_json::Value::Object(_) => serde_json::from_value(c.camera.clone())
            .map_err(|e| Error::invalid(what.clone(), e.to_string()))?,
        other => {
            return Err(Error::invalid(
                what,
                format!("expected \"ideal\", \"default\" or a camera object, got {other}"),
            ));
        }
    };
    camera.resolve_paths(base);
    camera
        .validate()
        .map_err(|e| Error::invalid(what, e.to_string()))?;
    Ok(ResolvedCamera {
        name: c.name.clone(),
        camera,
    })
}

fn resolve_set(s: &SetSpec, base: &Path) -> Result<ResolvedSet> {
    let what = format!("sets[{}]", s.name);
    let mut generator = match (&s.scene, &s.generate) {
        (Some(scene), None) => {
            let mut scene = scene.clone();
            if let SceneSpec::Dataset { path, .. } = &mut scene
                && path.is_relative()
            {
                *path = base.join(&*path);
            }
            let count = match (&scene, s.count) {
                (_, Some(n)) => n,
                (SceneSpec::Dataset { .. }, None) => ALL_PAIRS,
                (_, None) => {
                    return Err(Error::invalid(
                        what,
                        "a generated scene needs \"count\" (the number of pairs)",
                    ));
                }
            };
            GeneratorConfig {
                count,
                scene,
                ..GeneratorConfig::default()
            }
        }
        (None, Some(file)) => {
            let file = if file.is_relative() {
                base.join(file)
            } else {
                file.clone()
            };
            GeneratorConfig::from_file(&file)?
        }
        _ => {
            return Err(Error::invalid(
                what,
                "give exactly one of \"scene\" (inline) and \"generate\" (a pins generate config file)",
            ));
        }
    };
    if let Some(n) = s.count {
        generator.count = n;
    }
    if let Some(seed) = s.seed {
        generator.seed = seed;
    }
    generator.save_clean = false;
    let missing = match &generator.scene {
        SceneSpec::Dataset { path, .. } if !path.is_dir() => {
            Some(format!("its data folder {} does not exist", path.display()))
        }
        _ => None,
    };
    if missing.is_none() {
        generator
            .validate()
            .map_err(|e| Error::invalid(what, e.to_string()))?;
    }
    Ok(ResolvedSet {
        name: s.name.clone(),
        generator,
        missing,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(json: &str) -> Result<BenchPlan> {
        let cfg: BenchRealConfig =
            serde_json::from_str(json).map_err(|e| Error::invalid("json", e.to_string()))?;
        cfg.resolve(Path::new("/base"))
    }

    #[test]
    fn defaults_and_paths() {
        let p = plan(r#"{"sets": [{"name": "a", "scene": {"kind": "dataset", "path": "rel"}},
                                   {"name": "b", "scene": {"kind": "chairs", "width": 64, "height": 48}, "count": 2, "seed": 7}]}"#)
            .unwrap();
        assert_eq!(p.iters, [4, 8, 12, 16]);
        assert_eq!(p.weights, "default");
        assert_eq!(
            p.cameras
                .iter()
                .map(|c| c.name.as_str())
                .collect::<Vec<_>>(),
            ["clean", "camera"]
        );
        assert_eq!(p.cameras[0].camera, CameraConfig::ideal());
        assert_eq!(p.cameras[1].camera, CameraConfig::default());
        assert!(
            matches!(&p.sets[0].generator.scene, SceneSpec::Dataset { path, .. } if path == Path::new("/base/rel"))
        );
        assert!(p.sets[0].missing.is_some());
        assert_eq!(p.sets[0].generator.count, ALL_PAIRS);
        assert_eq!(
            (p.sets[1].generator.count, p.sets[1].generator.seed),
            (2, 7)
        );
        assert!(p.sets[1].missing.is_none());
    }

    #[test]
    fn bad_values_are_named() {
        for (json, needle) in [
            (r#"{"sets": []}"#, "sets"),
            (
                r#"{"sets": [{"name": "a", "scene": {"kind": "chairs"}}]}"#,
                "count",
            ),
            (r#"{"sets": [{"name": "a"}]}"#, "exactly one"),
            (
                r#"{"sets": [{"name": "a/b", "scene": {"kind": "dataset", "path": "x"}}]}"#,
                "letters",
            ),
            (
                r#"{"sets": [{"name": "a", "scene": {"kind": "dataset", "path": "x"}},
                             {"name": "a", "scene": {"kind": "dataset", "path": "y"}}]}"#,
                "twice",
            ),
            (
                r#"{"iters": [0], "sets": [{"name": "a", "scene": {"kind": "dataset", "path": "x"}}]}"#,
                "iters",
            ),
            (
                r#"{"iters": [4, 4], "sets": [{"name": "a", "scene": {"kind": "dataset", "path": "x"}}]}"#,
                "repeated",
            ),
            (
                r#"{"cameras": [{"name": "c", "camera": "fancy"}], "sets": [{"name": "a", "scene": {"kind": "dataset", "path": "x"}}]}"#,
                "ideal",
            ),
            (
                r#"{"cameras": [{"name": "c", "camera": {"gama": 2}}], "sets": [{"name": "a", "scene": {"kind": "dataset", "path": "x"}}]}"#,
                "gama",
            ),
        ] {
            let e = plan(json).unwrap_err().to_string();
            assert!(e.contains(needle), "{json}: {e}");
        }
        let e = serde_json::from_str::<BenchRealConfig>(r#"{"sets": [], "set": 1}"#).unwrap_err();
        assert!(e.to_string().contains("set"), "{e}");
    }
}
