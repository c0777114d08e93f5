//! `pins pack` / `pins unpack` (WebDataset shards): reproducible bytes with fixed tar metadata,
//! an exact round trip, `pins train` and `pins eval` reading shards directly with the same
//! sample order and results as the folder, and damaged shards refused by name.

mod common;
use common::{failed, ok, pins, tiny_dataset};

use std::collections::BTreeMap;
use std::fs;
use std::path::Path;

fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let p = e.unwrap().path();
            (
                p.file_name().unwrap().to_string_lossy().into_owned(),
                fs::read(&p).unwrap(),
            )
        })
        .collect()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn packs_reproducibly_and_unpacks_exactly() {
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 7, 8);
    let (a, b) = (d.path().join("a"), d.path().join("b"));
    for out in [&a, &b] {
        let msg = ok(&pins(&[
            "pack",
            "--in",
            s(&data),
            "--out",
            s(out),
            "--samples-per-shard",
            "3",
        ]));
        assert!(msg.contains("7 samples in 3 shards"), "{msg}");
    }
    let (sa, sb) = (snapshot(&a), snapshot(&b));
    assert_eq!(sa, sb, "two packs of one folder differ");
    assert!(sa.contains_key("shard-000002.tar") && sa.contains_key("index.json"));
    assert!(sa.contains_key("config.json") && sa.contains_key("manifest.json"));
    // WebDataset members: one basename per sample, fixed metadata.
    let mut archive = tar::Archive::new(fs::File::open(a.join("shard-000000.tar")).unwrap());
    let mut names = Vec::new();
    for e in archive.entries().unwrap() {
        let e = e.unwrap();
        let h = e.header();
        assert_eq!(
            (h.mtime().unwrap(), h.uid().unwrap(), h.gid().unwrap()),
            (0, 0, 0)
        );
        assert_eq!(h.mode().unwrap(), 0o644);
        assert_eq!(h.username().unwrap(), Some(""));
        names.push(e.path().unwrap().to_string_lossy().into_owned());
    }
    assert_eq!(
        &names[..4],
        [
            "00000.img1.png",
            "00000.img2.png",
            "00000.flow.flo",
            "00000.json"
        ]
    );
    assert_eq!(names.len(), 12);
    // The round trip gives the generator's folder back, byte for byte.
    let back = d.path().join("back");
    let msg = ok(&pins(&["unpack", "--in", s(&a), "--out", s(&back)]));
    assert!(msg.contains("7 samples"), "{msg}");
    assert_eq!(snapshot(&back), snapshot(&data));
    assert!(ok(&pins(&["generate", "--verify", "--out", s(&back)])).contains("7"));
    // An existing output folder is refused, and nothing is changed.
    let err = failed(&pins(&["pack", "--in", s(&data), "--out", s(&a)]));
    assert!(err.contains("already exists"), "{err}");
    let err = failed(&pins(&["unpack", "--in", s(&a), "--out", s(&back)]));
    assert!(err.contains("already exists"), "{err}");
    assert_eq!(snapshot(&a), sb);
    let err = failed(&pins(&[
        "pack",
        "--in",
        s(&data),
        "--out",
        s(&d.path().join("z")),
        "--samples-per-shard",
        "0",
    ]));
    assert!(err.contains("--samples-per-shard"), "{err}");
    assert!(!d.path().join("z").exists());
}

#[test]
fn train_and_eval_read_shards_as_they_read_the_folder() {
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 5, 8);
    let shards = d.path().join("shards");
    ok(&pins(&[
        "pack",
        "--in",
        s(&data),
        "--out",
        s(&shards),
        "--samples-per-shard",
        "2",
    ]));
    // Evaluation: the same pairs in the same order with the same scores.
    let report = |data: &Path, name: &str| {
        let out = d.path().join(name);
        ok(&pins(&[
            "eval",
            "--data",
            s(data),
            "--iters",
            "2",
            "--out",
            s(&out.join("report.json")),
        ]));
        let v: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(out.join("report.json")).unwrap()).unwrap();
        let pairs: Vec<_> = v["per_pair"]
            .as_array()
            .expect("per_pair")
            .iter()
            .map(|p| (p["name"].clone(), p["rows"][0]["epe"].clone()))
            .collect();
        (v["rows"][0]["epe"].clone(), pairs)
    };
    let (folder, shard) = (report(&data, "eval_folder"), report(&shards, "eval_shards"));
    assert_eq!(folder.1.len(), 5);
    assert_eq!(folder, shard);
    // Training: the same steps, losses and weights.
    let cfg = d.path().join("train.json");
    fs::write(
        &cfg,
        r#"{"model": "mms-small", "steps": 3, "batch_size": 1, "crop": [64, 64], "iters": 2,
            "val_fraction": 0.2, "val_every": 3, "val_max_pairs": 1, "val_iters": 2,
            "checkpoint_every": 3}"#,
    )
    .unwrap();
    let train = |data: &Path, name: &str| {
        let out = d.path().join(name);
        ok(&pins(&[
            "train",
            "--config",
            s(&cfg),
            "--data",
            s(data),
            "--out",
            s(&out),
            "--quiet",
        ]));
        let log: Vec<String> = fs::read_to_string(out.join("log.csv"))
            .unwrap()
            .lines()
            .map(|l| {
                // Every column but the time per step.
                let mut f: Vec<&str> = l.split(',').collect();
                f.remove(5);
                f.join(",")
            })
            .collect();
        // The tensors (the files' training stamps name the data's fingerprint, which tells a
        // shard set from a folder).
        (log, common::safetensors_f32(&out.join("last.safetensors")))
    };
    let (a, b) = (train(&data, "run_folder"), train(&shards, "run_shards"));
    assert_eq!(a.0, b.0, "training logs differ");
    assert!(a.1 == b.1, "trained weights differ");
}

#[test]
fn damaged_shards_are_refused_by_name() {
    let d = tempfile::tempdir().unwrap();
    let data = tiny_dataset(d.path(), "data", 4, 8);
    let shards = d.path().join("shards");
    ok(&pins(&[
        "pack",
        "--in",
        s(&data),
        "--out",
        s(&shards),
        "--samples-per-shard",
        "2",
    ]));
    // One flipped byte inside an image: unpack checks the SHA-256 and names the shard.
    let f = shards.join("shard-000001.tar");
    let mut bytes = fs::read(&f).unwrap();
    bytes[700] ^= 0x55;
    fs::write(&f, &bytes).unwrap();
    let err = failed(&pins(&[
        "unpack",
        "--in",
        s(&shards),
        "--out",
        s(&d.path().join("u")),
    ]));
    assert!(err.contains("shard-000001.tar"), "{err}");
    assert!(!d.path().join("u").exists());
    // A truncated shard: its size no longer matches the index, for eval as for unpack.
    bytes.truncate(1000);
    fs::write(&f, &bytes).unwrap();
    let err = failed(&pins(&["eval", "--data", s(&shards), "--iters", "1"]));
    assert!(
        err.contains("shard-000001.tar") && err.contains("index says"),
        "{err}"
    );
    // An index that is not JSON, or of another format.
    fs::write(shards.join("index.json"), "{\"format\": \"other\"}").unwrap();
    let err = failed(&pins(&[
        "unpack",
        "--in",
        s(&shards),
        "--out",
        s(&d.path().join("u")),
    ]));
    assert!(err.contains("index.json"), "{err}");
}
