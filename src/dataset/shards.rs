//! Datasets as WebDataset shards: POSIX tar files in which the files of one sample share a
//! basename (`00042.img1.png`, `00042.img2.png`, `00042.flow.flo`, `00042.json`), with fixed tar
//! metadata (mtime 0, uid/gid 0, mode 0644, no owner names) so the same folder always packs to
//! the same bytes, and an `index.json` giving every member's byte range, so training and
//! evaluation read a pair straight out of its shard without unpacking anything.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};
use crate::scene::readers::PairPaths;

mod pack;
pub use pack::{PackSummary, pack};

/// The index's format tag.
pub const FORMAT: &str = "pins-webdataset-1";
/// The index's file name inside a shard folder.
pub const INDEX: &str = "index.json";
/// Dataset-level files of a `pins generate` folder carried beside the shards.
const CARRIED: [&str; 2] = ["config.json", "manifest.json"];

/// One member of a shard: its name in the tar and where its bytes are.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Member {
    pub name: String,
    /// Offset of the member's data from the start of the tar file, and its length.
    pub offset: u64,
    pub size: u64,
}

/// One sample: the pair's name in the source dataset, its WebDataset key, and its members by
/// role (`img1`, `img2`, `flow`, `json`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Sample {
    pub name: String,
    pub key: String,
    pub members: BTreeMap<String, Member>,
}

/// One tar file of the set.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardFile {
    pub file: String,
    pub bytes: u64,
    pub sha256: String,
    pub samples: Vec<Sample>,
}

/// `index.json`.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShardIndex {
    pub format: String,
    pub samples_per_shard: usize,
    pub shards: Vec<ShardFile>,
}

/// A shard folder opened for reading: its index and where it lies.
#[derive(Clone, Debug)]
pub struct ShardSet {
    pub root: PathBuf,
    pub index: ShardIndex,
    /// Sample `i` (in `samples()` order) → (shard, position in its shard).
    positions: Vec<(usize, usize)>,
}

/// Whether `dir` is a shard folder (it holds an `index.json` of this format).
pub fn is_shard_folder(dir: &Path) -> bool {
    let p = dir.join(INDEX);
    p.is_file()
        && std::fs::read(&p)
            .ok()
            .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok())
            .is_some_and(|v| v["format"] == FORMAT)
}

