//! Tests of the training stream (`flow::train::stream`): draws by weight, crops, upscaled sources.

use super::*;

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).expect("write");
    p
}

fn folder(tag: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("pins-stream-{tag}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("dir");
    dir
}

const SMALL: &str = r#"{"count": 1, "seed": 3, "scene": {"kind": "chairs", "width": 40, "height": 32, "supersample": 1, "sprites": [1, 2]}}"#;
const LARGE: &str = r#"{"count": 1, "seed": 4, "scene": {"kind": "chairs", "width": 56, "height": 48, "supersample": 1, "sprites": [1, 2]}}"#;

/// Pairs are the generator's samples, a function of (step, slot, draw) alone; the sources
/// are drawn by weight; validation pairs take each source in proportion; the fingerprint
/// follows the weights and configs.
#[test]
fn pairs_follow_the_weights_and_repeat() {
    let dir = folder("mix");
    write(&dir, "a.json", SMALL);
    write(&dir, "b.json", LARGE);
    let mix = write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1}, {"generator": "b.json", "weight": 3}]}"#,
    );
    let stream = Stream::open(&mix).expect("open");
    assert!(is_stream_file(&mix) && !is_stream_file(&dir));
    assert_eq!(stream.smallest_frame(), (32, 40));
    // The draw by weight: about three in four from b (48 rows).
    let mut r = rng::stream(1, &[0]);
    let from_b = (0..400)
        .filter(|_| stream.source_at(r.random_range(0.0..1.0)) == 1)
        .count();
    assert!((260..=340).contains(&from_b), "{from_b} of 400 from b");
    // Validation: 1 of 4 pairs from a, in order of the shares.
    let sources: Vec<usize> = (0..4)
        .map(|j| stream.source_at((j as f64 + 0.5) / 4.0))
        .collect();
    assert_eq!(sources, [0, 1, 1, 1]);
    // A pair is made again exactly; another index is another pair.
    let pair = |step, slot| {
        let mut r = rng::stream(5, &[step as u64]);
        let (a, b, f, crop) = stream
            .train_pair(step, slot, 2, [24, 32], None, &mut r)
            .expect("pair");
        assert_eq!(crop, [24, 32], "no source has a crop of its own");
        (a, b, f)
    };
    let (a1, b1, f1) = pair(3, 1);
    let (a2, b2, f2) = pair(3, 1);
    assert_eq!(
        (a1.data(), b1.data(), f1.data()),
        (a2.data(), b2.data(), f2.data())
    );
    assert_eq!(a1.shape().0, 3);
    let (a3, _, _) = pair(4, 1);
    assert_ne!(a1.data(), a3.data());
    // The validation pair j of source b is that generator's sample VAL_BASE + j.
    let (va, _, vf) = stream.val_pair(1, 4).expect("val");
    let generator = Generator::new(GeneratorConfig::from_file(&dir.join("b.json")).unwrap())
        .expect("generator");
    let (ga, _, gf) = generator.pair(VAL_BASE + 1).expect("sample");
    assert_eq!(va.data(), crate::flow::data::to_rgb(ga).data());
    assert_eq!(Some(vf.data()), gf.as_ref().map(|f| f.data()));
    // The fingerprint changes with a weight and with a config, not with the folder.
    let f0 = stream.fingerprint().clone();
    assert_eq!(f0.pairs, 0);
    write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1}, {"generator": "b.json", "weight": 2}]}"#,
    );
    assert_ne!(Stream::open(&mix).unwrap().fingerprint(), &f0);
    let moved = folder("moved");
    for f in ["a.json", "b.json"] {
        std::fs::copy(dir.join(f), moved.join(f)).unwrap();
    }
    let text = r#"{"sources": [{"generator": "a.json", "weight": 1}, {"generator": "b.json", "weight": 3}]}"#;
    let moved_mix = write(&moved, "mix.json", text);
    assert_eq!(Stream::open(&moved_mix).unwrap().fingerprint(), &f0);
    // Nor does the layout of a config: its keys in another order, other spacing.
    let relaid: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(moved.join("a.json")).unwrap()).unwrap();
    let relaid = serde_json::to_string_pretty(&relaid).unwrap();
    assert_ne!(
        relaid,
        std::fs::read_to_string(moved.join("a.json")).unwrap()
    );
    write(&moved, "a.json", &relaid);
    assert_eq!(Stream::open(&moved_mix).unwrap().fingerprint(), &f0);
    // The scale of the weights changes neither the pairs nor the fingerprint; a seed or a
    // count (where the training indices start) does.
    let doubled = r#"{"sources": [{"generator": "a.json", "weight": 2.0}, {"generator": "b.json", "weight": 6}]}"#;
    write(&moved, "mix.json", doubled);
    assert_eq!(Stream::open(&moved_mix).unwrap().fingerprint(), &f0);
    write(
        &moved,
        "a.json",
        &SMALL.replace("\"count\": 1", "\"count\": 7"),
    );
    assert_ne!(Stream::open(&moved_mix).unwrap().fingerprint(), &f0);
    write(&moved, "a.json", SMALL);
    write(
        &moved,
        "b.json",
        &LARGE.replace("\"seed\": 4", "\"seed\": 5"),
    );
    assert_ne!(Stream::open(&moved_mix).unwrap().fingerprint(), &f0);
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&moved);
}

