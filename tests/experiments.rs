//! Every shipped experiment config parses, validates and names only known keys: training
//! configs (`train_*` with a model), tracking settings (`track_config_*`), tracking clips and
//! tracking experiments (`track_*`), the real-data benchmark (`bench_real*`), the live system's
//! benchmark (`bench_live*`), Note S12's
//! detection limits (`s12_limits*`) and generator configs (everything else).

use std::path::Path;

#[test]
fn every_experiment_config_is_valid() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let (mut generator, mut train, mut clips, mut tracking, mut settings) = (0, 0, 0, 0, 0);
    for entry in std::fs::read_dir(&dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_none_or(|e| e != "json") {
            continue;
        }
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&p).unwrap();
        fn fail<T>(p: &Path) -> impl Fn(pins::Error) -> T + '_ {
            move |e| panic!("{}: {e}", p.display())
        }
        if name.starts_with("train_") && text.contains("\"model\"") {
            let cfg = pins::flow::train::TrainConfig::from_file(&p).unwrap_or_else(fail(&p));
            assert_eq!(cfg.model, "mms-small", "{name}");
            train += 1;
        } else if name.starts_with("track_") && text.contains("\"clips\"") {
            let cfg =
                pins::track::experiment::ExperimentConfig::from_file(&p).unwrap_or_else(fail(&p));
            assert!(!cfg.clips.is_empty() && !cfg.predictors.is_empty());
            tracking += 1;
        } else if name.starts_with("track_config") {
            // Tracking settings for `pins track --config` (all keys, for users to copy).
            let cfg = pins::track::config::TrackConfig::from_file(&p).unwrap_or_else(fail(&p));
            let profile = cfg.profile.expect("an example names its profile");
            assert_eq!(
                cfg,
                pins::track::config::TrackConfig::profile(profile),
                "{name}"
            );
            settings += 1;
        } else if name.starts_with("bench_real") {
            pins::report::bench_real::config::load(&p).unwrap_or_else(fail(&p));
        } else if name.starts_with("bench_live") {
            let cfg =
                pins::report::bench_live::LiveBenchConfig::from_file(&p).unwrap_or_else(fail(&p));
            assert!(!cfg.points.is_empty() && !cfg.dis.is_empty(), "{name}");
        } else if name.starts_with("s12_limits") {
            pins::report::detection_limits::LimitsConfig::from_file(&p).unwrap_or_else(fail(&p));
        } else if name.starts_with("track_") {
            pins::dataset::sequence::SequenceConfig::from_file(&p).unwrap_or_else(fail(&p));
            clips += 1;
        } else {
            pins::dataset::GeneratorConfig::from_file(&p).unwrap_or_else(fail(&p));
            generator += 1;
        }
    }
    assert!(generator >= 10, "found only {generator} generator configs");
    assert!(train >= 2 && clips >= 4 && tracking >= 3 && settings >= 1);
}

/// `experiments/README.md` names every config (also under `campaign/`) and every record in
/// `results/`: a file named nowhere is a file nobody can find or trust.
#[test]
fn every_experiment_file_is_named_in_the_readme() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let readme = std::fs::read_to_string(dir.join("README.md")).expect("experiments/README.md");
    let mut files = Vec::new();
    let mut stack = vec![dir.clone()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).expect("a readable folder") {
            let p = entry.expect("a folder entry").path();
            if p.is_dir() {
                stack.push(p);
            } else if p.file_name().is_some_and(|n| n != "README.md") {
                files.push(p);
            }
        }
    }
    let unnamed: Vec<String> = files
        .iter()
        .map(|p| p.strip_prefix(&dir).expect("under experiments/"))
        .filter(|rel| {
            let name = rel.file_name().expect("a file name").to_string_lossy();
            !readme.contains(&*rel.to_string_lossy()) && !readme.contains(&*name)
        })
        .map(|rel| rel.display().to_string())
        .collect();
    assert!(
        unnamed.is_empty(),
        "experiments/README.md names none of: {unnamed:?}"
    );
}

/// The campaign's streams open (every generator config and photograph they name), and its
/// cool-down mix keeps every one of the run's sources (weighted otherwise, beside any it adds):
/// the decay phase must not forget what the run learned.
#[test]
fn the_campaign_streams_open_and_the_cool_down_mix_keeps_the_sources() {
    use pins::flow::train::stream::{Stream, StreamConfig};
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/campaign");
    let sources = |name: &str| {
        let p = dir.join(name);
        Stream::open(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        let cfg: StreamConfig = pins::io::read_json(&p).unwrap();
        let mut files: Vec<std::path::PathBuf> =
            cfg.sources.into_iter().map(|s| s.generator).collect();
        files.sort();
        files
    };
    let run = sources("stream.json");
    // Every cool-down mix (the committed one and any trial beside it) anneals on the run's
    // sources and perhaps more, never fewer.
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().to_string_lossy().into_owned();
        if name.starts_with("cooldown") && name.ends_with(".json") {
            let cool = sources(&name);
            let dropped: Vec<_> = run.iter().filter(|s| !cool.contains(s)).collect();
            assert!(dropped.is_empty(), "{name} drops {dropped:?}");
        }
    }
}
