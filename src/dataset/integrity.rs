//! Dataset integrity: the size and SHA-256 of every file a sample lists (recorded in its
//! `NNNNN_meta.json`), and the check that tells a complete sample from a missing, truncated,
//! altered or outdated one. Reruns redo what fails it; `pins generate --verify` reports it.

use std::fmt;
use std::fs::File;
use std::path::Path;

use sha2::{Digest, Sha256};

use super::manifest::{FileRecord, SampleMeta};
use crate::error::{Error, Result};

/// How deeply [`check_sample`] looks at the files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Depth {
    /// Sizes and SHA-256 of every file (reads every byte).
    Hashes,
    /// Presence and sizes only (one `stat` per file).
    Sizes,
}

/// One thing wrong with a sample.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Issue {
    /// Neither its sidecar nor any of its files exist.
    Missing,
    /// Some of its files exist but not the sidecar written last: an interrupted write.
    MetaMissing,
    MetaUnreadable(String),
    MetaUnparsable(String),
    /// A sidecar of an older format, listing files without sizes and hashes.
    OldFormat,
    /// The sidecar is another sample's (index, seed).
    WrongSample {
        index: usize,
        seed: u64,
    },
    /// The sidecar lists a file outside the sample, or not its two images.
    BadFileList(String),
    FileMissing(String),
    FileUnreadable {
        name: String,
        reason: String,
    },
    Truncated {
        name: String,
        found: u64,
        expected: u64,
    },
    Longer {
        name: String,
        found: u64,
        expected: u64,
    },
    HashMismatch(String),
}

/// Everything wrong with sample `index`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SampleProblem {
    pub index: usize,
    pub issues: Vec<Issue>,
}

impl SampleProblem {
    /// True when nothing of the sample exists (it is to be made, not repaired).
    pub fn is_absent(&self) -> bool {
        self.issues == [Issue::Missing]
    }
}

/// The size and SHA-256 of `dir/name`.
pub fn record_file(dir: &Path, name: &str) -> Result<FileRecord> {
    let path = dir.join(name);
    let (bytes, sha256) = sha256_file(&path).map_err(|e| Error::io(&path, e))?;
    Ok(FileRecord {
        name: name.to_string(),
        bytes,
        sha256,
    })
}

/// Length and lower-case hex SHA-256 of the file at `path`.
pub fn sha256_file(path: &Path) -> std::io::Result<(u64, String)> {
    let mut hasher = Sha256::new();
    let bytes = std::io::copy(&mut File::open(path)?, &mut hasher)?;
    Ok((bytes, format!("{:x}", hasher.finalize())))
}

/// Sample `index` of `dir` if its sidecar parses, is that of (`index`, `seed`), and every file it
/// lists exists with the recorded size (and, at [`Depth::Hashes`], hash); otherwise everything
/// found wrong with it.
pub fn check_sample(
    dir: &Path,
    index: usize,
    seed: u64,
    depth: Depth,
) -> std::result::Result<SampleMeta, SampleProblem> {
    let fail = |issues: Vec<Issue>| Err(SampleProblem { index, issues });
    let meta_name = SampleMeta::file_name(index);
    let text = match std::fs::read_to_string(dir.join(&meta_name)) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            let any_file = [
                "img1.png",
                "img2.png",
                "flow.flo",
                "clean1.png",
                "clean2.png",
            ]
            .iter()
            .any(|s| dir.join(format!("{index:05}_{s}")).exists());
            return fail(vec![if any_file {
                Issue::MetaMissing
            } else {
                Issue::Missing
            }]);
        }
        Err(e) => return fail(vec![Issue::MetaUnreadable(e.to_string())]),
    };
    let meta: SampleMeta = match serde_json::from_str(&text) {
        Ok(m) => m,
        Err(e) => return fail(vec![unparsable(&text, e)]),
    };
    if (meta.index, meta.seed) != (index, seed) {
        return fail(vec![Issue::WrongSample {
            index: meta.index,
            seed: meta.seed,
        }]);
    }
    if let Some(bad) = bad_file_list(&meta) {
        return fail(vec![Issue::BadFileList(bad)]);
    }
    let issues: Vec<Issue> = meta
        .files
        .iter()
        .filter_map(|f| check_file(dir, f, depth))
        .collect();
    if issues.is_empty() {
        Ok(meta)
    } else {
        fail(issues)
    }
}