/// A source's training pairs start past its config's count: a stream never remakes the
/// pairs that a folder of the same config holds.
#[test]
fn training_pairs_start_past_the_count() {
    let dir = folder("count");
    write(
        &dir,
        "a.json",
        &SMALL.replace("\"count\": 1", "\"count\": 5"),
    );
    let mix = write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1}]}"#,
    );
    let stream = Stream::open(&mix).expect("open");
    let generator = Generator::new(GeneratorConfig::from_file(&dir.join("a.json")).unwrap())
        .expect("generator");
    let mut r = rng::stream(1, &[0]);
    let (a, _, _, _) = stream
        .train_pair(2, 1, 3, [24, 32], None, &mut r)
        .expect("pair");
    let (g, _, _) = generator.pair(5 + 2 * 3 + 1).expect("sample");
    assert_eq!(a.data(), crate::flow::data::to_rgb(g).data());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A movers source mixes with a chairs one: its frame counts toward the smallest, and its
/// pairs are its discs moving over a still background.
#[test]
fn a_movers_source_makes_pairs_beside_chairs() {
    let dir = folder("movers");
    write(&dir, "a.json", SMALL);
    write(
        &dir,
        "m.json",
        r#"{"count": 1, "seed": 5, "scene": {"kind": "movers", "width": 48, "height": 36, "discs": [1, 1], "radius_px": [5, 5], "speed_px": [3, 3]}}"#,
    );
    let mix = write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1}, {"generator": "m.json", "weight": 1}]}"#,
    );
    let stream = Stream::open(&mix).expect("open");
    assert_eq!(stream.smallest_frame(), (32, 40));
    let (.., flow) = stream.generators[1].pair(7).expect("pair");
    let flow = flow.expect("movers pairs have flow");
    let moving: Vec<f32> = (0..flow.height())
        .flat_map(|y| (0..flow.width()).map(move |x| (y, x)))
        .map(|(y, x)| {
            let (u, v) = flow.get(y, x);
            u.hypot(v)
        })
        .filter(|&m| m > 0.0)
        .collect();
    // One disc of radius 5 (about 79 px) moving 3 px; everything else still.
    assert!(
        (60..=100).contains(&moving.len()),
        "{} moving px",
        moving.len()
    );
    assert!(moving.iter().all(|m| (m - 3.0).abs() < 1e-3));
    let _ = std::fs::remove_dir_all(&dir);
}

