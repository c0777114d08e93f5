//! Mutation fuzzing of every file reader (stable Rust, no cargo-fuzz): valid files of each format,
//! written by pins' own writers and taken from `../shared/data` when present, are mutated
//! thousands of times with a seeded RNG (byte flips, truncations, extensions, splices, integer
//! overwrites and format-aware header edits), and every variant must give `Ok` (a value that
//! keeps the type's invariants) or a typed `pins::Error` naming the file: never a panic, and
//! never more allocation in one call than [`bound`].
//!
//! Environment:
//! - `PINS_FUZZ_SEED` (default 20240611): the RNG seed; variant `i` of a format depends only on
//!   (seed, format, i), so a failure is replayed exactly.
//! - `PINS_FUZZ_VARIANTS` (default 2000): variants per binary format (JSON configs get 0.4 of
//!   it each). A fixed count, so every machine runs the same variants whatever its speed or
//!   load, and a run that passes here passes everywhere.
//! - `PINS_FUZZ_SECONDS`: a time budget per binary format instead of the count, for long runs
//!   (e.g. `PINS_FUZZ_SECONDS=600` overnight); how far it gets then depends on the machine.
//! - `PINS_FUZZ_ONLY=FORMAT` runs one format; `PINS_FUZZ_ONLY=FORMAT:INDEX` replays one variant
//!   and prints its outcome; `PINS_FUZZ_DUMP=FILE` also writes that variant's bytes there.
//!
//! Run with `--nocapture` to see how many variants ran per format.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::{Cell, RefCell};
use std::collections::HashMap;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering::Relaxed};
use std::sync::{Mutex, MutexGuard, Once, OnceLock};
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::Value;

use pins::io::{self, BitDepth};
use pins::{Flow, Image};

// ---------------------------------------------------------------------------------------------
// Allocation counting
// ---------------------------------------------------------------------------------------------

/// The system allocator, counting the bytes currently allocated and their peak.
struct Counting;

#[global_allocator]
static ALLOC: Counting = Counting;

static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// Live memory above which the allocator refuses (the process then aborts, after a note naming
/// the variant): a reader asking for gigabytes must not swap out the shared test machine.
const HARD_CAP: usize = 1 << 30;
/// What is running, for that note: format name (NUL-padded), variant index, seed.
static CURRENT_NAME: Mutex<[u8; 32]> = Mutex::new([0; 32]);
static VARIANT: AtomicU64 = AtomicU64::new(0);
static SEED: AtomicU64 = AtomicU64::new(0);

/// `PINS_FUZZ_TRAP=BYTES`: every single request above it calls [`big_allocation`], a place for
/// a debugger's breakpoint (`break fuzz_readers::big_allocation`).
static TRAP: AtomicUsize = AtomicUsize::new(usize::MAX);

#[inline(never)]
fn big_allocation(n: usize) {
    std::hint::black_box(n);
}

fn reserve(n: usize) -> bool {
    if n > TRAP.load(Relaxed) {
        big_allocation(n);
    }
    let now = CURRENT.fetch_add(n, Relaxed) + n;
    if now > HARD_CAP {
        CURRENT.fetch_sub(n, Relaxed);
        note_refusal(n);
        return false;
    }
    PEAK.fetch_max(now, Relaxed);
    true
}

fn release(n: usize) {
    CURRENT.fetch_sub(n, Relaxed);
}

/// Writes, without allocating, which variant asked for too much.
fn note_refusal(n: usize) {
    use std::io::Write;
    let mut buf = [0u8; 256];
    let name = CURRENT_NAME.try_lock().map(|g| *g).unwrap_or([b'?'; 32]);
    let end = name.iter().position(|&b| b == 0).unwrap_or(32);
    let name = std::str::from_utf8(&name[..end]).unwrap_or("?");
    let len = {
        let mut w = &mut buf[..];
        let _ = write!(
            w,
            "\nfuzz_readers: refused an allocation of {n} bytes (live memory over {HARD_CAP}) in \
             format {name} variant {}; replay: PINS_FUZZ_SEED={} PINS_FUZZ_ONLY={name}:{}\n",
            VARIANT.load(Relaxed),
            SEED.load(Relaxed),
            VARIANT.load(Relaxed)
        );
        256 - w.len()
    };
    let _ = std::io::stderr().write_all(&buf[..len]);
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            release(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !reserve(layout.size()) {
            return std::ptr::null_mut();
        }
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            release(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        release(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !reserve(new_size - old) {
            return std::ptr::null_mut();
        }
        let q = unsafe { System.realloc(ptr, layout, new_size) };
        if q.is_null() {
            if new_size > old {
                release(new_size - old);
            }
        } else if new_size < old {
            release(old - new_size);
        }
        q
    }
}

/// Runs `f` and returns its result (or the panic message) and the peak of the bytes it
/// allocated on top of what was live before.
fn measured<T>(f: impl FnOnce() -> T) -> (Result<T, String>, usize) {
    let base = CURRENT.load(Relaxed);
    PEAK.store(base, Relaxed);
    QUIET.with(|q| q.set(true));
    let r = catch_unwind(AssertUnwindSafe(f));
    QUIET.with(|q| q.set(false));
    let peak = PEAK.load(Relaxed).saturating_sub(base);
    let r = r.map_err(|_| {
        LAST_PANIC
            .with(|p| p.borrow_mut().take())
            .unwrap_or_else(|| "panic without a message".into())
    });
    (r, peak)
}

thread_local! {
    static QUIET: Cell<bool> = const { Cell::new(false) };
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// A panic hook that records (instead of printing) panics raised while a variant runs.
fn install_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if QUIET.with(|q| q.get()) {
                LAST_PANIC.with(|p| *p.borrow_mut() = Some(info.to_string()));
            } else {
                default(info);
            }
        }));
    });
}

/// The formats run one at a time (tests of this binary take this lock), so that the process-wide
/// allocation count belongs to the call being measured and the pixel budget is this file's.
fn lock() -> MutexGuard<'static, ()> {
    static LOCK: Mutex<()> = Mutex::new(());
    LOCK.lock().unwrap_or_else(|e| e.into_inner())
}

// ---------------------------------------------------------------------------------------------
// Settings and bounds
// ---------------------------------------------------------------------------------------------

/// The pixel budget while fuzzing: 2 MP admits every real seed (the largest, the DiffuserCam
/// PSF, is 1600×1200) and keeps a legitimately decoded variant small.
const FUZZ_BUDGET: u64 = 1 << 21;

/// The most one reader call may allocate for an input of `len` bytes: `max(64 MiB, 32 × len)`.
///
/// Why: with the fuzzing budget of 2^21 pixels, the largest image a header can make a reader
/// decode is 2 MP of RGBA f32 (32 MiB in the decoder) plus the planar f32 copy (24 MiB), under
/// 64 MiB; and an uncompressed input expands at most about 16 times (u8 samples to f32 planes
/// beside the decoder's own buffer), so 32 × its length is room to spare. A reader that
/// allocates by what a header claims rather than by what the file holds or the budget allows
/// goes over it.
fn bound(len: usize) -> usize {
    (64 << 20).max(32 * len)
}

/// How much each format is fuzzed.
#[derive(Clone, Copy)]
enum Amount {
    Variants(u64),
    Seconds(f64),
}

struct Settings {
    seed: u64,
    /// Variants per format of weight 1, or a time budget per format of weight 1.
    amount: Amount,
    only: Option<(String, Option<u64>)>,
    dump: Option<PathBuf>,
}

fn settings() -> Settings {
    let seed = std::env::var("PINS_FUZZ_SEED")
        .ok()
        .map(|s| s.trim().parse().expect("PINS_FUZZ_SEED must be an integer"))
        .unwrap_or(20240611);
    let amount = match std::env::var("PINS_FUZZ_SECONDS") {
        Ok(s) => Amount::Seconds(
            s.trim()
                .parse()
                .expect("PINS_FUZZ_SECONDS must be a number"),
        ),
        Err(_) => Amount::Variants(
            std::env::var("PINS_FUZZ_VARIANTS")
                .ok()
                .map(|s| {
                    s.trim()
                        .parse()
                        .expect("PINS_FUZZ_VARIANTS must be an integer")
                })
                .unwrap_or(2000),
        ),
    };
    let only = std::env::var("PINS_FUZZ_ONLY")
        .ok()
        .map(|s| match s.split_once(':') {
            Some((f, i)) => (
                f.to_string(),
                Some(
                    i.parse()
                        .expect("PINS_FUZZ_ONLY=FORMAT:INDEX needs an integer index"),
                ),
            ),
            None => (s, None),
        });
    let dump = std::env::var_os("PINS_FUZZ_DUMP").map(PathBuf::from);
    if let Some(t) = std::env::var("PINS_FUZZ_TRAP")
        .ok()
        .and_then(|t| t.parse().ok())
    {
        TRAP.store(t, Relaxed);
    }
    Settings {
        seed,
        amount,
        only,
        dump,
    }
}

/// `../shared/data`, or `None` with a note when it is not there.
fn data_dir(format: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data"));
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "fuzz {format}: {} not found, skipping the real seed files",
            dir.display()
        );
        None
    }
}

fn repo(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

// ---------------------------------------------------------------------------------------------
// The harness
// ---------------------------------------------------------------------------------------------

/// One valid file to start from; `weight` is its share of the variants.
struct Seed {
    name: String,
    bytes: Vec<u8>,
    weight: u32,
}

fn seed(name: impl Into<String>, bytes: Vec<u8>, weight: u32) -> Seed {
    Seed {
        name: name.into(),
        bytes,
        weight,
    }
}

/// Adds the real files `rels` (relative to `../shared/data`) when the folder exists.
fn real_seeds(seeds: &mut Vec<Seed>, format: &str, rels: &[&str], weight: u32) {
    let Some(dir) = data_dir(format) else { return };
    for rel in rels {
        match std::fs::read(dir.join(rel)) {
            Ok(b) => seeds.push(seed(*rel, b, weight)),
            Err(e) => eprintln!("fuzz {format}: cannot read seed {rel}: {e}"),
        }
    }
}

/// A format-aware edit: changes `bytes` and describes what it did.
type Edit = fn(&mut ChaCha8Rng, &mut Vec<u8>) -> String;

/// What one call returns: `Ok(None)` for a good value, `Ok(Some(why))` for a value that breaks
/// its type's invariants, `Err` for a typed refusal.
type Outcome = pins::Result<Option<String>>;

/// A reader call: bytes, file path, whether to read from the file, variant index.
type Call<'a> = Box<dyn Fn(&[u8], &Path, bool, u64) -> Outcome + 'a>;

struct Target<'a> {
    name: &'static str,
    /// Extension of the file name the readers see.
    ext: &'static str,
    seeds: Vec<Seed>,
    edit: Edit,
    /// Applied after the mutations with probability 1/2 (e.g. fixing PNG chunk CRCs).
    post: Option<Edit>,
    /// Share of `PINS_FUZZ_SECONDS`.
    weight: f64,
    /// Every `file_every`-th variant is written to the file and read through the path reader.
    file_every: u64,
    /// Whether every error must name the file (otherwise those that do not are only counted).
    names_file: bool,
    /// Files written beside the file under test (e.g. the clips an experiment names).
    extra_files: Vec<Seed>,
    /// The reader call: bytes, file path, whether to read from the file, variant index.
    call: Call<'a>,
}