impl fmt::Display for Issue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Issue::Missing => write!(f, "missing"),
            Issue::MetaMissing => write!(f, "metadata missing (an interrupted write)"),
            Issue::MetaUnreadable(e) => write!(f, "metadata unreadable ({e})"),
            Issue::MetaUnparsable(e) => write!(f, "metadata does not parse ({e})"),
            Issue::OldFormat => write!(f, "metadata of an older format, without file hashes"),
            Issue::WrongSample { index, seed } => {
                write!(f, "metadata is that of sample {index} with seed {seed}")
            }
            Issue::BadFileList(e) => write!(f, "metadata {e}"),
            Issue::FileMissing(name) => write!(f, "{name} missing"),
            Issue::FileUnreadable { name, reason } => write!(f, "{name} unreadable ({reason})"),
            Issue::Truncated {
                name,
                found,
                expected,
            } => write!(f, "{name} truncated ({found} of {expected} bytes)"),
            Issue::Longer {
                name,
                found,
                expected,
            } => write!(
                f,
                "{name} is longer than recorded ({found} instead of {expected} bytes)"
            ),
            Issue::HashMismatch(name) => write!(f, "{name} does not match its hash"),
        }
    }
}

impl fmt::Display for SampleProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:05}: ", self.index)?;
        for (k, issue) in self.issues.iter().enumerate() {
            if k > 0 {
                write!(f, "; ")?;
            }
            write!(f, "{issue}")?;
        }
        Ok(())
    }
}

/// Tells a sidecar of the older format (bare file names) from one that is simply broken.
fn unparsable(text: &str, e: serde_json::Error) -> Issue {
    let old = serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| {
            v.get("files")?
                .as_array()
                .map(|a| a.iter().all(|f| f.is_string()))
        })
        .unwrap_or(false);
    if old {
        Issue::OldFormat
    } else {
        Issue::MetaUnparsable(e.to_string())
    }
}

/// A sample lists its own files only (`NNNNN_*`, no path), its two images among them.
fn bad_file_list(meta: &SampleMeta) -> Option<String> {
    let prefix = format!("{:05}_", meta.index);
    if let Some(f) = meta.files.iter().find(|f| {
        !f.name.starts_with(&prefix)
            || f.name.contains(['/', '\\'])
            || f.name.contains("..")
            || f.name == SampleMeta::file_name(meta.index)
    }) {
        return Some(format!("lists {:?}, not a file of this sample", f.name));
    }
    for k in [1, 2] {
        let img = format!("{prefix}img{k}.png");
        if !meta.files.iter().any(|f| f.name == img) {
            return Some(format!("does not list {img}"));
        }
    }
    None
}

