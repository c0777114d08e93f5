//! Re-identification end to end through `pins track`: a disc rendered through the default
//! camera on seeds the defaults were not tuned on, its exact flow blanked for 20 frames (an
//! estimator that loses the object for longer than a track's patience), so the track ends;
//! when the flow finds the disc again, the new track takes the old ID, and `pins track eval`
//! reports one track, no ID switch and no second track. With `--reid-frames 0` the object
//! comes back under a new ID, which the evaluation calls a second track.

use std::path::Path;

use pins::scene::truth::Truth;
use pins::track::eval::{TrackReport, evaluate};
use pins::track::tracker::tracks::Tracks;

mod common;
use common::{ok, pins, render_disc_line};

const FRAMES: usize = 60;
/// The frames (pairs) whose flow is blanked: longer than the tracker's patience of 15.
const HIDDEN: std::ops::Range<usize> = 15..35;

/// Renders a 160×120 clip of one disc of radius 10 crossing the frame at about 2 px/frame.
fn render(dir: &Path, seed: u64) -> Truth {
    render_disc_line(dir, seed, FRAMES, [0.1, 0.45], [0.9, 0.6])
}

/// The exact flows, with those of `HIDDEN` set to zero everywhere.
fn blank_flows(clip: &Path) -> std::path::PathBuf {
    let dir = clip.join("blanked");
    for n in 0..FRAMES - 1 {
        let name = format!("{n:05}.flo");
        let mut f = pins::io::read_flow(&clip.join("flows").join(&name)).unwrap();
        if HIDDEN.contains(&n) {
            for y in 0..f.height() {
                for x in 0..f.width() {
                    f.set(y, x, 0.0, 0.0);
                }
            }
        }
        pins::io::write_flo(&dir.join(&name), &f).unwrap();
    }
    dir
}

fn track(
    clip: &Path,
    flows: &Path,
    out: &Path,
    extra: &[&str],
    truth: &Truth,
) -> (TrackReport, Tracks) {
    let mut args = vec![
        "track",
        "--flows",
        flows.to_str().unwrap(),
        "--frames",
        clip.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--no-plots",
    ];
    args.extend_from_slice(extra);
    ok(&pins(&args));
    let tracks = Tracks::read(&out.join("tracks.json")).unwrap();
    (evaluate(&tracks, truth).unwrap(), tracks)
}

#[test]
fn an_object_the_flow_loses_for_20_frames_keeps_its_id() {
    for seed in [907, 908] {
        let d = tempfile::tempdir().unwrap();
        let clip = d.path().join("clip");
        let truth = render(&clip, seed);
        let flows = blank_flows(&clip);
        let frames = clip.join("frames");
        let (on, tracks) = track(&frames, &flows, &d.path().join("on"), &[], &truth);
        assert_eq!(on.objects.len(), 1, "seed {seed}: {on:?}");
        assert_eq!(on.objects[0].truth_index, Some(0), "seed {seed}: {on:?}");
        assert_eq!(on.id_switches, 0, "seed {seed}: {on:?}");
        assert_eq!(on.second_tracks() + on.false_tracks(), 0, "seed {seed}");
        // The one track covers the object before and after the gap.
        let seen: Vec<usize> = tracks.objects[0].frames.iter().map(|f| f.frame).collect();
        assert!(
            seen.iter().any(|&n| n < HIDDEN.start),
            "seed {seed}: {seen:?}"
        );
        assert!(
            seen.iter().any(|&n| n > HIDDEN.end),
            "seed {seed}: {seen:?}"
        );
        let off_cfg = d.path().join("no_reid.json");
        std::fs::write(&off_cfg, r#"{"tracker": {"reid_frames": 0}}"#).unwrap();
        let (off, _) = track(
            &frames,
            &flows,
            &d.path().join("off"),
            &["--config", off_cfg.to_str().unwrap()],
            &truth,
        );
        assert_eq!(off.objects.len(), 2, "seed {seed}: {off:?}");
        assert_eq!(off.id_switches, 1, "seed {seed}: {off:?}");
        assert_eq!(
            (off.second_tracks(), off.false_tracks()),
            (1, 0),
            "seed {seed}"
        );
    }
}
