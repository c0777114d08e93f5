use std::path::Path;

use super::*;
use crate::track::detect::background::BackgroundModel;
use crate::track::experiment::ExperimentConfig;
use crate::track::motion::mtp::MtpConfig;

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// The profiles are what `pins track`, `pins live` and the experiments resolved before there was
/// one config: `DetectConfig::resolved(estimated)`, `MtpConfig::resolved(measured)` and the
/// flags' and experiment keys' own defaults.
#[test]
fn the_profiles_are_the_old_resolved_defaults() {
    for (p, est) in [(Profile::Exact, false), (Profile::Estimated, true)] {
        let c = TrackConfig::profile(p);
        assert_eq!(c.profile, Some(p));
        let d = &c.detect;
        assert_eq!(
            (d.change, d.align, d.place.enabled),
            (Some(est), Some(est), Some(est))
        );
        assert_eq!(d.background, BackgroundModel::Affine);
        assert!(d.check_background && d.photometric && d.trim && d.retry_aligned);
        assert_eq!((d.max_residual_ratio, d.change_k), (0.8, 4.0));
        assert_eq!(d.align_weights, crate::track::detect::align::ALIGN_WEIGHTS);
        assert_eq!(
            (d.place.frames, d.place.min_frames, d.place.split),
            (30, 10, 0.5)
        );
        assert!(d.place.pixel_noise);
        let m = &c.tracker.mtp;
        let (method, per_order, reach) = if est {
            (Method::Select, 5, 1.0)
        } else {
            (Method::Poly, 1, 0.0)
        };
        assert_eq!(m.method, Some(method));
        assert_eq!(m.samples_per_order, Some(per_order));
        assert_eq!(m.trend_reach, Some(reach));
        assert_eq!((m.window, m.order), (30, 2));
        assert_eq!(
            (m.position_r, m.motion_r, m.aligned_motion_r),
            (1.0, 0.25, Some(0.25))
        );
        assert_eq!(
            m.motion_source,
            crate::track::motion::mtp::MotionSource::Auto
        );
        let t = &c.tracker;
        assert_eq!(
            (t.confirm, t.max_gate_factor, t.match_cascade),
            (5, 2.0, true)
        );
        assert_eq!((t.consistency_max_ratio, t.partial_area_ratio), (1.0, 0.35));
        assert_eq!((t.max_coast_reported, t.reid_frames), (0, 150));
        assert_eq!((t.appearance_k, t.appearance_px, t.reid_k), (6.0, 5.0, 3.0));
        assert_eq!((t.foreground_gate, t.weak_continues_tentative), (0.5, true));
        assert_eq!((c.threshold, c.min_area, c.noise_k), (0.5, 20, 3.0));
        assert_eq!(c.horizons, vec![1, 15, 30]);
        assert_eq!(c.flow.weights, crate::flow::infer::TRACK_WEIGHTS);
        assert_eq!(c.flow.iters, None);
        assert_eq!(
            (c.flow.scale, c.flow.refine.as_str(), c.flow.start.as_str()),
            (None, "none", "zero")
        );
        // The default scale makes a frame 1280 px wide, enlarging it at most 4 times.
        let widths = [160, 320, 640, 1000, 1280, 1920];
        let scales = widths.map(|w| c.flow.scale_for(w));
        assert_eq!(scales, [4.0, 4.0, 2.0, 1.28, 1.0, 1.0]);
        c.validate().unwrap();
        // Resolving again changes nothing; a named profile wins over the fallback.
        let other = if est {
            Profile::Exact
        } else {
            Profile::Estimated
        };
        assert_eq!(c.resolved(other), c);
        assert_eq!(TrackConfig::default().resolved(p), c);
    }
}

/// Where only the alignment or the placement is turned on, the predictor's samples count as
/// measured on the frames (as `MtpConfig::resolved(measured)` had it); a value set stays.
#[test]
fn the_predictor_follows_what_measures_its_samples() {
    let mut c = TrackConfig::default();
    c.detect.align = Some(true);
    let r = c.resolved(Profile::Exact);
    assert_eq!(r.detect.change, Some(false));
    assert_eq!(r.tracker.mtp.method, Some(Method::Select));
    assert_eq!(r.tracker.mtp.samples_per_order, Some(5));
    c.tracker.mtp.samples_per_order = Some(3);
    assert_eq!(
        c.resolved(Profile::Exact).tracker.mtp.samples_per_order,
        Some(3)
    );
    c.detect.align = Some(false);
    let r = c.resolved(Profile::Estimated);
    assert_eq!(
        r.tracker.mtp.method,
        Some(Method::Select),
        "the placement is still on"
    );
    c.detect.place.enabled = Some(false);
    let r = c.resolved(Profile::Estimated);
    assert_eq!(r.tracker.mtp.method, Some(Method::Poly));
    assert_eq!(r.tracker.mtp.trend_reach, Some(0.0));
}

#[test]
fn a_file_names_a_profile_and_overrides_one_key() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "c.json",
        r#"{"profile": "estimated", "tracker": {"confirm": 3}}"#,
    );
    let c = TrackConfig::from_file(&p).unwrap();
    // The file's profile wins over the input's.
    let r = c.resolved(Profile::Exact);
    let mut want = TrackConfig::profile(Profile::Estimated);
    want.tracker.confirm = 3;
    assert_eq!(r, want);
    // Without a profile, the input's.
    let p = write(
        d.path(),
        "n.json",
        r#"{"detect": {"place": {"frames": 20}}}"#,
    );
    let r = TrackConfig::from_file(&p).unwrap().resolved(Profile::Exact);
    let mut want = TrackConfig::profile(Profile::Exact);
    want.detect.place.frames = 20;
    assert_eq!(r, want);
    // `null` for a profile's setting is the profile's.
    let p = write(d.path(), "z.json", r#"{"detect": {"align": null}}"#);
    let r = TrackConfig::from_file(&p)
        .unwrap()
        .resolved(Profile::Estimated);
    assert_eq!(r, TrackConfig::profile(Profile::Estimated));
}