fn rng_for(seed: u64, format: &str, index: u64) -> ChaCha8Rng {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in format.bytes() {
        h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
    }
    ChaCha8Rng::seed_from_u64(seed ^ h ^ index.wrapping_mul(0x9e37_79b9_7f4a_7c15))
}

/// Variant `index`: (its seed file's name, the mutations, the bytes).
fn variant(t: &Target, seed: u64, index: u64) -> (String, String, Vec<u8>) {
    let mut rng = rng_for(seed, t.name, index);
    let total: u32 = t.seeds.iter().map(|s| s.weight).sum();
    let mut pick = rng.random_range(0..total);
    let mut chosen = &t.seeds[0];
    for s in &t.seeds {
        if pick < s.weight {
            chosen = s;
            break;
        }
        pick -= s.weight;
    }
    let mut bytes = chosen.bytes.clone();
    let mut desc = Vec::new();
    for _ in 0..rng.random_range(1..=3) {
        let d = match rng.random_range(0..100) {
            0..25 => flip(&mut rng, &mut bytes),
            25..37 => truncate(&mut rng, &mut bytes),
            37..47 => extend(&mut rng, &mut bytes),
            47..60 => overwrite_int(&mut rng, &mut bytes),
            60..65 => splice(&mut rng, &mut bytes),
            _ => (t.edit)(&mut rng, &mut bytes),
        };
        desc.push(d);
    }
    if let Some(post) = t.post
        && rng.random_bool(0.5)
    {
        desc.push(post(&mut rng, &mut bytes));
    }
    (chosen.name.clone(), desc.join("; "), bytes)
}

fn fuzz(t: Target) {
    let _guard = lock();
    install_hook();
    io::set_max_pixels(FUZZ_BUDGET);
    let s = settings();
    let replay = match &s.only {
        Some((f, _)) if f != t.name => {
            eprintln!("fuzz {}: skipped (PINS_FUZZ_ONLY={f})", t.name);
            return;
        }
        Some((_, i)) => *i,
        None => None,
    };
    assert!(!t.seeds.is_empty(), "{}: no seed files", t.name);
    {
        let mut cur = CURRENT_NAME.lock().unwrap_or_else(|e| e.into_inner());
        *cur = [0; 32];
        let n = t.name.len().min(31);
        cur[..n].copy_from_slice(&t.name.as_bytes()[..n]);
    }
    SEED.store(s.seed, Relaxed);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("fuzz.{}", t.ext));
    for f in &t.extra_files {
        std::fs::write(dir.path().join(&f.name), &f.bytes).unwrap();
    }
    let file_name = path.file_name().unwrap().to_string_lossy().into_owned();
    let (budget, count) = match s.amount {
        Amount::Seconds(seconds) => (Duration::from_secs_f64(seconds * t.weight), u64::MAX),
        Amount::Variants(n) => (Duration::MAX, ((n as f64 * t.weight).ceil() as u64).max(10)),
    };
    let start = Instant::now();
    let (mut ran, mut oks, mut errs) = (0u64, 0u64, 0u64);
    let (mut max_peak, mut max_ratio) = (0usize, 0.0f64);
    let mut failures = Vec::new();
    let mut kinds: HashMap<String, u64> = HashMap::new();
    // Errors that do not name the file, where that is reported rather than failed.
    let (mut unnamed, mut unnamed_examples) = (0u64, Vec::<String>::new());
    let indices: Box<dyn Iterator<Item = u64>> = match replay {
        Some(i) => Box::new(std::iter::once(i)),
        None => Box::new(0..),
    };
    for index in indices {
        if replay.is_none() && (index >= count || start.elapsed() > budget) {
            break;
        }
        let (from, desc, bytes) = variant(&t, s.seed, index);
        let from_file = index % t.file_every == 0;
        if from_file {
            std::fs::write(&path, &bytes).unwrap();
        }
        VARIANT.store(index, Relaxed);
        let (result, peak) = measured(|| (t.call)(&bytes, &path, from_file, index));
        ran += 1;
        max_peak = max_peak.max(peak);
        max_ratio = max_ratio.max(peak as f64 / bytes.len().max(1) as f64);
        let what = format!(
            "{} variant {index} (PINS_FUZZ_SEED={} PINS_FUZZ_ONLY={}:{index}; from {from}; {desc}; \
             {} bytes)",
            t.name,
            s.seed,
            t.name,
            bytes.len()
        );
        if replay.is_some() {
            eprintln!("{what}\n  outcome: {result:?}\n  peak allocation: {peak} bytes");
            if let Some(d) = &s.dump {
                std::fs::write(d, &bytes).unwrap();
            }
        }
        match result {
            Err(panic) => failures.push(format!("{what}: PANIC {panic}")),
            Ok(Ok(None)) => oks += 1,
            Ok(Ok(Some(why))) => failures.push(format!("{what}: bad value: {why}")),
            Ok(Err(e)) => {
                errs += 1;
                let msg = e.to_string();
                let kind = msg
                    .replace(&path.display().to_string(), "")
                    .chars()
                    .take(48)
                    .collect::<String>();
                *kinds.entry(kind.clone()).or_default() += 1;
                if !msg.contains(&file_name) {
                    if t.names_file {
                        failures.push(format!("{what}: error does not name the file: {msg}"));
                    } else {
                        unnamed += 1;
                        if unnamed_examples.len() < 3 && !unnamed_examples.contains(&kind) {
                            unnamed_examples.push(kind);
                        }
                    }
                }
            }
        }
        if peak > bound(bytes.len()) {
            failures.push(format!(
                "{what}: allocated {peak} bytes at peak, over the bound {}",
                bound(bytes.len())
            ));
        }
    }
    let mut top: Vec<_> = kinds.into_iter().collect();
    top.sort_by_key(|k| std::cmp::Reverse(k.1));
    eprintln!(
        "fuzz {}: {ran} variants in {:.1} s (seed {}, {} seed files): {oks} ok, {errs} errors, \
         {} failures; peak allocation {:.1} MB (at most {:.1}× the input)\n  most frequent \
         errors: {:?}",
        t.name,
        start.elapsed().as_secs_f64(),
        s.seed,
        t.seeds.len(),
        failures.len(),
        max_peak as f64 / 1e6,
        max_ratio,
        &top[..top.len().min(4)]
    );
    if unnamed > 0 {
        eprintln!(
            "  note: {unnamed} errors do not name the file, e.g. {unnamed_examples:?} (not a \
             failure for {}: the message comes from code outside src/io)",
            t.name
        );
    }
    assert!(
        failures.is_empty(),
        "{}: {} failures, the first ones:\n{}",
        t.name,
        failures.len(),
        failures[..failures.len().min(12)].join("\n")
    );
    if replay.is_none() {
        assert!(ran >= 10, "{}: only {ran} variants ran", t.name);
    }
}

// ---------------------------------------------------------------------------------------------
// Generic mutations
// ---------------------------------------------------------------------------------------------

fn pick<'a, T>(rng: &mut ChaCha8Rng, s: &'a [T]) -> &'a T {
    &s[rng.random_range(0..s.len())]
}

/// A position, half the time in the first 64 bytes (where the headers are).
fn position(rng: &mut ChaCha8Rng, len: usize) -> usize {
    if rng.random_bool(0.5) {
        rng.random_range(0..len.min(64))
    } else {
        rng.random_range(0..len)
    }
}

fn flip(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.is_empty() {
        b.push(rng.random());
        return "push".into();
    }
    let n = rng.random_range(1..=8);
    for _ in 0..n {
        let i = position(rng, b.len());
        b[i] = match rng.random_range(0..4) {
            0 => b[i] ^ (1 << rng.random_range(0..8)),
            1 => rng.random(),
            2 => *pick(rng, &[0u8, 0xff, 0x7f, 0x80, b'0', b' ', b'\n']),
            _ => b[i].wrapping_add(*pick(rng, &[1u8, 0xff])),
        };
    }
    format!("{n} byte flips")
}

fn truncate(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let at = if b.is_empty() {
        0
    } else {
        position(rng, b.len())
    };
    b.truncate(at);
    format!("truncated to {at}")
}

fn extend(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let n = rng.random_range(1..=256);
    if rng.random_bool(0.5) || b.is_empty() {
        for _ in 0..n {
            b.push(rng.random());
        }
        format!("{n} random bytes appended")
    } else {
        let n = n.min(b.len());
        let start = rng.random_range(0..=b.len() - n);
        let chunk = b[start..start + n].to_vec();
        b.extend_from_slice(&chunk);
        format!("{n} own bytes appended")
    }
}

fn splice(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.len() < 2 {
        return flip(rng, b);
    }
    let n = rng.random_range(1..=b.len().min(64));
    let from = rng.random_range(0..=b.len() - n);
    let to = rng.random_range(0..=b.len() - n);
    let chunk = b[from..from + n].to_vec();
    b[to..to + n].copy_from_slice(&chunk);
    format!("{n} bytes copied from {from} to {to}")
}

const INTERESTING_U32: &[u32] = &[
    0,
    1,
    2,
    3,
    7,
    8,
    15,
    16,
    255,
    256,
    1023,
    1024,
    4095,
    4096,
    16000,
    32767,
    32768,
    46340,
    46341,
    65535,
    65536,
    100_000,
    1 << 20,
    1 << 24,
    0x7fff_fffe,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_fffe,
    0xffff_ffff,
];

fn interesting_u32(rng: &mut ChaCha8Rng) -> u32 {
    if rng.random_bool(0.8) {
        *pick(rng, INTERESTING_U32)
    } else {
        rng.random()
    }
}

fn interesting_u64(rng: &mut ChaCha8Rng) -> u64 {
    match rng.random_range(0..4) {
        0 => u64::from(interesting_u32(rng)),
        1 => *pick(
            rng,
            &[
                u64::MAX,
                u64::MAX - 7,
                1 << 32,
                1 << 40,
                1 << 62,
                i64::MAX as u64,
                100 << 20,
            ],
        ),
        _ => rng.random(),
    }
}

