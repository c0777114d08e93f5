//! Packing a dataset into WebDataset shards (`pins pack`): each pair's files become tar
//! members under one key, with fixed metadata so the same folder always packs to the same
//! bytes, and the index records every member's byte range as read back from the tar written.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::{CARRIED, FORMAT, INDEX, Member, Sample, ShardFile, ShardIndex, locate, sha256_file};
use crate::error::{Error, Result};
use crate::scene::readers::{Layout, PairPaths, discover};

/// What `pack` wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PackSummary {
    pub samples: usize,
    pub shards: usize,
    pub bytes: u64,
}

/// The WebDataset key of a pair name: the extension starts at the first dot and folders are
/// not part of a key, so dots and slashes become underscores.
fn key_of(name: &str) -> String {
    name.chars()
        .map(|c| {
            if matches!(c, '.' | '/' | '\\') {
                '_'
            } else {
                c
            }
        })
        .collect()
}

fn ext_of(path: &Path) -> Result<String> {
    path.extension()
        .and_then(|e| e.to_str())
        .map(|e| e.to_ascii_lowercase())
        .ok_or_else(|| Error::invalid("pack", format!("{} has no extension", path.display())))
}

/// The `pins generate` sidecar of a pair (`NNNNN_meta.json` beside `NNNNN_img1.png`).
fn meta_of(p: &PairPaths) -> Option<PathBuf> {
    let file = p.img1.file_name()?.to_str()?;
    let stem = file.strip_suffix("_img1.png")?;
    let meta = p.img1.with_file_name(format!("{stem}_meta.json"));
    meta.is_file().then_some(meta)
}

/// A tar header with the fixed metadata of every member.
fn header(name: &str, size: u64) -> Result<tar::Header> {
    let mut h = tar::Header::new_ustar();
    h.set_path(name)
        .map_err(|e| Error::invalid("pack", format!("member name {name:?}: {e}")))?;
    h.set_size(size);
    h.set_mode(0o644);
    h.set_mtime(0);
    h.set_uid(0);
    h.set_gid(0);
    h.set_entry_type(tar::EntryType::Regular);
    h.set_cksum();
    Ok(h)
}

/// Packs the pairs of the dataset at `input` (any layout `pins` reads; a `pins generate`
/// folder keeps each sample's metadata as `KEY.json` and its `config.json`/`manifest.json`)
/// into `out/shard-NNNNNN.tar`, `per_shard` samples each, in the dataset's order, and writes
/// `out/index.json`. `out` must not exist; it appears complete or not at all.
pub fn pack(input: &Path, out: &Path, per_shard: usize) -> Result<PackSummary> {
    if per_shard == 0 {
        return Err(Error::invalid("--samples-per-shard", "must be >= 1"));
    }
    if out.exists() {
        return Err(Error::invalid(
            "--out",
            format!("{} already exists; pack writes a new folder", out.display()),
        ));
    }
    let pairs = discover(input, Layout::Auto)?;
    let mut keys = std::collections::BTreeSet::new();
    for p in &pairs {
        if !keys.insert(key_of(&p.name)) {
            return Err(Error::invalid(
                "pack",
                format!("two pairs share the key {:?}", key_of(&p.name)),
            ));
        }
    }
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty());
    if let Some(parent) = parent {
        std::fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
    }
    let tmp = crate::io::atomic::temp_sibling(out);
    std::fs::create_dir_all(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let result = pack_into(input, &pairs, &tmp, per_shard).and_then(|s| {
        std::fs::rename(&tmp, out).map_err(|e| Error::io(out, e))?;
        Ok(s)
    });
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result
}

fn pack_into(
    input: &Path,
    pairs: &[PairPaths],
    dir: &Path,
    per_shard: usize,
) -> Result<PackSummary> {
    let mut shards = Vec::new();
    let mut total = 0u64;
    for (s, chunk) in pairs.chunks(per_shard).enumerate() {
        let file = format!("shard-{s:06}.tar");
        let path = dir.join(&file);
        let f = File::create(&path).map_err(|e| Error::io(&path, e))?;
        let mut b = tar::Builder::new(std::io::BufWriter::new(f));
        let mut samples = Vec::new();
        for p in chunk {
            let key = key_of(&p.name);
            let mut roles: Vec<(&str, PathBuf)> =
                vec![("img1", p.img1.clone()), ("img2", p.img2.clone())];
            if let Some(f) = &p.flow {
                roles.push(("flow", f.clone()));
            }
            if let Some(m) = meta_of(p) {
                roles.push(("json", m));
            }
            let mut members = BTreeMap::new();
            for (role, src) in roles {
                let bytes = std::fs::read(&src).map_err(|e| Error::io(&src, e))?;
                let name = if role == "json" {
                    format!("{key}.json")
                } else {
                    format!("{key}.{role}.{}", ext_of(&src)?)
                };
                b.append(&header(&name, bytes.len() as u64)?, bytes.as_slice())
                    .map_err(|e| Error::io(&path, e))?;
                members.insert(
                    role.to_string(),
                    Member {
                        name,
                        offset: 0,
                        size: bytes.len() as u64,
                    },
                );
            }
            samples.push(Sample {
                name: p.name.clone(),
                key,
                members,
            });
        }
        let mut w = b.into_inner().map_err(|e| Error::io(&path, e))?;
        w.flush().map_err(|e| Error::io(&path, e))?;
        let f = w
            .into_inner()
            .map_err(|e| Error::io(&path, e.into_error()))?;
        f.sync_all().map_err(|e| Error::io(&path, e))?;
        drop(f);
        // The byte ranges, read back from the tar as written.
        locate(&path, &mut samples)?;
        let bytes = std::fs::metadata(&path)
            .map_err(|e| Error::io(&path, e))?
            .len();
        total += bytes;
        shards.push(ShardFile {
            file,
            bytes,
            sha256: sha256_file(&path)?,
            samples,
        });
    }
    for name in CARRIED {
        let src = input.join(name);
        if src.is_file() {
            std::fs::copy(&src, dir.join(name)).map_err(|e| Error::io(&src, e))?;
        }
    }
    let index = ShardIndex {
        format: FORMAT.into(),
        samples_per_shard: per_shard,
        shards,
    };
    let json = serde_json::to_string_pretty(&index)
        .map_err(|e| Error::invalid("index.json", e.to_string()))?;
    crate::io::write_bytes_atomic(&dir.join(INDEX), json.as_bytes())?;
    Ok(PackSummary {
        samples: pairs.len(),
        shards: index.shards.len(),
        bytes: total,
    })
}
