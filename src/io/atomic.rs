//! Atomic file writes: write to a temporary sibling, flush, then rename, so no reader ever sees a
//! partial file and a failed write leaves nothing behind; create-only publication (hard link) for
//! claims that several processes may race for; and the cleanup of provably stale temporaries.

use std::fs::{self, File, OpenOptions};
use std::io::{BufWriter, ErrorKind, Write};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::Duration;

use crate::error::{Error, Result};

/// A temporary file older than this is stale whoever wrote it: no single atomic write takes hours.
pub const STALE_AFTER: Duration = Duration::from_secs(6 * 3600);

/// Writes `path` atomically: `fill` writes into a buffered temporary file next to `path`, which
/// is renamed over `path` only if `fill` succeeds. On any error the temporary file is removed.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let tmp = temp_sibling(path);
    let result = (|| {
        create_parent(path)?;
        let file = File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        let mut w = BufWriter::new(file);
        fill(&mut w)?;
        let file = w
            .into_inner()
            .map_err(|e| Error::io(&tmp, e.into_error()))?;
        file.sync_data().map_err(|e| Error::io(&tmp, e))?;
        fs::rename(&tmp, path).map_err(|e| Error::io(path, e))
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes).map_err(|e| Error::io(path, e)))
}

/// Creates `path` holding `bytes` only if no file of that name exists: the bytes are written and
/// synced under a temporary name, then hard-linked to `path`, which fails if the name is taken.
/// Of several processes racing for one name exactly one gets `Ok(true)`; the others get
/// `Ok(false)` and the winner's file, which is complete from the moment it appears. On a file
/// system without hard links it falls back to `create_new`, still exclusive, but where a racing
/// reader may briefly see the file shorter than it will be.
pub fn create_new_atomic(path: &Path, bytes: &[u8]) -> Result<bool> {
    create_parent(path)?;
    let tmp = temp_sibling(path);
    let linked = (|| {
        let mut file = File::create(&tmp).map_err(|e| Error::io(&tmp, e))?;
        file.write_all(bytes).map_err(|e| Error::io(&tmp, e))?;
        file.sync_data().map_err(|e| Error::io(&tmp, e))?;
        Ok::<_, Error>(fs::hard_link(&tmp, path))
    })();
    let _ = fs::remove_file(&tmp);
    match linked? {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == ErrorKind::AlreadyExists => Ok(false),
        Err(_) => create_new_plain(path, bytes),
    }
}

/// Reads a whole file, naming the path on failure.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    fs::read(path).map_err(|e| Error::io(path, e))
}

/// True for the temporary names made by [`write_atomic`], so resumable jobs can clean them up.
pub fn is_temp_name(name: &str) -> bool {
    name.starts_with('.') && name.contains(".tmp-")
}

/// Deletes the temporary files in `dir` that are provably stale, and only those (another process
/// may be writing the others right now): written on this host by a process that no longer runs
/// (`/proc/PID` is gone), or, from any host, last modified more than `max_age` ago. Returns how
/// many were removed.
pub fn remove_stale_temporaries(dir: &Path, max_age: Duration) -> Result<usize> {
    let mut removed = 0;
    for entry in fs::read_dir(dir).map_err(|e| Error::io(dir, e))?.flatten() {
        let path = entry.path();
        if !is_stale_temp(&path, max_age) {
            continue;
        }
        match fs::remove_file(&path) {
            Ok(()) => removed += 1,
            // Renamed or removed by its writer or another cleaner meanwhile.
            Err(e) if e.kind() == ErrorKind::NotFound => {}
            Err(e) => return Err(Error::io(&path, e)),
        }
    }
    Ok(removed)
}

/// See [`remove_stale_temporaries`]; false for anything that is not one of our temporaries.
pub fn is_stale_temp(path: &Path, max_age: Duration) -> bool {
    let Some(name) = path.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return false;
    };
    let Some((host, pid)) = parse_temp_name(&name) else {
        return false;
    };
    let proc_works = Path::new("/proc/self").exists();
    if proc_works
        && host.as_deref() == Some(host_tag())
        && !Path::new("/proc").join(pid.to_string()).exists()
    {
        return true;
    }
    fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|age| age > max_age)
}

/// `(host, pid)` of a temporary name `.NAME.tmp-HOST-PID-N`; the host is `None` for the older
/// `.NAME.tmp-PID-N`, whose writer's host is unknown.
fn parse_temp_name(name: &str) -> Option<(Option<String>, u32)> {
    if !is_temp_name(name) {
        return None;
    }
    let (_, tail) = name.rsplit_once(".tmp-")?;
    let mut parts = tail.rsplitn(3, '-');
    let _n: u64 = parts.next()?.parse().ok()?;
    let pid: u32 = parts.next()?.parse().ok()?;
    Some((parts.next().map(str::to_owned), pid))
}

