//! The claim on an output folder: `config.json`, created atomically (written whole, then linked
//! to its name, which fails if the name is taken), so that of several runs started together on
//! one folder exactly one config owns it, while runs of that same config (reruns, shards) share it.

use std::path::Path;
use std::time::Duration;

use super::config::GeneratorConfig;
use super::manifest::SampleMeta;
use crate::error::{Error, Result};
use crate::io;

/// The name of the claim inside a dataset folder.
pub const CONFIG_FILE: &str = "config.json";

/// Makes `dir` (created if needed) the folder of `config`: claims it if nobody has, joins it if
/// its `config.json` is the same config, and refuses it (an error naming the folder and what
/// differs) if it is another config or if it holds samples without any `config.json`.
pub fn claim(dir: &Path, config: &GeneratorConfig) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let path = dir.join(CONFIG_FILE);
    let text = serde_json::to_string_pretty(config)
        .map_err(|e| Error::invalid("config", e.to_string()))?;
    if !path.exists() {
        // Samples are written only after a claim, so samples without one are of unknown origin;
        // but a racing run of our config may have claimed the folder and written some since we
        // looked, so look at `config.json` again before refusing.
        if holds_samples(dir)? && !path.exists() {
            return Err(Error::invalid(
                "output folder",
                format!(
                    "{} holds generated samples but no {CONFIG_FILE}, so their config is \
                     unknown; choose another --out or remove them",
                    dir.display()
                ),
            ));
        }
        if io::atomic::create_new_atomic(&path, text.as_bytes())? {
            return Ok(());
        }
    }
    let theirs = read_claim(dir)?;
    if theirs == *config {
        return Ok(());
    }
    Err(Error::invalid(
        "output folder",
        format!(
            "{} holds a dataset made with another config (see its {CONFIG_FILE}; it differs in {}); \
             choose another --out or remove it",
            dir.display(),
            differing_keys(&theirs, config)
        ),
    ))
}

/// The config that owns `dir`, from its `config.json`.
pub fn read_claim(dir: &Path) -> Result<GeneratorConfig> {
    let path = dir.join(CONFIG_FILE);
    // Where the file system has no hard links a claim is created in place, and a racing reader
    // may see it before its bytes: give the writer a moment before calling it broken.
    let mut tries = 0;
    loop {
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                return Err(Error::invalid(
                    "dataset folder",
                    format!(
                        "{} has no {CONFIG_FILE}: it is not a folder written by `pins generate`",
                        dir.display()
                    ),
                ));
            }
            Err(e) => return Err(Error::io(&path, e)),
        };
        match serde_json::from_str::<GeneratorConfig>(&text) {
            Ok(c) => return Ok(c),
            Err(_) if tries < 20 => {
                tries += 1;
                std::thread::sleep(Duration::from_millis(50));
            }
            Err(e) => {
                return Err(Error::format(
                    &path,
                    format!(
                        "not a generator config ({e}); choose another --out or remove {}",
                        dir.display()
                    ),
                ));
            }
        }
    }
}

/// True if `dir` holds a sample sidecar or a manifest.
fn holds_samples(dir: &Path) -> Result<bool> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    Ok(entries.flatten().any(|e| {
        let name = e.file_name();
        let name = name.to_string_lossy();
        name == "manifest.json"
            || name
                .strip_suffix("_meta.json")
                .and_then(|i| i.parse::<usize>().ok())
                .is_some_and(|i| name == SampleMeta::file_name(i))
    }))
}

/// The top-level keys in which two configs differ, for the refusal message.
fn differing_keys(a: &GeneratorConfig, b: &GeneratorConfig) -> String {
    let (a, b) = (serde_json::to_value(a).ok(), serde_json::to_value(b).ok());
    let keys: Vec<String> = match (
        a.as_ref().and_then(|v| v.as_object()),
        b.as_ref().and_then(|v| v.as_object()),
    ) {
        (Some(a), Some(b)) => a
            .keys()
            .chain(b.keys().filter(|k| !a.contains_key(*k)))
            .filter(|k| a.get(*k) != b.get(*k))
            .cloned()
            .collect(),
        _ => Vec::new(),
    };
    if keys.is_empty() {
        "its values".into()
    } else {
        keys.join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_config_joins_other_config_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("ds");
        let cfg = GeneratorConfig::default();
        claim(&d, &cfg).unwrap();
        claim(&d, &cfg).unwrap();
        assert_eq!(read_claim(&d).unwrap(), cfg);
        let other = GeneratorConfig {
            seed: 9,
            ..cfg.clone()
        };
        let err = claim(&d, &other).unwrap_err().to_string();
        assert!(
            err.contains("another config") && err.contains("differs in seed"),
            "{err}"
        );
        assert!(err.contains(d.to_str().unwrap()), "{err}");
        assert_eq!(
            read_claim(&d).unwrap(),
            cfg,
            "the refused run changed nothing"
        );
    }

    #[test]
    fn samples_without_a_claim_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("00002_meta.json"), "{}").unwrap();
        let err = claim(dir.path(), &GeneratorConfig::default())
            .unwrap_err()
            .to_string();
        assert!(err.contains("no config.json"), "{err}");
        assert!(!dir.path().join(CONFIG_FILE).exists());
        // Unrelated files do not count.
        let other = tempfile::tempdir().unwrap();
        std::fs::write(other.path().join("notes.txt"), "x").unwrap();
        claim(other.path(), &GeneratorConfig::default()).unwrap();
        std::fs::write(other.path().join(CONFIG_FILE), "{\"count\": ").unwrap();
        let err = read_claim(other.path()).unwrap_err().to_string();
        assert!(err.contains("not a generator config"), "{err}");
    }
}