fn check_file(dir: &Path, f: &FileRecord, depth: Depth) -> Option<Issue> {
    let path = dir.join(&f.name);
    let unreadable = |e: std::io::Error| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Issue::FileMissing(f.name.clone())
        } else {
            Issue::FileUnreadable {
                name: f.name.clone(),
                reason: e.to_string(),
            }
        }
    };
    let size = match std::fs::metadata(&path) {
        Ok(m) if m.is_file() => m.len(),
        Ok(_) => return Some(Issue::FileMissing(f.name.clone())),
        Err(e) => return Some(unreadable(e)),
    };
    let size_issue = |found: u64| {
        let (name, expected) = (f.name.clone(), f.bytes);
        if found < expected {
            Some(Issue::Truncated {
                name,
                found,
                expected,
            })
        } else if found > expected {
            Some(Issue::Longer {
                name,
                found,
                expected,
            })
        } else {
            None
        }
    };
    if let Some(issue) = size_issue(size) {
        return Some(issue);
    }
    if depth == Depth::Sizes {
        return None;
    }
    match sha256_file(&path) {
        // The file may have changed between the stat and the read.
        Ok((found, _)) if found != f.bytes => size_issue(found),
        Ok((_, hash)) if hash != f.sha256 => Some(Issue::HashMismatch(f.name.clone())),
        Ok(_) => None,
        Err(e) => Some(unreadable(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(dir: &Path) -> SampleMeta {
        let mut files = Vec::new();
        for (name, body) in [
            ("00003_img1.png", &b"first image"[..]),
            ("00003_img2.png", b"two"),
        ] {
            std::fs::write(dir.join(name), body).unwrap();
            files.push(record_file(dir, name).unwrap());
        }
        let meta = SampleMeta {
            index: 3,
            seed: 77,
            width: 1,
            height: 1,
            channels: 1,
            files,
            flow: None,
            source: None,
            layers: None,
            scene_draw: None,
        };
        meta.write(&dir.join(SampleMeta::file_name(3))).unwrap();
        meta
    }

    fn issues(dir: &Path, depth: Depth) -> Vec<String> {
        match check_sample(dir, 3, 77, depth) {
            Ok(_) => vec![],
            Err(p) => p.issues.iter().map(|i| i.to_string()).collect(),
        }
    }

    #[test]
    fn hashes_are_sha256() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("abc"), b"abc").unwrap();
        let r = record_file(dir.path(), "abc").unwrap();
        assert_eq!(r.bytes, 3);
        assert_eq!(
            r.sha256,
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }

    #[test]
    fn every_kind_of_damage_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        assert_eq!(issues(d, Depth::Hashes), ["missing"]);
        let meta = sample(d);
        assert_eq!(check_sample(d, 3, 77, Depth::Hashes), Ok(meta.clone()));
        // Another seed: the sidecar is not this config's sample 3.
        assert!(check_sample(d, 3, 78, Depth::Sizes).is_err());
        // Same size, other bytes: only the hash sees it.
        std::fs::write(d.join("00003_img1.png"), b"first imagE").unwrap();
        assert!(check_sample(d, 3, 77, Depth::Sizes).is_ok());
        assert_eq!(
            issues(d, Depth::Hashes),
            ["00003_img1.png does not match its hash"]
        );
        std::fs::write(d.join("00003_img1.png"), b"fir").unwrap();
        std::fs::remove_file(d.join("00003_img2.png")).unwrap();
        assert_eq!(
            issues(d, Depth::Sizes),
            [
                "00003_img1.png truncated (3 of 11 bytes)",
                "00003_img2.png missing"
            ]
        );
        // A sidecar of the older format, then a broken one, then none.
        let meta_path = d.join(SampleMeta::file_name(3));
        std::fs::write(
            &meta_path,
            r#"{"index":3,"seed":77,"width":1,"height":1,"channels":1,
                "files":["00003_img1.png","00003_img2.png"],"flow":null}"#,
        )
        .unwrap();
        assert_eq!(
            issues(d, Depth::Hashes),
            ["metadata of an older format, without file hashes"]
        );
        std::fs::write(&meta_path, &meta.to_json().unwrap()[..40]).unwrap();
        assert!(issues(d, Depth::Hashes)[0].starts_with("metadata does not parse"));
        std::fs::remove_file(&meta_path).unwrap();
        assert_eq!(
            issues(d, Depth::Hashes),
            ["metadata missing (an interrupted write)"]
        );
    }

    #[test]
    fn a_sidecar_may_only_list_its_own_files() {
        let dir = tempfile::tempdir().unwrap();
        let mut meta = sample(dir.path());
        meta.files[1].name = "../00003_img2.png".into();
        meta.write(&dir.path().join(SampleMeta::file_name(3)))
            .unwrap();
        assert!(issues(dir.path(), Depth::Sizes)[0].contains("not a file of this sample"));
        meta.files.truncate(1);
        meta.write(&dir.path().join(SampleMeta::file_name(3)))
            .unwrap();
        assert_eq!(
            issues(dir.path(), Depth::Sizes),
            ["metadata does not list 00003_img2.png"]
        );
    }
}
