//! Every shipped experiment config parses, validates and names only known keys.

use std::path::Path;

#[test]
fn every_experiment_config_is_valid() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments");
    let mut n = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let p = entry.unwrap().path();
        if p.extension().is_some_and(|e| e == "json")
            && p.file_name().is_some_and(|f| f != "train_small.json")
        {
            pins::dataset::GeneratorConfig::from_file(&p)
                .unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            n += 1;
        }
    }
    assert!(n >= 10, "found only {n} configs");
}

#[test]
fn the_shipped_training_config_is_valid() {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/train_small.json");
    let cfg = pins::flow::train::TrainConfig::from_file(&p).unwrap();
    assert_eq!(cfg.model, "mms-small");
}