/// Overwrites a u8/u16/u32/u64 (either endianness) in the first 512 bytes.
fn overwrite_int(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let width = *pick(rng, &[1usize, 2, 4, 8]);
    if b.len() < width {
        return extend(rng, b);
    }
    let at = rng.random_range(0..=b.len().min(512) - width.min(b.len().min(512)));
    let v = interesting_u64(rng);
    let big = rng.random_bool(0.5);
    let bytes = if big {
        v.to_be_bytes()[8 - width..].to_vec()
    } else {
        v.to_le_bytes()[..width].to_vec()
    };
    b[at..at + width].copy_from_slice(&bytes);
    format!(
        "u{} {} {v:#x} at {at}",
        8 * width,
        if big { "BE" } else { "LE" }
    )
}

// ---------------------------------------------------------------------------------------------
// Format-aware edits
// ---------------------------------------------------------------------------------------------

fn flo_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.len() < 12 {
        return extend(rng, b);
    }
    let int = |rng: &mut ChaCha8Rng| -> i32 {
        if rng.random_bool(0.2) {
            -(interesting_u32(rng) as i32).wrapping_abs()
        } else {
            interesting_u32(rng) as i32
        }
    };
    match rng.random_range(0..5) {
        0 => {
            let v = int(rng);
            b[4..8].copy_from_slice(&v.to_le_bytes());
            format!(".flo width {v}")
        }
        1 => {
            let v = int(rng);
            b[8..12].copy_from_slice(&v.to_le_bytes());
            format!(".flo height {v}")
        }
        2 => {
            let (w, h) = (int(rng), int(rng));
            b[4..8].copy_from_slice(&w.to_le_bytes());
            b[8..12].copy_from_slice(&h.to_le_bytes());
            format!(".flo size {w}x{h}")
        }
        3 => {
            let (w, h) = (b[4..8].to_vec(), b[8..12].to_vec());
            b[4..8].copy_from_slice(&h);
            b[8..12].copy_from_slice(&w);
            ".flo width and height swapped".into()
        }
        _ => {
            let m: f32 = *pick(rng, &[202021.0, 202021.26, -202021.25, f32::NAN, 0.0]);
            b[0..4].copy_from_slice(&m.to_le_bytes());
            format!(".flo magic {m}")
        }
    }
}

/// Byte ranges of the first `n` whitespace-separated tokens (skipping `#` comments).
fn header_tokens(b: &[u8], n: usize) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut i = 0;
    while out.len() < n && i < b.len().min(1024) {
        if b[i].is_ascii_whitespace() {
            i += 1;
        } else if b[i] == b'#' {
            while i < b.len() && b[i] != b'\n' {
                i += 1;
            }
        } else {
            let s = i;
            while i < b.len() && !b[i].is_ascii_whitespace() && b[i] != b'#' {
                i += 1;
            }
            out.push((s, i));
            // A magic like "PF" or "P6" is directly followed by whitespace; keep going.
        }
    }
    out
}

fn token_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>, n: usize, reps: &[&str]) -> String {
    let toks = header_tokens(b, n);
    if toks.is_empty() {
        return flip(rng, b);
    }
    let i = rng.random_range(0..toks.len());
    let (s, e) = toks[i];
    match rng.random_range(0..10) {
        0 => {
            b.splice(e..e, b" # comment\n".iter().copied());
            format!("comment after token {i}")
        }
        1 => {
            let end = toks.last().map_or(0, |t| t.1);
            let rep: &[u8] = pick::<&[u8]>(rng, &[&b""[..], b"\r\n", b"\n\n", b"  ", b"\t"]);
            let ws_end = end + b[end..].iter().take(1).count();
            b.splice(end..ws_end, rep.iter().copied());
            format!("separator after the header -> {rep:?}")
        }
        _ => {
            let rep = if rng.random_bool(0.85) {
                pick(rng, reps).to_string()
            } else {
                (0..rng.random_range(1..=30))
                    .map(|_| char::from(b'0' + rng.random_range(0..10u8)))
                    .collect()
            };
            b.splice(s..e, rep.bytes());
            format!("token {i} -> {rep:?}")
        }
    }
}

const NUMBER_TOKENS: &[&str] = &[
    "0",
    "1",
    "2",
    "3",
    "-1",
    "-0",
    "+3",
    "255",
    "256",
    "16000",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "4294967295",
    "4294967296",
    "18446744073709551615",
    "18446744073709551616",
    "99999999999999999999999",
    "1e3",
    "1.5",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e39",
    "-1e-45",
    "0x10",
    "",
    "-1.0",
    "1.0",
    "0.0",
];

fn pfm_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if rng.random_bool(0.15) {
        let m: &[u8] = pick::<&[u8]>(rng, &[&b"PF"[..], b"Pf", b"pf", b"P6", b"PF4"]);
        let n = b.len().min(2);
        b.splice(0..n, m.iter().copied());
        return format!("magic {:?}", String::from_utf8_lossy(m));
    }
    token_edit(rng, b, 4, NUMBER_TOKENS)
}

fn ppm_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if rng.random_bool(0.15) {
        let m: &[u8] = pick::<&[u8]>(rng, &[&b"P6"[..], b"P5", b"P3", b"P2", b"P7", b"P1", b"P4"]);
        let n = b.len().min(2);
        b.splice(0..n, m.iter().copied());
        return format!("magic {:?}", String::from_utf8_lossy(m));
    }
    token_edit(rng, b, 4, NUMBER_TOKENS)
}

/// Replaces the value of `key` in a `.npy` header dictionary (the reader's own delimiting).
fn replace_dict_value(header: &str, key: &str, new: &str) -> Option<String> {
    let at = header.find(&format!("'{key}'"))?;
    let after = at + key.len() + 2;
    let colon = after + header[after..].find(':')? + 1;
    let rest = &header[colon..];
    let lead = rest.len() - rest.trim_start().len();
    let start = colon + lead;
    let rest = &header[start..];
    let end = if rest.starts_with('(') {
        start + rest.find(')')? + 1
    } else {
        start + rest.find([',', '}']).unwrap_or(rest.len())
    };
    Some(format!("{}{new}{}", &header[..start], &header[end..]))
}

fn npy_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.len() < 12 || !b.starts_with(b"\x93NUMPY") {
        return flip(rng, b);
    }
    let major = b[6];
    let (len, start) = if major == 1 {
        (usize::from(u16::from_le_bytes([b[8], b[9]])), 10)
    } else {
        (u32::from_le_bytes([b[8], b[9], b[10], b[11]]) as usize, 12)
    };
    let end = (start + len).min(b.len());
    let header: String = b[start..end].iter().map(|&c| c as char).collect();
    let edited = match rng.random_range(0..7) {
        0 => {
            let d = pick(
                rng,
                &[
                    "'<f4'", "'>f4'", "'<f8'", "'|u1'", "'<u2'", "'>u2'", "'<f2'", "'|b1'",
                    "'<i8'", "'<c8'", "'|O'", "'<U10'", "''", "'<f4", "<f4", "'\u{e9}'",
                ],
            );
            replace_dict_value(&header, "descr", d).map(|h| (h, format!("descr {d}")))
        }
        1 | 2 => {
            let s = pick(
                rng,
                &[
                    "()",
                    "(0,)",
                    "(0, 0)",
                    "(0, 5)",
                    "(1,)",
                    "(5,)",
                    "(3, 1)",
                    "(1, 1)",
                    "(1, 1, 1, 1)",
                    "(99999999, 99999999)",
                    "(18446744073709551615, 2)",
                    "(18446744073709551616, 2)",
                    "(4294967296, 4294967296, 3)",
                    "(4611686018427387904, 4, 1)",
                    "(-1, 5)",
                    "(5, 5, 0)",
                    "(2, 2, 5)",
                    "(5, 5, 2)",
                    "(2, 5, 5)",
                    "(1e3, 2)",
                    "(2 3)",
                    "(,)",
                    "((2, 3))",
                    "[2, 3]",
                    "(3, 129, 129)",
                    "(129, 129, 3)",
                    "(1024, 1024, 4)",
                    "(2000, 2000)",
                    "(16000, 16000)",
                ],
            );
            replace_dict_value(&header, "shape", s).map(|h| (h, format!("shape {s}")))
        }
        3 => {
            let f = pick(rng, &["True", "False", "1", "None", "'False'", ""]);
            replace_dict_value(&header, "fortran_order", f).map(|h| (h, format!("fortran {f}")))
        }
        4 => {
            let v = *pick(rng, &[0u8, 1, 2, 3, 4, 255]);
            b[6] = v;
            return format!("version byte {v}");
        }
        5 => {
            let v = interesting_u32(rng);
            if major == 1 {
                b[8..10].copy_from_slice(&(v as u16).to_le_bytes());
            } else {
                b[8..12].copy_from_slice(&v.to_le_bytes());
            }
            return format!("header length {v}");
        }
        _ => {
            let key = pick(rng, &["descr", "shape", "fortran_order"]);
            Some((
                header.replace(&format!("'{key}'"), "'gone'"),
                format!("{key} renamed"),
            ))
        }
    };
    let Some((new_header, desc)) = edited else {
        return flip(rng, b);
    };
    let fix = rng.random_bool(0.7);
    let mut out = b[..start].to_vec();
    if fix {
        if major == 1 {
            out[8..10].copy_from_slice(&(new_header.len() as u16).to_le_bytes());
        } else {
            out[8..12].copy_from_slice(&(new_header.len() as u32).to_le_bytes());
        }
    }
    out.extend(new_header.chars().map(|c| c as u32 as u8));
    out.extend_from_slice(&b[end..]);
    *b = out;
    format!("{desc}{}", if fix { " (length fixed)" } else { "" })
}

fn crc_table() -> &'static [u32; 256] {
    static T: OnceLock<[u32; 256]> = OnceLock::new();
    T.get_or_init(|| {
        let mut t = [0u32; 256];
        for (i, e) in t.iter_mut().enumerate() {
            let mut c = i as u32;
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    0xedb8_8320 ^ (c >> 1)
                } else {
                    c >> 1
                };
            }
            *e = c;
        }
        t
    })
}

/// CRC-32 as PNG uses it.
fn crc32(data: &[u8]) -> u32 {
    let t = crc_table();
    let mut c = 0xffff_ffffu32;
    for &b in data {
        c = t[((c ^ u32::from(b)) & 0xff) as usize] ^ (c >> 8);
    }
    !c
}

/// PNG chunks: (offset of the length field, data length) while they fit in the file.
fn png_chunks(b: &[u8]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    let mut at = 8;
    while at + 12 <= b.len() {
        let len = u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]]) as usize;
        if at + 12 + len > b.len() {
            break;
        }
        out.push((at, len));
        at += 12 + len;
    }
    out
}