#[test]
fn unknown_keys_and_bad_values_are_refused_naming_file_and_key() {
    let d = tempfile::tempdir().unwrap();
    for (text, says) in [
        (r#"{"tracker": {"confirmm": 3}}"#, "tracker.confirmm"),
        (r#"{"tracker": {"mtp": {"windw": 3}}}"#, "tracker.mtp.windw"),
        (r#"{"thresold": 1}"#, "thresold"),
        (r#"{"profile": "mms"}"#, "profile"),
        (
            r#"{"detect": {"place": {"frames": "x"}}}"#,
            "detect.place.frames",
        ),
        (
            r#"{"detect": {"align_weights": [1, 2]}}"#,
            "detect.align_weights",
        ),
        (
            r#"{"detect": {"align_weights": [1, -1, 1]}}"#,
            "detect.align_weights",
        ),
        (r#"{"tracker": {"confirm": 0}}"#, "tracker.confirm"),
        (
            r#"{"tracker": {"mtp": {"trend_reach": -1}}}"#,
            "trend_reach",
        ),
        (
            r#"{"detect": {"place": {"split": -0.5}}}"#,
            "detect.place.split",
        ),
        (r#"{"flow": {"scale": 5}}"#, "flow.scale"),
        (r#"{"flow": {"start": "middle"}}"#, "flow.start"),
        (r#"{"horizons": []}"#, "horizons"),
        (r#"{"noise_k": -1}"#, "noise_k"),
        ("[1, 2]", "c.json"),
        ("{", "c.json"),
    ] {
        let p = write(d.path(), "c.json", text);
        let e = TrackConfig::from_file(&p).unwrap_err().to_string();
        assert!(e.contains(says) && e.contains("c.json"), "{text}: {e}");
    }
    let e = TrackConfig::from_file(&d.path().join("none.json")).unwrap_err();
    assert!(e.to_string().contains("none.json"), "{e}");
}

/// `pins track --config F` and an experiment whose `track` is F's content build the same
/// tracker; a predictor's `mtp` overrides only the keys it names.
#[test]
fn the_cli_and_the_experiments_build_the_same_settings() {
    let d = tempfile::tempdir().unwrap();
    let text = r#"{"tracker": {"confirm": 4, "max_gate_factor": 1.0, "mtp": {"position_r": 2.0}},
                   "detect": {"place": {"split": 0.7}}, "noise_k": 2.5}"#;
    let file = write(d.path(), "t.json", text);
    let track: Value = serde_json::from_str(text).unwrap();
    for (flow, profile) in [("truth", Profile::Exact), ("mms", Profile::Estimated)] {
        let cli = TrackConfig::from_file(&file)
            .unwrap()
            .options(profile, false)
            .unwrap();
        let exp: ExperimentConfig = serde_json::from_value(serde_json::json!({
            "clips": [{"name": "c", "config": "c.json"}],
            "predictors": [{"name": "same"}, {"name": "cv", "mtp": {"method": "constant_velocity"}}],
            "horizons": [1, 15, 30],
            "flow": flow,
            "track": track,
        }))
        .unwrap();
        let same = exp.options(0).unwrap();
        assert_eq!(same.tracker, cli.tracker, "{flow}");
        assert_eq!(same.detect, cli.detect, "{flow}");
        assert_eq!(
            (same.threshold, same.noise_k, same.min_area),
            (0.5, 2.5, 20)
        );
        assert_eq!(same.horizons, cli.horizons);
        let cv = exp.options(1).unwrap();
        assert_eq!(cv.tracker.mtp.method, Some(Method::ConstantVelocity));
        assert_eq!(cv.tracker.mtp.position_r, 2.0);
        assert_eq!(
            cv.tracker.mtp.samples_per_order,
            cli.tracker.mtp.samples_per_order
        );
    }
    // A predictor's unknown key is refused, naming it.
    let exp: ExperimentConfig = serde_json::from_value(serde_json::json!({
        "clips": [], "predictors": [{"name": "p", "mtp": {"windw": 3}}], "horizons": [1],
    }))
    .unwrap();
    let e = exp.options(0).unwrap_err().to_string();
    assert!(
        e.contains("predictors[0].mtp") && e.contains("windw"),
        "{e}"
    );
}

/// `experiments/track_config_estimated.json` holds every key at the estimated profile's value.
#[test]
fn the_example_config_is_the_estimated_profile_in_full() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("experiments/track_config_estimated.json");
    let c = TrackConfig::from_file(&path).unwrap();
    let want = TrackConfig::profile(Profile::Estimated);
    assert_eq!(
        c,
        want,
        "{}",
        serde_json::to_string_pretty(&want).unwrap_or_default()
    );
    let text: Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    assert_eq!(
        text,
        serde_json::to_value(&c).unwrap(),
        "every key, as written"
    );
    // The struct defaults of the parts are the profiles' own where no profile decides.
    assert_eq!(c.tracker.mtp.window, MtpConfig::default().window);
}