/// `dir/.name.tmp-<host>-<pid>-<n>`: hidden, unique per host, process and call, in the same
/// directory so that the final rename stays on one file system.
pub fn temp_sibling(path: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(
        ".{name}.tmp-{}-{}-{n}",
        host_tag(),
        std::process::id()
    ))
}

/// This host's name as it goes into temporary names (letters, digits, `.`, `_`, `-`; at most
/// 64 characters), or `unknown-host`.
fn host_tag() -> &'static str {
    static TAG: OnceLock<String> = OnceLock::new();
    TAG.get_or_init(|| {
        let raw = fs::read_to_string("/proc/sys/kernel/hostname")
            .or_else(|_| fs::read_to_string("/etc/hostname"))
            .ok()
            .or_else(|| std::env::var("HOSTNAME").ok())
            .unwrap_or_default();
        let tag: String = raw
            .trim()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-') {
                    c
                } else {
                    '_'
                }
            })
            .take(64)
            .collect();
        if tag.is_empty() {
            "unknown-host".into()
        } else {
            tag
        }
    })
}

fn create_parent(path: &Path) -> Result<()> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    }
    Ok(())
}

/// The fallback of [`create_new_atomic`]: exclusive creation, then the bytes.
fn create_new_plain(path: &Path, bytes: &[u8]) -> Result<bool> {
    let mut file = match OpenOptions::new().write(true).create_new(true).open(path) {
        Ok(f) => f,
        Err(e) if e.kind() == ErrorKind::AlreadyExists => return Ok(false),
        Err(e) => return Err(Error::io(path, e)),
    };
    let written = file.write_all(bytes).and_then(|()| file.sync_data());
    if let Err(e) = written {
        let _ = fs::remove_file(path);
        return Err(Error::io(path, e));
    }
    Ok(true)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.bin");
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial").unwrap();
            Err(Error::invalid("test", "fails on purpose"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
        write_bytes_atomic(&p, b"ok").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"ok");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn create_new_atomic_has_one_winner_among_racing_threads() {
        for round in 0..20 {
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join("claim.json");
            let wins: Vec<bool> = std::thread::scope(|s| {
                let handles: Vec<_> = (0..4u8)
                    .map(|k| {
                        let p = &p;
                        s.spawn(move || create_new_atomic(p, &[b'a' + k; 1000]).unwrap())
                    })
                    .collect();
                handles.into_iter().map(|h| h.join().unwrap()).collect()
            });
            assert_eq!(wins.iter().filter(|&&w| w).count(), 1, "round {round}");
            let k = wins.iter().position(|&w| w).unwrap() as u8;
            assert_eq!(fs::read(&p).unwrap(), vec![b'a' + k; 1000]);
            // Only the claim is left: every temporary was removed.
            assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
        }
    }

    #[test]
    fn only_provably_stale_temporaries_are_removed() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let host = host_tag();
        // Ours (alive), a dead process on this host (no pid is above pid_max = 2^22), another
        // host, and the older name without a host: only the dead one is provably stale.
        let live = format!(".a.png.tmp-{host}-{}-0", std::process::id());
        let dead = format!(".b.png.tmp-{host}-999999999-0");
        let elsewhere = ".c.png.tmp-some-other-host-999999999-0".to_string();
        let legacy = ".d.png.tmp-999999999-0".to_string();
        for name in [&live, &dead, &elsewhere, &legacy, &"e.png".to_string()] {
            fs::write(d.join(name), b"x").unwrap();
        }
        assert_eq!(
            parse_temp_name(&elsewhere),
            Some((Some("some-other-host".into()), 999999999))
        );
        assert_eq!(parse_temp_name(&legacy), Some((None, 999999999)));
        assert_eq!(parse_temp_name("e.png"), None);
        let removed = remove_stale_temporaries(d, STALE_AFTER).unwrap();
        let mut left: Vec<String> = fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        if Path::new("/proc/self").exists() {
            assert_eq!(removed, 1);
            assert!(!left.contains(&dead), "{left:?}");
        }
        for kept in [&live, &elsewhere, &legacy] {
            assert!(left.contains(kept), "{kept} removed: {left:?}");
        }
        // Older than the limit, everything that is a temporary is stale, from any host.
        let old = std::time::SystemTime::now() - STALE_AFTER - Duration::from_secs(60);
        for e in fs::read_dir(d).unwrap() {
            File::options()
                .write(true)
                .open(e.unwrap().path())
                .unwrap()
                .set_modified(old)
                .unwrap();
        }
        assert_eq!(remove_stale_temporaries(d, STALE_AFTER).unwrap(), 3);
        let left: Vec<_> = fs::read_dir(d).unwrap().collect();
        assert_eq!(left.len(), 1, "only e.png is not a temporary");
    }
}