/// What cannot make training pairs is refused with the file and the reason.
#[test]
fn bad_streams_are_refused() {
    let dir = folder("bad");
    write(&dir, "a.json", SMALL);
    write(
        &dir,
        "disc.json",
        r#"{"count": 1, "scene": {"kind": "disc", "radius": 5}}"#,
    );
    for (text, needle) in [
        (r#"{"sources": []}"#, "none given"),
        (
            r#"{"sources": [{"generator": "a.json", "weight": 0}]}"#,
            "positive",
        ),
        (
            r#"{"sources": [{"generator": "a.json", "weight": -1}]}"#,
            "positive",
        ),
        (
            r#"{"sources": [{"generator": "nope.json", "weight": 1}]}"#,
            "nope.json",
        ),
        (
            r#"{"sources": [{"generator": "disc.json", "weight": 1}]}"#,
            "chairs or movers",
        ),
        (
            r#"{"sources": [{"generator": "a.json", "weight": 1, "x": 2}]}"#,
            "unknown field",
        ),
        (r#"{"source": []}"#, "unknown field"),
        (
            r#"{"sources": [{"generator": "a.json", "weight": 1e308}, {"generator": "a.json", "weight": 1e308}]}"#,
            "add up to inf",
        ),
    ] {
        let mix = write(&dir, "mix.json", text);
        let e = Stream::open(&mix).err().expect(text).to_string();
        assert!(e.contains(needle), "{text}: {e}");
    }
    let e = Stream::open(&dir.join("missing.json"))
        .err()
        .expect("missing")
        .to_string();
    assert!(e.contains("missing.json"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A source with a crop of its own: every batch is of one size, the steps of each crop come
/// in proportion to their sources' weights, and a large step's slots all come from the
/// sources of its crop; a crop its frames cannot hold is refused.
#[test]
fn a_source_with_its_own_crop_makes_whole_batches_of_it() {
    use crate::flow::train::{TrainConfig, source::TrainData, step};
    let dir = folder("crops");
    let chairs = |seed: u64, w: usize, h: usize| {
        format!(
            r#"{{"count": 1, "seed": {seed}, "scene": {{"kind": "chairs", "width": {w}, "height": {h}, "supersample": 1, "sprites": [1, 2]}}}}"#
        )
    };
    write(&dir, "a.json", &chairs(3, 80, 64));
    write(&dir, "c.json", &chairs(5, 80, 72));
    write(&dir, "b.json", &chairs(4, 160, 128));
    let mix = write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 2}, {"generator": "c.json", "weight": 1},
                        {"generator": "b.json", "weight": 1, "crop": [128, 144]}]}"#,
    );
    let config = TrainConfig {
        crop: [64, 64],
        batch_size: 3,
        ..TrainConfig::default()
    };
    let data = TrainData::open(&mix, &config).expect("open");
    let mut large = 0;
    for s in 0..80 {
        let examples = step::examples(&config, &data, s).expect("examples");
        let sizes: Vec<_> = examples.iter().map(|e| e.size).collect();
        assert!(sizes.iter().all(|&z| z == sizes[0]), "step {s}: {sizes:?}");
        assert!(sizes[0] == (64, 64) || sizes[0] == (128, 144), "{sizes:?}");
        large += (sizes[0] == (128, 144)) as usize;
    }
    // A quarter of the weight: about 20 of 80 steps.
    assert!(
        (8..=34).contains(&large),
        "{large} of 80 steps at the large crop"
    );
    // The same stream without the crop is another run's data.
    let plain = write(
        &dir,
        "plain.json",
        r#"{"sources": [{"generator": "a.json", "weight": 2}, {"generator": "c.json", "weight": 1},
                        {"generator": "b.json", "weight": 1}]}"#,
    );
    let other = TrainData::open(&plain, &config).expect("open");
    assert_ne!(data.fingerprint, other.fingerprint);
    // Frames smaller than a source's crop, and a crop off the grid, are refused.
    for (name, text, says) in [
        (
            "bad.json",
            r#"{"sources": [{"generator": "a.json", "weight": 1, "crop": [128, 144]}]}"#,
            ["[128, 144]", "64x80"],
        ),
        (
            "odd.json",
            r#"{"sources": [{"generator": "b.json", "weight": 1, "crop": [100, 144]}]}"#,
            ["sources[0].crop", "multiple of 8"],
        ),
    ] {
        let file = write(&dir, name, text);
        let err = TrainData::open(&file, &config)
            .err()
            .expect("refused")
            .to_string();
        assert!(says.iter().all(|w| err.contains(w)), "{name}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// An upscaled source makes the generator's pair made larger, as `flow::scale` makes frames
/// larger before the network: each image resized bilinearly, the flow resized with its
/// vectors multiplied by the factor; a crop its frames hold only once larger is accepted; the
/// factor is part of the data's identity; a factor outside [1, 4] is refused by name.
#[test]
fn an_upscaled_source_makes_its_pairs_larger_with_their_flow() {
    use crate::flow::train::{TrainConfig, source::TrainData};
    let dir = folder("upscale");
    write(&dir, "a.json", SMALL);
    let mix = write(
        &dir,
        "mix.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1, "upscale": 2, "crop": [64, 64]}]}"#,
    );
    let stream = Stream::open(&mix).expect("open");
    assert_eq!(stream.smallest_frame(), (64, 80));
    let (a, b, f) = stream.val_pair(0, 1).expect("val");
    let generator =
        Generator::new(GeneratorConfig::from_file(&dir.join("a.json")).expect("config"))
            .expect("generator");
    let (ga, gb, gf) = generator.pair(VAL_BASE).expect("sample");
    let gf = gf.expect("a chairs scene has flow");
    assert_eq!((a.shape(), b.shape()), ((3, 64, 80), (3, 64, 80)));
    let grow = |img: &Image| crate::flow::data::to_rgb(resize_to(img, 64, 80).expect("resize"));
    assert_eq!(a.data(), grow(&ga).data());
    assert_eq!(b.data(), grow(&gb).data());
    // Inside the frame, a vector of the larger flow at pixel (X, Y) is twice the generator's
    // flow read bilinearly at the same place in the scene, ((X + ½)/2 − ½, (Y + ½)/2 − ½).
    let (gu, gv) = (gf.u(), gf.v());
    let (u, v) = (f.u(), f.v());
    let read = |plane: &[f32], x: f32, y: f32| {
        let (x0, y0) = (x.floor() as usize, y.floor() as usize);
        let (tx, ty) = (x - x0 as f32, y - y0 as f32);
        let at = |x: usize, y: usize| plane[y * 40 + x];
        (1.0 - ty) * ((1.0 - tx) * at(x0, y0) + tx * at(x0 + 1, y0))
            + ty * ((1.0 - tx) * at(x0, y0 + 1) + tx * at(x0 + 1, y0 + 1))
    };
    let mut checked = 0;
    for y in 1..63 {
        for x in 1..79 {
            let (sx, sy) = ((x as f32 + 0.5) / 2.0 - 0.5, (y as f32 + 0.5) / 2.0 - 0.5);
            let j = y * 80 + x;
            let (eu, ev) = (2.0 * read(gu, sx, sy), 2.0 * read(gv, sx, sy));
            assert!(
                (u[j] - eu).abs() < 1e-3 && (v[j] - ev).abs() < 1e-3,
                "({x}, {y}): ({}, {}) against ({eu}, {ev})",
                u[j],
                v[j]
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 62 * 78);
    // The 32×40 frames hold the 64×64 crop only once made larger; without the factor they
    // are refused, and the factor is part of the data's identity.
    let config = TrainConfig {
        crop: [64, 64],
        ..TrainConfig::default()
    };
    let data = TrainData::open(&mix, &config).expect("open");
    let other = write(
        &dir,
        "other.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1, "upscale": 3, "crop": [64, 64]}]}"#,
    );
    assert_ne!(
        data.fingerprint,
        TrainData::open(&other, &config).expect("open").fingerprint
    );
    let plain = write(
        &dir,
        "plain.json",
        r#"{"sources": [{"generator": "a.json", "weight": 1, "crop": [64, 64]}]}"#,
    );
    assert!(TrainData::open(&plain, &config).is_err());
    for bad in ["0.5", "5", "-2"] {
        let text =
            format!(r#"{{"sources": [{{"generator": "a.json", "weight": 1, "upscale": {bad}}}]}}"#);
        let file = write(&dir, "bad.json", &text);
        let err = Stream::open(&file).err().expect("refused").to_string();
        assert!(
            err.contains("sources[0].upscale") && err.contains(bad),
            "{bad}: {err}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