/// Recomputes the CRC of every complete chunk, so that mutations reach past the CRC checks.
#[allow(clippy::ptr_arg)] // an `Edit`, whose signature takes the Vec
fn png_fix_crcs(_: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    for (at, len) in png_chunks(b) {
        let crc = crc32(&b[at + 4..at + 8 + len]);
        b[at + 8 + len..at + 12 + len].copy_from_slice(&crc.to_be_bytes());
    }
    "chunk CRCs fixed".into()
}

/// Sets the declared size in a PNG's IHDR and fixes its CRC.
fn png_set_size(b: &mut [u8], w: u32, h: u32) {
    b[16..20].copy_from_slice(&w.to_be_bytes());
    b[20..24].copy_from_slice(&h.to_be_bytes());
    let crc = crc32(&b[12..29]);
    b[29..33].copy_from_slice(&crc.to_be_bytes());
}

fn png_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.len() < 33 || &b[12..16] != b"IHDR" {
        return flip(rng, b);
    }
    let desc = match rng.random_range(0..6) {
        0 => {
            let v = interesting_u32(rng);
            b[16..20].copy_from_slice(&v.to_be_bytes());
            format!("IHDR width {v}")
        }
        1 => {
            let v = interesting_u32(rng);
            b[20..24].copy_from_slice(&v.to_be_bytes());
            format!("IHDR height {v}")
        }
        2 => {
            let (w, h) = *pick(
                rng,
                &[
                    (16000u32, 16000u32),
                    (1, 0xffff_ffff),
                    (0xffff_ffff, 1),
                    (0, 5),
                    (1448, 1448),
                    (1449, 1449),
                    (65535, 65535),
                    (2048, 1024),
                ],
            );
            b[16..20].copy_from_slice(&w.to_be_bytes());
            b[20..24].copy_from_slice(&h.to_be_bytes());
            format!("IHDR size {w}x{h}")
        }
        3 => {
            let (i, vals): (usize, &[u8]) = *pick(
                rng,
                &[
                    (24usize, &[0u8, 1, 2, 4, 8, 16, 3, 32, 255][..]),
                    (25, &[0u8, 2, 3, 4, 6, 1, 5, 7, 255][..]),
                    (26, &[0u8, 1][..]),
                    (27, &[0u8, 1][..]),
                    (28, &[0u8, 1, 2][..]),
                ],
            );
            let v = *pick(rng, vals);
            b[i] = v;
            format!("IHDR byte {i} = {v}")
        }
        4 => {
            let chunks = png_chunks(b);
            if chunks.is_empty() {
                return flip(rng, b);
            }
            let (at, _) = *pick(rng, &chunks);
            let v = interesting_u32(rng);
            b[at..at + 4].copy_from_slice(&v.to_be_bytes());
            return format!("chunk at {at} length {v}");
        }
        _ => {
            // Drop or repeat a chunk.
            let chunks = png_chunks(b);
            if chunks.len() < 2 {
                return flip(rng, b);
            }
            let (at, len) = chunks[rng.random_range(1..chunks.len())];
            let chunk = b[at..at + 12 + len].to_vec();
            if rng.random_bool(0.5) {
                b.drain(at..at + 12 + len);
                return format!("chunk at {at} dropped");
            }
            b.splice(at..at, chunk);
            return format!("chunk at {at} repeated");
        }
    };
    if rng.random_bool(0.5) {
        let crc = crc32(&b[12..29]);
        b[29..33].copy_from_slice(&crc.to_be_bytes());
        format!("{desc} (CRC fixed)")
    } else {
        desc
    }
}

fn jpeg_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let sof = (2..b.len().saturating_sub(10))
        .find(|&p| b[p] == 0xff && (0xc0..=0xc3).contains(&b[p + 1]));
    let Some(p) = sof else {
        return flip(rng, b);
    };
    let u16v = |rng: &mut ChaCha8Rng| *pick(rng, &[0u16, 1, 2, 7, 8, 9, 255, 16000, 65500, 65535]);
    match rng.random_range(0..5) {
        0 => {
            let v = u16v(rng);
            b[p + 5..p + 7].copy_from_slice(&v.to_be_bytes());
            format!("SOF height {v}")
        }
        1 => {
            let v = u16v(rng);
            b[p + 7..p + 9].copy_from_slice(&v.to_be_bytes());
            format!("SOF width {v}")
        }
        2 => {
            let v = *pick(rng, &[0u8, 1, 2, 3, 4, 255]);
            b[p + 9] = v;
            format!("SOF components {v}")
        }
        3 => {
            let v = *pick(rng, &[0u8, 8, 12, 16, 255]);
            b[p + 4] = v;
            format!("SOF precision {v}")
        }
        _ => {
            // The length of a random marker segment.
            let markers: Vec<usize> = (2..b.len().saturating_sub(4))
                .filter(|&q| b[q] == 0xff && (0xc0..=0xfe).contains(&b[q + 1]) && b[q + 1] != 0xd8)
                .take(32)
                .collect();
            if markers.is_empty() {
                return flip(rng, b);
            }
            let q = *pick(rng, &markers);
            let v = u16v(rng);
            b[q + 2..q + 4].copy_from_slice(&v.to_be_bytes());
            format!("segment at {q} length {v}")
        }
    }
}

fn tiff_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if b.len() < 8 {
        return flip(rng, b);
    }
    let le = b.starts_with(b"II");
    let rd16 = |b: &[u8], i: usize| {
        let a = [b[i], b[i + 1]];
        if le {
            u16::from_le_bytes(a)
        } else {
            u16::from_be_bytes(a)
        }
    };
    let rd32 = |b: &[u8], i: usize| {
        let a = [b[i], b[i + 1], b[i + 2], b[i + 3]];
        if le {
            u32::from_le_bytes(a)
        } else {
            u32::from_be_bytes(a)
        }
    };
    let w32 = |v: u32| if le { v.to_le_bytes() } else { v.to_be_bytes() };
    let w16 = |v: u16| if le { v.to_le_bytes() } else { v.to_be_bytes() };
    let ifd = rd32(b, 4) as usize;
    if ifd + 2 > b.len() || rng.random_bool(0.1) {
        let v = interesting_u32(rng);
        b[4..8].copy_from_slice(&w32(v));
        return format!("IFD offset {v}");
    }
    let n = usize::from(rd16(b, ifd)).min((b.len() - ifd - 2) / 12);
    if n == 0 {
        return flip(rng, b);
    }
    let e = ifd + 2 + 12 * rng.random_range(0..n);
    let tag = rd16(b, e);
    match rng.random_range(0..5) {
        0 => {
            let v = interesting_u32(rng);
            if rd16(b, e + 2) == 3 {
                b[e + 8..e + 10].copy_from_slice(&w16(v as u16));
            } else {
                b[e + 8..e + 12].copy_from_slice(&w32(v));
            }
            format!("tag {tag} value {v}")
        }
        1 => {
            let v = interesting_u32(rng);
            b[e + 4..e + 8].copy_from_slice(&w32(v));
            format!("tag {tag} count {v}")
        }
        2 => {
            let v = rng.random_range(0..=20u16);
            b[e + 2..e + 4].copy_from_slice(&w16(v));
            format!("tag {tag} type {v}")
        }
        3 => {
            let v = *pick(
                rng,
                &[
                    256u16, 257, 258, 259, 262, 273, 277, 278, 279, 284, 317, 322, 323, 324, 325,
                    338, 339,
                ],
            );
            b[e..e + 2].copy_from_slice(&w16(v));
            format!("tag {tag} -> {v}")
        }
        _ => {
            // Width or height, whichever this file stores, to a large or odd value.
            let v = *pick(rng, &[0u32, 1, 16000, 60000, 65535, 1 << 20, 0xffff_ffff]);
            let mut hit = String::from("no size tag");
            for i in 0..n {
                let e = ifd + 2 + 12 * i;
                if matches!(rd16(b, e), 256 | 257) && rng.random_bool(0.7) {
                    if rd16(b, e + 2) == 3 {
                        b[e + 8..e + 10].copy_from_slice(&w16(v as u16));
                    } else {
                        b[e + 8..e + 12].copy_from_slice(&w32(v));
                    }
                    hit = format!("size tags = {v}");
                }
            }
            hit
        }
    }
}

/// EXR header attributes: (name, offset of the size field, value offset, value length), and the
/// offset just after the header.
fn exr_attrs(b: &[u8]) -> (Vec<(String, usize, usize, usize)>, usize) {
    let mut out = Vec::new();
    let mut at = 8;
    let cstr = |at: usize| -> Option<(String, usize)> {
        let end = at + b.get(at..)?.iter().take(256).position(|&c| c == 0)?;
        Some((String::from_utf8_lossy(&b[at..end]).into_owned(), end + 1))
    };
    while let Some((name, next)) = cstr(at) {
        if name.is_empty() {
            return (out, next);
        }
        let Some((_, next)) = cstr(next) else { break };
        let Some(size) = b.get(next..next + 4) else {
            break;
        };
        let size = i32::from_le_bytes([size[0], size[1], size[2], size[3]]);
        if size < 0 || next + 4 + size as usize > b.len() {
            break;
        }
        out.push((name, next, next + 4, size as usize));
        at = next + 4 + size as usize;
    }
    (out, b.len())
}

fn exr_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let (attrs, header_end) = exr_attrs(b);
    if attrs.is_empty() {
        return flip(rng, b);
    }
    let int = |rng: &mut ChaCha8Rng| -> i32 {
        if rng.random_bool(0.3) {
            *pick(rng, &[-1i32, -2, i32::MIN, -16000])
        } else {
            interesting_u32(rng) as i32
        }
    };
    let find = |n: &str| attrs.iter().find(|a| a.0 == n).cloned();
    match rng.random_range(0..6) {
        0 => {
            let name = *pick(rng, &["dataWindow", "displayWindow"]);
            let Some((_, _, v, len)) = find(name) else {
                return flip(rng, b);
            };
            if len < 4 {
                return flip(rng, b);
            }
            let k = rng.random_range(0..len / 4);
            let x = int(rng);
            b[v + 4 * k..v + 4 * k + 4].copy_from_slice(&x.to_le_bytes());
            format!("{name}[{k}] = {x}")
        }
        1 => {
            let (name, _, v, len) = pick(rng, &attrs).clone();
            if len < 4 {
                return flip(rng, b);
            }
            let k = rng.random_range(0..=len - 4);
            let x = int(rng);
            b[v + k..v + k + 4].copy_from_slice(&x.to_le_bytes());
            format!("{name} +{k} = {x}")
        }
        2 => {
            let (name, s, _, _) = pick(rng, &attrs).clone();
            let x = int(rng);
            b[s..s + 4].copy_from_slice(&x.to_le_bytes());
            format!("{name} size = {x}")
        }
        3 => {
            // A channel's pixel type or sampling.
            let Some((_, _, v, len)) = find("channels") else {
                return flip(rng, b);
            };
            let end = v + len;
            let Some(nul) = b[v..end].iter().position(|&c| c == 0) else {
                return flip(rng, b);
            };
            let fields = v + nul + 1;
            if fields + 16 > end {
                return flip(rng, b);
            }
            let (off, vals): (usize, &[i32]) = *pick(
                rng,
                &[
                    (0usize, &[0i32, 1, 2, 3, -1, 255][..]),
                    (8, &[0i32, 2, 3, -1, 1 << 30][..]),
                    (12, &[0i32, 2, 3, -1, 1 << 30][..]),
                ],
            );
            let x = *pick(rng, vals);
            b[fields + off..fields + off + 4].copy_from_slice(&x.to_le_bytes());
            format!("channel field +{off} = {x}")
        }
        4 => {
            let Some((_, _, v, _)) = find("compression") else {
                return flip(rng, b);
            };
            let x = rng.random_range(0..=12u8);
            b[v] = x;
            format!("compression {x}")
        }
        _ => {
            // An entry of the chunk offset table.
            if header_end + 8 > b.len() {
                return flip(rng, b);
            }
            let k = rng.random_range(0..((b.len() - header_end) / 8).clamp(1, 16));
            let at = header_end + 8 * k;
            if at + 8 > b.len() {
                return flip(rng, b);
            }
            let x = interesting_u64(rng);
            b[at..at + 8].copy_from_slice(&x.to_le_bytes());
            format!("offset table[{k}] = {x}")
        }
    }
}