fn sha256_file(path: &Path) -> Result<String> {
    let mut f = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(|e| Error::io(path, e))?;
        if n == 0 {
            break;
        }
        h.update(&buf[..n]);
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// Fills in each member's offset from the tar's own entries.
fn locate(path: &Path, samples: &mut [Sample]) -> Result<()> {
    let f = File::open(path).map_err(|e| Error::io(path, e))?;
    let mut archive = tar::Archive::new(f);
    let mut at: BTreeMap<String, (u64, u64)> = BTreeMap::new();
    for e in archive.entries().map_err(|e| Error::io(path, e))? {
        let e = e.map_err(|e| Error::io(path, e))?;
        let name = e
            .path()
            .map_err(|e| Error::io(path, e))?
            .to_string_lossy()
            .into_owned();
        at.insert(name, (e.raw_file_position(), e.size()));
    }
    for s in samples {
        for m in s.members.values_mut() {
            let &(offset, size) = at.get(&m.name).ok_or_else(|| {
                Error::format(path, format!("member {} missing after writing", m.name))
            })?;
            if size != m.size {
                return Err(Error::format(
                    path,
                    format!("member {} has the wrong size", m.name),
                ));
            }
            m.offset = offset;
        }
    }
    Ok(())
}

impl ShardSet {
    /// Opens the shard folder `root`: reads and checks its index (format, every shard file
    /// present with the recorded size, member ranges inside their file, keys unique). Contents
    /// are checked against their SHA-256 by `verify` (and by `unpack`), not here.
    pub fn open(root: &Path) -> Result<Self> {
        let path = root.join(INDEX);
        let index: ShardIndex = crate::io::read_json(&path)?;
        if index.format != FORMAT {
            return Err(Error::format(
                &path,
                format!("format {:?}, expected {FORMAT:?}", index.format),
            ));
        }
        let mut keys = std::collections::BTreeSet::new();
        for s in &index.shards {
            if s.file.contains(['/', '\\']) || s.file.starts_with('.') {
                return Err(Error::format(
                    &path,
                    format!("shard file {:?} leaves the folder", s.file),
                ));
            }
            let f = root.join(&s.file);
            let len = std::fs::metadata(&f).map_err(|e| Error::io(&f, e))?.len();
            if len != s.bytes {
                return Err(Error::format(
                    &f,
                    format!("{len} bytes, the index says {}", s.bytes),
                ));
            }
            for sample in &s.samples {
                if !keys.insert(&sample.key) {
                    return Err(Error::format(&path, format!("key {:?} twice", sample.key)));
                }
                for role in ["img1", "img2"] {
                    if !sample.members.contains_key(role) {
                        return Err(Error::format(
                            &path,
                            format!("sample {:?} has no {role}", sample.key),
                        ));
                    }
                }
                for m in sample.members.values() {
                    if m.offset.checked_add(m.size).is_none_or(|end| end > len) {
                        return Err(Error::format(
                            &f,
                            format!("member {} lies beyond the file's {len} bytes", m.name),
                        ));
                    }
                }
            }
        }
        let positions = index
            .shards
            .iter()
            .enumerate()
            .flat_map(|(k, s)| (0..s.samples.len()).map(move |j| (k, j)))
            .collect();
        Ok(Self {
            root: root.to_path_buf(),
            index,
            positions,
        })
    }

    /// Every sample in order, with the shard file it lies in.
    pub fn samples(&self) -> impl Iterator<Item = (&ShardFile, &Sample)> {
        self.index
            .shards
            .iter()
            .flat_map(|s| s.samples.iter().map(move |x| (s, x)))
    }

    /// The pairs as a dataset sees them: the source pair names, and virtual paths
    /// `ROOT/SHARD.tar/MEMBER` (which name the member in messages and carry its extension).
    pub fn pairs(&self) -> Vec<PairPaths> {
        self.samples()
            .map(|(s, x)| {
                let at = |role: &str| {
                    x.members
                        .get(role)
                        .map(|m| self.root.join(&s.file).join(&m.name))
                };
                PairPaths {
                    name: x.name.clone(),
                    img1: at("img1").unwrap_or_default(),
                    img2: at("img2").unwrap_or_default(),
                    flow: at("flow"),
                }
            })
            .collect()
    }

    /// The bytes of member `role` of sample `i` (in `samples()` order), read from its range.
    pub fn read(&self, i: usize, role: &str) -> Result<Option<Vec<u8>>> {
        let (s, x) = self.sample(i)?;
        let Some(m) = x.members.get(role) else {
            return Ok(None);
        };
        let path = self.root.join(&s.file);
        let mut f = File::open(&path).map_err(|e| Error::io(&path, e))?;
        f.seek(SeekFrom::Start(m.offset))
            .map_err(|e| Error::io(&path, e))?;
        let mut buf = vec![0u8; m.size as usize];
        f.read_exact(&mut buf).map_err(|e| Error::io(&path, e))?;
        Ok(Some(buf))
    }

    /// The byte size of member `role` of sample `i`, if it has one.
    pub fn member_size(&self, i: usize, role: &str) -> Result<Option<u64>> {
        Ok(self.sample(i)?.1.members.get(role).map(|m| m.size))
    }

    /// Sample `i` and its shard file, in constant time.
    fn sample(&self, i: usize) -> Result<(&ShardFile, &Sample)> {
        let &(k, j) = self
            .positions
            .get(i)
            .ok_or_else(|| Error::invalid("shards", format!("no sample {i}")))?;
        let shard = &self.index.shards[k];
        Ok((shard, &shard.samples[j]))
    }

    /// Checks every shard file against its recorded SHA-256; the error names each bad one.
    pub fn verify(&self) -> Result<()> {
        let mut bad = Vec::new();
        for s in &self.index.shards {
            let got = sha256_file(&self.root.join(&s.file))?;
            if got != s.sha256 {
                bad.push(s.file.clone());
            }
        }
        if bad.is_empty() {
            Ok(())
        } else {
            Err(Error::invalid(
                "shards",
                format!(
                    "{}: content differs from the index (SHA-256): {}",
                    self.root.display(),
                    bad.join(", ")
                ),
            ))
        }
    }
}

/// Unpacks the shard folder `input` into `out` in FlyingChairs naming (`NAME_img1.EXT`,
/// `NAME_img2.EXT`, `NAME_flow.EXT`, `NAME_meta.json`) with the carried `config.json` and
/// `manifest.json`: a `pins generate` folder comes back byte for byte. The shards are checked
/// against their SHA-256 first; `out` must not exist and appears complete or not at all.
pub fn unpack(input: &Path, out: &Path) -> Result<usize> {
    let set = ShardSet::open(input)?;
    set.verify()?;
    if out.exists() {
        return Err(Error::invalid(
            "--out",
            format!(
                "{} already exists; unpack writes a new folder",
                out.display()
            ),
        ));
    }
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(parent) = parent {
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    }
    let tmp = crate::io::atomic::temp_sibling(out);
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let result = (|| {
        let mut n = 0;
        for (i, (_, x)) in set.samples().enumerate() {
            let stem = x.name.replace(['/', '\\'], "_");
            for (role, m) in &x.members {
                let file = if role == "json" {
                    format!("{stem}_meta.json")
                } else {
                    let ext = m.name.rsplit('.').next().unwrap_or("bin");
                    format!("{stem}_{role}.{ext}")
                };
                let bytes = set.read(i, role)?.unwrap_or_default();
                let dst = tmp.join(file);
                std::fs::write(&dst, bytes).map_err(|e| Error::io(&dst, e))?;
            }
            n += 1;
        }
        for name in CARRIED {
            let src = input.join(name);
            if src.is_file() {
                std::fs::copy(&src, tmp.join(name)).map_err(|e| Error::io(&src, e))?;
            }
        }
        std::fs::rename(&tmp, out).map_err(|e| Error::io(out, e))?;
        Ok(n)
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}
