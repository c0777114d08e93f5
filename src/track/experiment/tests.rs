//! The tracking experiments' tests: configs, clips and the table.

use super::*;

const SCENE: &str = r#"{"scene": {"width": 64, "height": 48, "frames": 4, "seed": 7,
    "objects": [{"path": "sinusoid", "radius": 6}]}}"#;

fn load(dir: &Path, clips: &str) -> Result<ExperimentConfig> {
    std::fs::write(dir.join("clip.json"), SCENE).unwrap();
    let path = dir.join("experiment.json");
    std::fs::write(
        &path,
        format!(r#"{{"clips": {clips}, "predictors": [{{"name": "poly"}}], "horizons": [1]}}"#),
    )
    .unwrap();
    ExperimentConfig::from_file(&path)
}

#[test]
fn clips_come_from_files_or_inline_once_per_seed() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = load(
        dir.path(),
        &format!(
            r#"[{{"name": "file", "config": "clip.json"}},
                {{"name": "seeded", "config": "clip.json", "seeds": [3, 4]}},
                {{"name": "inline", "clip": {SCENE}, "seeds": [9]}}]"#
        ),
    )
    .unwrap();
    let runs: Vec<(&str, u64)> = cfg
        .clips
        .iter()
        .map(|c| (c.name.as_str(), c.loaded.scene.seed))
        .collect();
    assert_eq!(
        runs,
        [
            ("file", 7),
            ("seeded_seed3", 3),
            ("seeded_seed4", 4),
            ("inline_seed9", 9)
        ]
    );
    // Apart from the seed, a seeded run is the clip itself.
    let mut c = cfg.clips[1].loaded.clone();
    c.scene.seed = 7;
    assert_eq!(c, cfg.clips[0].loaded);
}

#[test]
fn clip_specs_that_say_too_little_or_repeat_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let err = |clips: &str| load(dir.path(), clips).unwrap_err().to_string();
    assert!(err(r#"[{"name": "a"}]"#).contains("needs either"));
    let both = format!(r#"[{{"name": "a", "config": "clip.json", "clip": {SCENE}}}]"#);
    assert!(err(&both).contains("needs either"));
    assert!(err(r#"[{"name": "a", "config": "clip.json", "seeds": [1, 1]}]"#).contains("seed 1"));
    let twice = r#"[{"name": "a", "config": "clip.json"}, {"name": "a", "config": "clip.json"}]"#;
    assert!(err(twice).contains("two clips are named"));
    let missing = err(r#"[{"name": "a", "config": "nowhere.json"}]"#);
    assert!(missing.contains("nowhere.json"), "{missing}");
}