const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "3",
    "7",
    "8",
    "9",
    "64",
    "255",
    "256",
    "1000",
    "4096",
    "65536",
    "100000",
    "100000000",
    "1000000000",
    "4294967296",
    "1000000000000",
    "9007199254740993",
    "18446744073709551615",
    "18446744073709551616",
    "-9223372036854775808",
    "0.5",
    "-0.5",
    "1e-300",
    "1e300",
    "1.7976931348623157e308",
    "-1e308",
];

fn json_node_paths(v: &Value, prefix: &mut Vec<Seg>, out: &mut Vec<Vec<Seg>>) {
    out.push(prefix.clone());
    match v {
        Value::Array(a) => {
            for (i, x) in a.iter().enumerate() {
                prefix.push(Seg::I(i));
                json_node_paths(x, prefix, out);
                prefix.pop();
            }
        }
        Value::Object(m) => {
            for (k, x) in m {
                prefix.push(Seg::K(k.clone()));
                json_node_paths(x, prefix, out);
                prefix.pop();
            }
        }
        _ => {}
    }
}

#[derive(Clone, Debug)]
enum Seg {
    I(usize),
    K(String),
}

fn json_at<'a>(v: &'a mut Value, path: &[Seg]) -> Option<&'a mut Value> {
    let mut cur = v;
    for s in path {
        cur = match s {
            Seg::I(i) => cur.get_mut(*i)?,
            Seg::K(k) => cur.get_mut(k.as_str())?,
        };
    }
    Some(cur)
}

/// Changes one node of a JSON value; returns what it did.
fn mutate_json(rng: &mut ChaCha8Rng, root: &mut Value) -> String {
    let mut paths = Vec::new();
    json_node_paths(root, &mut Vec::new(), &mut paths);
    let path = pick(rng, &paths).clone();
    let Some(node) = json_at(root, &path) else {
        return "nothing".into();
    };
    let desc = format!("{path:?}");
    match node {
        Value::Number(_) => {
            let n = *pick(rng, NUMBERS);
            *node = serde_json::from_str(n).unwrap_or(Value::Null);
            format!("{desc} = {n}")
        }
        Value::String(_) => {
            let s = match rng.random_range(0..12) {
                0 => "a".repeat(10_000),
                1 => "\u{0}".into(),
                2 => "nonexistent/file.png".into(),
                _ => pick(
                    rng,
                    &[
                        "",
                        "x",
                        "default",
                        "delta",
                        "none",
                        "group",
                        "instance",
                        "poly",
                        "kalman",
                        "chairs",
                        "rocket",
                        "disc",
                        "dataset",
                        "line",
                        "spiral",
                        "random",
                        "sinusoid",
                        "mms",
                        "mms-small",
                        "-1",
                        "1e9",
                        "NaN",
                    ],
                )
                .to_string(),
            };
            let short: String = s.chars().take(16).collect();
            *node = Value::String(s);
            format!("{desc} = {short:?}")
        }
        Value::Bool(b) => {
            *node = if rng.random_bool(0.7) {
                Value::Bool(!*b)
            } else {
                Value::Null
            };
            format!("{desc} flipped")
        }
        Value::Null => {
            *node = pick(
                rng,
                &[Value::from(0), Value::from("x"), Value::Array(vec![])],
            )
            .clone();
            format!("{desc} null replaced")
        }
        Value::Array(a) => match rng.random_range(0..5) {
            0 => {
                a.clear();
                format!("{desc} emptied")
            }
            1 if !a.is_empty() => {
                let n = *pick(rng, &[1usize, 2, 7, 100, 1000]);
                let x = a[0].clone();
                a.extend(std::iter::repeat_n(x, n));
                format!("{desc} +{n} copies")
            }
            2 if !a.is_empty() => {
                a.remove(rng.random_range(0..a.len()));
                format!("{desc} element removed")
            }
            3 => {
                a.push(Value::from(*pick(rng, &[0i64, -1, 1 << 40])));
                format!("{desc} number pushed")
            }
            _ => {
                *node = Value::from(3);
                format!("{desc} -> 3")
            }
        },
        Value::Object(m) => match rng.random_range(0..4) {
            0 if !m.is_empty() => {
                let k = m.keys().nth(rng.random_range(0..m.len())).cloned().unwrap();
                m.remove(&k);
                format!("{desc} key {k} removed")
            }
            1 => {
                m.insert("bogus_key".into(), Value::from(1));
                format!("{desc} unknown key added")
            }
            2 => {
                *node = Value::Array(vec![]);
                format!("{desc} -> []")
            }
            _ => {
                *node = Value::Null;
                format!("{desc} -> null")
            }
        },
    }
}

fn json_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    if rng.random_bool(0.05) {
        let depth = *pick(rng, &[64usize, 200, 100_000]);
        let mut out = b"{\"x\": ".to_vec();
        out.extend(std::iter::repeat_n(b'[', depth));
        *b = out;
        return format!("nested {depth} deep");
    }
    let Ok(mut v) = serde_json::from_slice::<Value>(b) else {
        return flip(rng, b);
    };
    let mut desc = Vec::new();
    for _ in 0..rng.random_range(1..=3) {
        desc.push(mutate_json(rng, &mut v));
    }
    *b = serde_json::to_vec_pretty(&v).unwrap();
    desc.join(", ")
}

/// The header of safetensors bytes: (JSON value, header length), when it parses.
fn st_header(b: &[u8]) -> Option<(Value, usize)> {
    let n = u64::from_le_bytes(b.get(..8)?.try_into().ok()?) as usize;
    let text = b.get(8..8usize.checked_add(n)?)?;
    Some((serde_json::from_slice(text).ok()?, n))
}

fn st_rebuild(b: &mut Vec<u8>, header: &Value, old_len: usize) {
    let mut text = serde_json::to_vec(header).unwrap();
    while !text.len().is_multiple_of(8) {
        text.push(b' ');
    }
    let mut out = (text.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(&text);
    out.extend_from_slice(&b[8 + old_len..]);
    *b = out;
}

fn safetensors_edit(rng: &mut ChaCha8Rng, b: &mut Vec<u8>) -> String {
    let Some((mut header, n)) = st_header(b) else {
        return overwrite_int(rng, b);
    };
    let desc = match rng.random_range(0..6) {
        0 => {
            let v = if rng.random_bool(0.5) {
                interesting_u64(rng)
            } else {
                (n as u64).wrapping_add(*pick(rng, &[1u64, 8, u64::MAX, u64::MAX - 7]))
            };
            b[..8].copy_from_slice(&v.to_le_bytes());
            return format!("header length {v}");
        }
        1 | 2 => {
            // The model config in the metadata.
            let Some(cfg) = header
                .get("__metadata__")
                .and_then(|m| m.get(pins::flow::weights::CONFIG_KEY))
                .and_then(|c| c.as_str())
                .and_then(|c| serde_json::from_str::<Value>(c).ok())
            else {
                return flip(rng, b);
            };
            let mut cfg = cfg;
            let d = mutate_json(rng, &mut cfg);
            header["__metadata__"][pins::flow::weights::CONFIG_KEY] =
                Value::String(cfg.to_string());
            format!("model config {d}")
        }
        3 | 4 => {
            let Some(obj) = header.as_object_mut() else {
                return flip(rng, b);
            };
            let names: Vec<String> = obj
                .keys()
                .filter(|k| *k != "__metadata__")
                .cloned()
                .collect();
            if names.is_empty() {
                return flip(rng, b);
            }
            let name = pick(rng, &names).clone();
            let e = &mut obj[&name];
            match rng.random_range(0..5) {
                0 => {
                    let d = *pick(
                        rng,
                        &["F32", "F16", "BF16", "F64", "I64", "U8", "BOOL", "XX", ""],
                    );
                    e["dtype"] = Value::from(d);
                    format!("{name} dtype {d}")
                }
                1 => {
                    let shape: Vec<Value> = (0..rng.random_range(0..5))
                        .map(|_| match rng.random_range(0..4) {
                            0 => Value::from(interesting_u64(rng)),
                            1 => Value::from(-1),
                            _ => Value::from(rng.random_range(0..70u64)),
                        })
                        .collect();
                    let d = format!("{name} shape {shape:?}");
                    e["shape"] = Value::Array(shape);
                    d
                }
                2 => {
                    let (a, c) = (interesting_u64(rng), interesting_u64(rng));
                    e["data_offsets"] = serde_json::json!([a, c]);
                    format!("{name} data_offsets [{a}, {c}]")
                }
                3 => {
                    obj.remove(&name);
                    format!("{name} removed")
                }
                _ => {
                    let v = obj.remove(&name).unwrap();
                    obj.insert(format!("{name}.x"), v);
                    format!("{name} renamed")
                }
            }
        }
        _ => {
            // Raw bytes inside the header text (its length kept).
            let k = rng.random_range(1..=4);
            for _ in 0..k {
                let i = 8 + rng.random_range(0..n.max(1)).min(n.saturating_sub(1));
                if i < b.len() {
                    b[i] = *pick(
                        rng,
                        &[b'"', b'{', b'}', b'[', b']', b',', b':', b'9', b'-', 0],
                    );
                }
            }
            return format!("{k} header text bytes");
        }
    };
    st_rebuild(b, &header, n);
    desc
}

// ---------------------------------------------------------------------------------------------
// Invariants of the values readers return
// ---------------------------------------------------------------------------------------------

fn check_flow(f: &Flow) -> Option<String> {
    let (h, w) = (f.height(), f.width());
    if h == 0 || w == 0 || f.data().len() != 2 * h * w {
        return Some(format!("flow of {w}x{h} with {} values", f.data().len()));
    }
    for (i, (&u, &v)) in f.u().iter().zip(f.v()).enumerate() {
        let known = u.abs() < 1e9 && v.abs() < 1e9;
        let unknown = u.is_nan() && v.is_nan();
        if !known && !unknown {
            return Some(format!(
                "vector {i} = ({u}, {v}): unknown flow must be NaN in both components"
            ));
        }
    }
    None
}

fn check_image(im: &Image, picture: bool) -> Option<String> {
    let (c, h, w) = im.shape();
    if c == 0 || h == 0 || w == 0 || im.data().len() != c * h * w {
        return Some(format!("image {c}x{h}x{w} with {} values", im.data().len()));
    }
    if picture && !matches!(c, 1 | 3) {
        return Some(format!("read_image gave {c} channels, not 1 or 3"));
    }
    None
}

fn image_outcome(r: pins::Result<Image>, picture: bool) -> Outcome {
    r.map(|im| check_image(&im, picture))
}

fn flow_outcome(r: pins::Result<Flow>) -> Outcome {
    r.map(|f| check_flow(&f))
}

// ---------------------------------------------------------------------------------------------
// Seeds written by pins
// ---------------------------------------------------------------------------------------------

fn ramp(c: usize, h: usize, w: usize) -> Image {
    let n = c * h * w;
    Image::from_vec(
        c,
        h,
        w,
        (0..n).map(|i| (i * 37 % 101) as f32 / 100.0).collect(),
    )
    .unwrap()
}

fn small_flow(h: usize, w: usize) -> Flow {
    let mut f = Flow::from_vec(
        h,
        w,
        (0..2 * h * w)
            .map(|i| (i as f32 * 0.73).sin() * 9.0)
            .collect(),
    )
    .unwrap();
    f.set(0, 0, f32::NAN, f32::NAN);
    f
}

/// Bytes of a file written by `write` into a scratch folder.
fn written(name: &str, write: impl FnOnce(&Path) -> pins::Result<()>) -> Vec<u8> {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join(name);
    write(&p).unwrap();
    std::fs::read(&p).unwrap()
}

fn image_seeds(ext: &str) -> Vec<Seed> {
    let mut v = Vec::new();
    for (c, h, w) in [(1, 4, 5), (3, 3, 7), (4, 6, 2), (1, 1, 1), (3, 17, 9)] {
        for depth in [BitDepth::Eight, BitDepth::Sixteen] {
            let im = ramp(c, h, w);
            let name = format!("{c}x{h}x{w} {depth:?}.{ext}");
            // JPEG takes neither 16 bits nor alpha: those seeds are skipped.
            let dir = tempfile::tempdir().unwrap();
            let p = dir.path().join(format!("s.{ext}"));
            if io::write_image(&p, &im, depth).is_ok() {
                v.push(seed(name, std::fs::read(&p).unwrap(), 4));
            }
        }
    }
    v
}

// ---------------------------------------------------------------------------------------------
// The formats
// ---------------------------------------------------------------------------------------------

#[test]
fn fuzz_flo() {
    let mut seeds = vec![
        seed("3x5", io::encode_flo(&small_flow(3, 5)), 6),
        seed("1x1", io::encode_flo(&small_flow(1, 1)), 3),
        seed("8x16", io::encode_flo(&small_flow(8, 16)), 3),
    ];
    real_seeds(
        &mut seeds,
        "flo",
        &[
            "flyingchairs_crops/00001_flow.flo",
            "middlebury_rubberwhale/flow10.flo",
            "sintel_alley1/frame_0001.flo",
            "flyingchairs/0000001-gt.flo",
        ],
        1,
    );
    fuzz(Target {
        name: "flo",
        ext: "flo",
        seeds,
        edit: flo_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| {
            flow_outcome(match (file, i % 2) {
                (true, 0) => io::read_flo(p),
                (true, _) => io::read_flow(p),
                (false, 0) => io::decode_flo(b, p),
                (false, _) => io::decode_flow(b, p),
            })
        }),
    });
}

#[test]
fn fuzz_pfm_image() {
    let mut seeds = vec![
        seed(
            "grey 4x5",
            written("a.pfm", |p| io::write_pfm(p, &ramp(1, 4, 5))),
            4,
        ),
        seed(
            "colour 3x7",
            written("a.pfm", |p| io::write_pfm(p, &ramp(3, 3, 7))),
            4,
        ),
        seed(
            "big endian, comments",
            {
                let mut b = b"Pf\n# c\n 2 2 # t\n1.0\n".to_vec();
                for v in [1.0f32, 2.0, 3.0, 4.0] {
                    b.extend_from_slice(&v.to_be_bytes());
                }
                b
            },
            2,
        ),
    ];
    real_seeds(
        &mut seeds,
        "pfm-image",
        &["flyingchairs_crops/0000000-occ_weights_01.pfm"],
        2,
    );
    fuzz(Target {
        name: "pfm-image",
        ext: "pfm",
        seeds,
        edit: pfm_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| match (file, i % 2) {
            (true, 0) => image_outcome(io::read_pfm(p), false),
            (true, _) => image_outcome(io::read_image(p), true),
            (false, 0) => image_outcome(io::decode_pfm(b, p), false),
            (false, _) => image_outcome(io::decode_image(b, p), true),
        }),
    });
}

#[test]
fn fuzz_pfm_flow() {
    let seeds = vec![
        seed(
            "flow 3x5",
            written("f.pfm", |p| io::write_pfm_flow(p, &small_flow(3, 5))),
            4,
        ),
        seed(
            "flow 1x1",
            written("f.pfm", |p| io::write_pfm_flow(p, &small_flow(1, 1))),
            2,
        ),
        seed(
            "colour image 2x3",
            written("f.pfm", |p| io::write_pfm(p, &ramp(3, 2, 3))),
            2,
        ),
    ];
    fuzz(Target {
        name: "pfm-flow",
        ext: "pfm",
        seeds,
        edit: pfm_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| {
            flow_outcome(match (file, i % 2) {
                (true, 0) => io::read_pfm_flow(p),
                (true, _) => io::read_flow(p),
                (false, 0) => io::decode_pfm_flow(b, p),
                (false, _) => io::decode_flow(b, p),
            })
        }),
    });
}

#[test]
fn fuzz_kitti_flow() {
    let mut seeds = vec![
        seed(
            "kitti 3x5",
            written("k.png", |p| io::write_kitti_flow(p, &small_flow(3, 5))),
            4,
        ),
        seed(
            "kitti 16x16",
            written("k.png", |p| io::write_kitti_flow(p, &small_flow(16, 16))),
            4,
        ),
    ];
    real_seeds(&mut seeds, "kitti", &["kitti2015_000000/flow_gt.png"], 1);
    fuzz(Target {
        name: "kitti",
        ext: "png",
        seeds,
        edit: png_edit,
        post: Some(png_fix_crcs),
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| {
            let r = match (file, i % 2) {
                (true, 0) => io::read_kitti_flow(p),
                (true, _) => io::read_flow(p).map(|f| {
                    let m = f.valid_mask();
                    (f, m)
                }),
                (false, 0) => io::decode_kitti_flow(b, p),
                (false, _) => io::decode_flow(b, p).map(|f| {
                    let m = f.valid_mask();
                    (f, m)
                }),
            };
            r.map(|(f, valid)| {
                check_flow(&f).or_else(|| {
                    (valid != f.valid_mask()).then(|| "mask disagrees with the NaNs".into())
                })
            })
        }),
    });
}

#[test]
fn fuzz_npy() {
    let mut seeds = vec![
        seed("f4 grey", io::npy::encode_npy(&ramp(1, 4, 5)), 4),
        seed("f4 rgb", io::npy::encode_npy(&ramp(3, 3, 7)), 4),
        seed("f4 rgba", io::npy::encode_npy(&ramp(4, 2, 6)), 2),
    ];
    // Hand-made dtypes and a channel-last shape.
    for (descr, shape, size) in [
        ("|u1", "(3, 4, 3)", 1),
        ("<u2", "(2, 5)", 2),
        (">f8", "(2, 2, 2)", 8),
    ] {
        let dict = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}\n");
        let n: usize = shape
            .trim_matches(['(', ')'])
            .split(',')
            .map(|s| s.trim().parse::<usize>().unwrap())
            .product();
        let mut b = b"\x93NUMPY\x01\x00".to_vec();
        b.extend_from_slice(&(dict.len() as u16).to_le_bytes());
        b.extend_from_slice(dict.as_bytes());
        b.extend((0..n * size).map(|i| (i * 7) as u8));
        seeds.push(seed(format!("{descr} {shape}"), b, 2));
    }
    if let Ok(b) = std::fs::read(repo("datasets/psf/metalens_default.npy")) {
        seeds.push(seed("metalens_default.npy", b, 1));
    }
    fuzz(Target {
        name: "npy",
        ext: "npy",
        seeds,
        edit: npy_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| match (file, i % 2) {
            (true, 0) => image_outcome(io::read_npy(p), false),
            (true, _) => image_outcome(io::read_image(p), true),
            (false, 0) => image_outcome(io::decode_npy(b, p), false),
            (false, _) => image_outcome(io::decode_image(b, p), true),
        }),
    });
}

fn exr_seeds() -> Vec<Seed> {
    let mut seeds = Vec::new();
    for c in [1, 2, 3, 4] {
        seeds.push(seed(
            format!("{c} channels"),
            written("e.exr", |p| io::write_exr(p, &ramp(c, 5, 7))),
            3,
        ));
    }
    seeds.push(seed(
        "flow",
        written("f.exr", |p| io::write_flow_exr(p, &small_flow(4, 6))),
        3,
    ));
    // Every compression the exr crate writes, scan lines and tiles, f32, f16 and u32 samples.
    use exr::prelude::Compression as C;
    for (k, compression) in [
        C::Uncompressed,
        C::RLE,
        C::ZIP1,
        C::ZIP16,
        C::PIZ,
        C::PXR24,
        C::B44,
        C::B44A,
    ]
    .into_iter()
    .enumerate()
    {
        for (tiles, sample) in [(false, k % 3), (true, (k + 1) % 3)] {
            if let Some(b) = exr_encoded(compression, tiles, sample) {
                seeds.push(seed(
                    format!("{compression:?} tiles {tiles} sample {sample}"),
                    b,
                    1,
                ));
            }
        }
    }
    if let Ok(b) = std::fs::read(repo("datasets/psf/metalens_default.exr")) {
        seeds.push(seed("metalens_default.exr", b, 1));
    }
    seeds
}

/// A 13x9 R, G, B (or u, v) EXR of the given compression and layout; `sample` 0 is f32, 1 is
/// f16, 2 is u32. `None` where the exr crate does not write that combination.
fn exr_encoded(
    compression: exr::prelude::Compression,
    tiles: bool,
    sample: usize,
) -> Option<Vec<u8>> {
    use exr::prelude::*;
    let (w, h) = (13usize, 9usize);
    let plane = |k: usize| -> FlatSamples {
        let v = (0..w * h).map(move |i| ((i * k) % 97) as f32 * 0.125);
        match sample {
            0 => FlatSamples::F32(v.collect()),
            1 => FlatSamples::F16(v.map(f16::from_f32).collect()),
            _ => FlatSamples::U32(v.map(|x| x as u32).collect()),
        }
    };
    let names: &[&str] = if tiles { &["u", "v"] } else { &["R", "G", "B"] };
    let list = names
        .iter()
        .enumerate()
        .map(|(k, n)| AnyChannel::new(Text::new_or_none(*n).unwrap(), plane(k + 1)))
        .collect();
    let blocks = if tiles {
        Blocks::Tiles(Vec2(8, 4))
    } else {
        Blocks::ScanLines
    };
    let encoding = Encoding {
        compression,
        blocks,
        line_order: LineOrder::Increasing,
    };
    let image = Image::from_encoded_channels((w, h), encoding, AnyChannels::sort(list));
    let mut cur = std::io::Cursor::new(Vec::new());
    image.write().non_parallel().to_buffered(&mut cur).ok()?;
    Some(cur.into_inner())
}

#[test]
fn fuzz_exr_image() {
    fuzz(Target {
        name: "exr-image",
        ext: "exr",
        seeds: exr_seeds(),
        edit: exr_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| match (file, i % 2) {
            (true, 0) => image_outcome(io::read_exr(p), false),
            (true, _) => image_outcome(io::read_image(p), true),
            (false, 0) => image_outcome(io::decode_exr(b, p), false),
            (false, _) => image_outcome(io::decode_image(b, p), true),
        }),
    });
}

#[test]
fn fuzz_exr_flow() {
    fuzz(Target {
        name: "exr-flow",
        ext: "exr",
        seeds: exr_seeds(),
        edit: exr_edit,
        post: None,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, i| {
            flow_outcome(match (file, i % 2) {
                (true, 0) => io::read_flow_exr(p),
                (true, _) => io::read_flow(p),
                (false, 0) => io::decode_flow_exr(b, p),
                (false, _) => io::decode_flow(b, p),
            })
        }),
    });
}

fn raster_target(
    name: &'static str,
    ext: &'static str,
    seeds: Vec<Seed>,
    edit: Edit,
    post: Option<Edit>,
) {
    fuzz(Target {
        name,
        ext,
        seeds,
        edit,
        post,
        weight: 1.0,
        file_every: 16,
        names_file: true,
        extra_files: vec![],
        call: Box::new(|b, p, file, _| {
            image_outcome(
                if file {
                    io::read_image(p)
                } else {
                    io::decode_image(b, p)
                },
                true,
            )
        }),
    });
}

#[test]
fn fuzz_png() {
    let mut seeds = image_seeds("png");
    real_seeds(
        &mut seeds,
        "png",
        &[
            "flyingchairs_crops/0000000-img_0.png",
            "flyingchairs_crops/0000000-occ_01.png",
            "middlebury_rubberwhale/frame10.png",
            "kitti2015_000000/frame1.png",
            "sintel_alley1/frame_0001.png",
        ],
        1,
    );
    raster_target("png", "png", seeds, png_edit, Some(png_fix_crcs));
}

#[test]
fn fuzz_jpeg() {
    raster_target("jpeg", "jpg", image_seeds("jpg"), jpeg_edit, None);
}

#[test]
fn fuzz_ppm() {
    let mut seeds = image_seeds("ppm");
    seeds.extend(image_seeds("pgm"));
    real_seeds(
        &mut seeds,
        "ppm",
        &[
            "flyingchairs_crops/00001_img1.ppm",
            "flyingchairs/0000001-img0.ppm",
        ],
        1,
    );
    raster_target("ppm", "ppm", seeds, ppm_edit, None);
}

#[test]
fn fuzz_tiff() {
    let mut seeds = image_seeds("tif");
    real_seeds(&mut seeds, "tiff", &["psf_diffusercam/psf_sample.tif"], 1);
    raster_target("tiff", "tif", seeds, tiff_edit, None);
}

/// A tiny network's weights (fast to build and load) and the shipped `mms-small`.
fn weight_seeds(full_weight: u32) -> Vec<Seed> {
    use pins::flow::model::{Mms, MmsConfig, NormKind};
    let cfg = MmsConfig {
        name: "tiny".into(),
        encoder_dims: [8, 8, 8],
        feature_dim: 8,
        hidden_dim: 8,
        context_dim: 8,
        motion_dims: [8, 8, 8],
        head_dim: 8,
        dilations: vec![1, 2],
        corr_levels: 2,
        corr_radius: 1,
        iters: 1,
        feature_norm: NormKind::Instance,
        context_norm: NormKind::Group,
    };
    let device = burn::prelude::Device::flex();
    let model = Mms::new(&cfg, &device);
    let mut seeds = vec![seed(
        "tiny",
        pins::flow::weights::to_bytes(&model, &cfg).unwrap(),
        8,
    )];
    if full_weight > 0 {
        match std::fs::read(repo("datasets/weights/mms-small.safetensors")) {
            Ok(b) => seeds.push(seed("mms-small", b, full_weight)),
            Err(e) => eprintln!("weights: shipped mms-small not readable: {e}"),
        }
    }
    seeds
}

#[test]
fn fuzz_weights_config() {
    let mut seeds = weight_seeds(0);
    // The shipped file's header alone (read_config reads nothing else).
    if let Ok(b) = std::fs::read(repo("datasets/weights/mms-small.safetensors"))
        && let Some((_, n)) = st_header(&b)
    {
        seeds.push(seed("mms-small header", b[..8 + n].to_vec(), 4));
    }
    fuzz(Target {
        name: "weights-config",
        ext: "safetensors",
        seeds,
        edit: safetensors_edit,
        post: None,
        weight: 1.0,
        file_every: u64::MAX,
        names_file: false,
        extra_files: vec![],
        call: Box::new(|b, p, _, _| pins::flow::weights::read_config(b, p).map(|_| None)),
    });
}

#[test]
fn fuzz_weights_load() {
    let device = burn::prelude::Device::flex();
    fuzz(Target {
        name: "weights-load",
        ext: "safetensors",
        seeds: weight_seeds(1),
        edit: safetensors_edit,
        post: None,
        weight: 1.0,
        file_every: u64::MAX,
        names_file: false,
        extra_files: vec![],
        call: Box::new(move |b, p, _, _| {
            pins::flow::weights::from_bytes(b, p, &device).map(|_| None)
        }),
    });
}

// ---------------------------------------------------------------------------------------------
// JSON configs the CLI reads
// ---------------------------------------------------------------------------------------------

/// The experiment files whose names start with one of `prefixes`.
fn experiment_seeds(prefixes: &[&str]) -> Vec<Seed> {
    let mut v: Vec<Seed> = std::fs::read_dir(repo("experiments"))
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            n.ends_with(".json") && prefixes.iter().any(|x| n.starts_with(x))
        })
        .map(|p| {
            let n = p.file_name().unwrap().to_string_lossy().into_owned();
            seed(n, std::fs::read(&p).unwrap(), 1)
        })
        .collect();
    v.sort_by(|a, b| a.name.cmp(&b.name));
    v
}

fn json_target(
    name: &'static str,
    seeds: Vec<Seed>,
    extra_files: Vec<Seed>,
    names_file: bool,
    call: Call<'_>,
) {
    fuzz(Target {
        name,
        ext: "json",
        seeds,
        edit: json_edit,
        post: None,
        weight: 0.4,
        file_every: 1,
        names_file,
        extra_files,
        call,
    });
}

fn pretty<T: serde::Serialize>(v: &T) -> Vec<u8> {
    serde_json::to_vec_pretty(v).unwrap()
}

#[test]
fn fuzz_json_generator_config() {
    use pins::dataset::GeneratorConfig;
    let mut seeds = experiment_seeds(&["chairs_", "s12_", "real_", "eval_", "train_data"]);
    seeds.push(seed("default", pretty(&GeneratorConfig::default()), 2));
    json_target(
        "json-generator",
        seeds,
        vec![],
        true,
        Box::new(|_, p, _, _| GeneratorConfig::from_file(p).map(|_| None)),
    );
}

#[test]
fn fuzz_json_train_config() {
    use pins::flow::train::TrainConfig;
    let mut seeds = experiment_seeds(&["train_small"]);
    seeds.push(seed("default", pretty(&TrainConfig::default()), 2));
    json_target(
        "json-train",
        seeds,
        vec![],
        true,
        Box::new(|_, p, _, _| TrainConfig::from_file(p).map(|_| None)),
    );
}

#[test]
fn fuzz_json_camera_config() {
    use pins::imaging::CameraConfig;
    let seeds = vec![seed("default", pretty(&CameraConfig::default()), 1)];
    // As `pins simulate --config` reads it: serde, then validate (no file name to give).
    json_target(
        "json-camera",
        seeds,
        vec![],
        false,
        Box::new(
            |b, _, _, _| match serde_json::from_slice::<CameraConfig>(b) {
                Ok(c) => c.validate().map(|_| None),
                Err(_) => Ok(None),
            },
        ),
    );
}

#[test]
fn fuzz_json_sequence_config() {
    use pins::dataset::sequence::SequenceConfig;
    let mut seeds = experiment_seeds(&[
        "track_five",
        "track_note",
        "track_random",
        "track_sinusoid",
        "track_spiral",
    ]);
    seeds.push(seed("default", pretty(&SequenceConfig::default()), 1));
    json_target(
        "json-sequence",
        seeds,
        vec![],
        true,
        Box::new(|_, p, _, _| SequenceConfig::from_file(p).map(|_| None)),
    );
}

#[test]
fn fuzz_json_experiment_config() {
    use pins::track::experiment::ExperimentConfig;
    // The clips an experiment names lie beside it.
    json_target(
        "json-experiment",
        experiment_seeds(&["track_table"]),
        experiment_seeds(&["track_"]),
        false,
        Box::new(|_, p, _, _| ExperimentConfig::from_file(p).map(|_| None)),
    );
}

#[test]
fn fuzz_json_truth_and_tracks() {
    use pins::scene::trajectory::TrajectoryConfig;
    use pins::scene::truth::Truth;
    use pins::track::tracker::tracks::Tracks;
    let truth = Truth::of(&TrajectoryConfig::default()).unwrap();
    let tracks = br#"{"objects": [{"id": 0, "frames": [
        {"frame": 0, "centroid": [10.5, 20.0], "speed": 1.5, "direction": 0.3, "observed": true,
         "predicted": {"5": [12.0, 21.0]}},
        {"frame": 1, "centroid": [11.5, 20.5], "speed": 1.1, "direction": null, "observed": false,
         "predicted": {}}]}], "ms_per_frame": 0.25}"#;
    let seeds = vec![
        seed("truth", pretty(&truth), 1),
        seed("tracks", tracks.to_vec(), 1),
    ];
    json_target(
        "json-truth-tracks",
        seeds,
        vec![],
        true,
        Box::new(|_, p, _, i| {
            if i % 2 == 0 {
                Truth::read(p).map(|_| None)
            } else {
                Tracks::read(p).map(|_| None)
            }
        }),
    );
}

/// A calibration of the default array from the dots where the nominal model puts them.
fn calibration_seed() -> pins::wide::Calibration {
    use pins::wide::{ArrayLayout, calibrate, render};
    let layout = ArrayLayout::default();
    let (_, centres) = render::dot_grid_target(&layout, 5).unwrap();
    let mut dots = Vec::new();
    for tile in &centres {
        for &(x, y) in tile {
            if let Some((lens, sx, sy)) = render::nominal_sensor_position(&layout, x, y) {
                dots.push(calibrate::Dot {
                    lens,
                    x: sx,
                    y: sy,
                    area: 30,
                });
            }
        }
    }
    calibrate::calibrate_from_dots(&layout, &dots, 5, Some(2)).unwrap()
}

#[test]
fn fuzz_json_array_configs() {
    use pins::wide::{ArrayLayout, Stitcher, render};
    let layout = ArrayLayout::default();
    let calib = calibration_seed();
    let peers = br#"{"data": "x", "pairs": 2, "methods": [
        {"name": "OpenCV DIS medium", "epe": 2.5, "ae_deg": 3.0, "ms_per_pair": 12.0}]}"#;
    let seeds = vec![
        seed("layout", pretty(&layout), 1),
        seed("calibration", pretty(&calib), 1),
        seed("peers", peers.to_vec(), 1),
    ];
    // As `pins array` reads them: serde, then the checks the command runs before any work.
    json_target(
        "json-array",
        seeds,
        vec![],
        false,
        Box::new(|b, p, _, _| {
            if let Ok(l) = serde_json::from_slice::<ArrayLayout>(b) {
                render::check_layout(&l)?;
            }
            if let Ok(c) = serde_json::from_slice::<pins::wide::Calibration>(b) {
                Stitcher::new(&c)?;
            }
            if b.windows(9).any(|w| w == b"\"methods\"") {
                pins::report::eval_plot::read_peers(p)?;
            }
            Ok(None)
        }),
    );
}

/// Reproducer of a fuzzing find outside `src/io`: a `calib.json` whose polynomial order does
/// not match its coefficients (order 3 with the 6 coefficients of order 2) made
/// `Stitcher::new` (what `pins array stitch --calib` runs) panic in `Poly2::eval`; it is now
/// an error naming the lens and the coefficient count.
#[test]
fn inconsistent_calibration_polynomial_is_an_error() {
    let _guard = lock();
    let mut calib = calibration_seed();
    calib.lenses[0].fx.order += 1;
    // Every pixel of the map panics on a rayon worker: silence the hook so that it is quick.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let r = std::panic::catch_unwind(|| pins::wide::Stitcher::new(&calib).map(|_| ()));
    std::panic::set_hook(hook);
    assert!(
        matches!(r, Ok(Err(_))),
        "Stitcher::new panicked or accepted the calibration"
    );
}

// ---------------------------------------------------------------------------------------------
// The pixel budget, measured
// ---------------------------------------------------------------------------------------------

/// A real tiny PNG whose IHDR is patched to declare 16000×16000 (CRC fixed) is refused by
/// every reader that takes PNG, quickly and cheaply, naming the file, the size and the flag.
#[test]
fn crafted_huge_png_is_refused_before_decoding() {
    let _guard = lock();
    install_hook();
    io::set_max_pixels(io::DEFAULT_MAX_PIXELS);
    let mut grey = written("g.png", |p| {
        io::write_image(p, &ramp(1, 2, 2), BitDepth::Eight)
    });
    png_set_size(&mut grey, 16000, 16000);
    let mut kitti = written("k.png", |p| io::write_kitti_flow(p, &small_flow(2, 2)));
    png_set_size(&mut kitti, 16000, 16000);
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("huge.png");
    std::fs::write(&p, &grey).unwrap();
    let (r, peak) = measured(|| io::read_image(&p).map(|_| ()));
    let e = r.unwrap().unwrap_err().to_string();
    assert!(
        e.contains("huge.png") && e.contains("16000x16000") && e.contains("--max-pixels"),
        "{e}"
    );
    assert!(peak < 1 << 20, "refusal allocated {peak} bytes");
    std::fs::write(&p, &kitti).unwrap();
    for r in [
        measured(|| io::read_kitti_flow(&p).map(|_| ())),
        measured(|| io::read_flow(&p).map(|_| ())),
    ] {
        let e = r.0.unwrap().unwrap_err().to_string();
        assert!(
            e.contains("16000x16000") && e.contains("--max-pixels"),
            "{e}"
        );
        assert!(r.1 < 1 << 20, "refusal allocated {} bytes", r.1);
    }
}

/// Every other reader refuses a header declaring 16000×16000 before reading on, cheaply.
#[test]
fn every_reader_checks_the_budget_first() {
    let _guard = lock();
    install_hook();
    io::set_max_pixels(io::DEFAULT_MAX_PIXELS);
    let p = |ext: &str| PathBuf::from(format!("huge.{ext}"));
    let mut flo = 202021.25f32.to_le_bytes().to_vec();
    flo.extend_from_slice(&16000i32.to_le_bytes());
    flo.extend_from_slice(&16000i32.to_le_bytes());
    let pfm = b"PF\n16000 16000\n-1.0\n".to_vec();
    let npy_dict = "{'descr': '<f4', 'fortran_order': False, 'shape': (16000, 16000), }\n";
    let mut npy = b"\x93NUMPY\x01\x00".to_vec();
    npy.extend_from_slice(&(npy_dict.len() as u16).to_le_bytes());
    npy.extend_from_slice(npy_dict.as_bytes());
    let mut exr = written("e.exr", |p| io::write_exr(p, &ramp(1, 2, 2)));
    let (attrs, _) = exr_attrs(&exr);
    for (name, _, v, _) in attrs {
        if name == "dataWindow" || name == "displayWindow" {
            exr[v + 8..v + 12].copy_from_slice(&15999i32.to_le_bytes());
            exr[v + 12..v + 16].copy_from_slice(&15999i32.to_le_bytes());
        }
    }
    type Case<'a> = (&'a str, Box<dyn Fn() -> pins::Result<()> + 'a>);
    let cases: Vec<Case> = vec![
        (
            "flo",
            Box::new(|| io::decode_flo(&flo, &p("flo")).map(|_| ())),
        ),
        (
            "pfm",
            Box::new(|| io::decode_pfm(&pfm, &p("pfm")).map(|_| ())),
        ),
        (
            "pfm flow",
            Box::new(|| io::decode_pfm_flow(&pfm, &p("pfm")).map(|_| ())),
        ),
        (
            "npy",
            Box::new(|| io::decode_npy(&npy, &p("npy")).map(|_| ())),
        ),
        (
            "exr",
            Box::new(|| io::decode_exr(&exr, &p("exr")).map(|_| ())),
        ),
        (
            "exr flow",
            Box::new(|| io::decode_flow_exr(&exr, &p("exr")).map(|_| ())),
        ),
    ];
    for (what, f) in cases {
        let (r, peak) = measured(f);
        let e = r.unwrap().unwrap_err().to_string();
        assert!(
            e.contains("16000x16000") && e.contains("--max-pixels") && e.contains("huge."),
            "{what}: {e}"
        );
        assert!(peak < 1 << 20, "{what}: refusal allocated {peak} bytes");
    }
}

/// The budget is one process-wide setting: a 1200×1000 image is refused under 1 MP and read
/// once the budget is raised to 2 MP.
#[test]
fn raising_the_budget_lets_a_larger_image_through() {
    let _guard = lock();
    install_hook();
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("moderate.png");
    io::write_image(&p, &Image::filled(1, 1000, 1200, 0.25), BitDepth::Eight).unwrap();
    io::set_max_pixels(1_000_000);
    assert_eq!(io::max_pixels(), 1_000_000);
    let e = io::read_image(&p).unwrap_err().to_string();
    assert!(e.contains("1200x1000") && e.contains("--max-pixels"), "{e}");
    io::set_max_pixels(2_000_000);
    let im = io::read_image(&p).unwrap();
    assert_eq!(im.shape(), (1, 1000, 1200));
    io::set_max_pixels(io::DEFAULT_MAX_PIXELS);
}

/// A weights file whose config claims enormous widths (that validate) is refused without
/// building a network of that size (Burn creates parameters lazily; the shapes are compared
/// before any is allocated).
#[test]
fn weights_claiming_a_huge_network_are_refused_cheaply() {
    let _guard = lock();
    install_hook();
    let tiny = weight_seeds(0).remove(0).bytes;
    let (header, n) = st_header(&tiny).unwrap();
    let key = pins::flow::weights::CONFIG_KEY;
    let cfg: Value = serde_json::from_str(header["__metadata__"][key].as_str().unwrap()).unwrap();
    let device = burn::prelude::Device::flex();
    for (field, value) in [
        ("feature_dim", 1u64 << 20),
        ("hidden_dim", 1 << 16),
        ("head_dim", 1 << 24),
    ] {
        let (mut cfg, mut header) = (cfg.clone(), header.clone());
        cfg[field] = Value::from(value);
        header["__metadata__"][key] = Value::String(cfg.to_string());
        let mut b = tiny.clone();
        st_rebuild(&mut b, &header, n);
        let p = Path::new("huge.safetensors");
        let (r, peak) = measured(|| pins::flow::weights::from_bytes(&b, p, &device).map(|_| ()));
        let e = r
            .unwrap_or_else(|panic| panic!("{field}: {panic}"))
            .expect_err("loaded")
            .to_string();
        assert!(
            e.contains("huge.safetensors") && e.contains("do not fit"),
            "{e}"
        );
        assert!(peak < 64 << 20, "{field} = {value}: {peak} bytes at peak");
    }
}
