//! `pins live`: the ESP32 camera's stream (or a recording of it) through the live pipeline.

use std::io::Write;
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::{Context, Result, bail};

use pins::live::http::{Timeouts, get_small};
use pins::live::pipeline::{Line, Pipeline, PipelineConfig};
use pins::live::reader::{Counts, Frame, Reader, ReaderConfig};
use pins::live::record::{Lines, Recorder, Replay};
use pins::live::serve::{ViewState, serve};
use pins::live::url::HttpUrl;
use pins::live::view::render_view;
use pins::track::config::{Profile, TrackConfig};

#[derive(clap::Args)]
pub(crate) struct LiveArgs {
    /// The camera's stream, e.g. http://192.168.4.1:81/stream.
    #[arg(long, conflicts_with = "replay", required_unless_present_any = ["replay", "frames"])]
    url: Option<String>,
    /// Run on a recording made with --record instead of a camera.
    #[arg(long)]
    replay: Option<PathBuf>,
    /// Run on a folder of images (any format, in name order) as if recorded at --fps.
    #[arg(long, conflicts_with_all = ["url", "replay"])]
    frames: Option<PathBuf>,
    /// Frame rate of --frames (their time stamps are k / fps).
    #[arg(long, default_value_t = 15.0, requires = "frames")]
    fps: f64,
    /// With --replay: process every recorded frame, not only those the live run processed.
    #[arg(long, requires = "replay")]
    all_frames: bool,
    /// Array calibration (from `pins array calibrate`): frames are stitched to the wide image.
    #[arg(long)]
    calib: Option<PathBuf>,
    /// Tracking settings (a JSON TrackConfig, as for `pins track`; the estimated profile
    /// unless it names another); the flags below override it.
    #[arg(long)]
    config: Option<PathBuf>,
    /// The defaults for an estimated flow (the default here) or an exact one.
    #[arg(long)]
    profile: Option<Profile>,
    /// MMS weights (flow.weights): a file, or the built-in mms-small (the default here
    /// without --config), mms-small-real or default (= mms-small-real).
    #[arg(long)]
    weights: Option<String>,
    /// Device of the MMS network: cpu, or a GPU backend of this build (wgpu[:N], cuda[:N]).
    #[arg(long, default_value = "cpu")]
    device: String,
    /// MMS refinement iterations (flow.iters): a count, or auto (at most the weights' own,
    /// stopping once the flow settles). Default: the config's with --config, else auto.
    #[arg(long)]
    iters: Option<pins::flow::iters::Iters>,
    /// Start each pair's MMS from the previous pair's flow, carried forward (flow.warm_start).
    #[arg(long)]
    warm_start: bool,
    /// Encode every frame twice, as the first and second of its pairs (flow.reuse false): the
    /// same flow, slower.
    #[arg(long)]
    no_reuse: bool,
    /// Downscale factor in (0, 1] applied (after stitching) before the flow.
    #[arg(long, default_value_t = 1.0)]
    scale: f64,
    /// Output folder: tracks.jsonl (written whole at the end) and summary.json; stdout without.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Save every received whole JPEG with its time stamps in this folder.
    #[arg(long, conflicts_with_all = ["replay", "frames"])]
    record: Option<PathBuf>,
    /// Serve the browser view at this address, e.g. 127.0.0.1:8080.
    #[arg(long)]
    serve: Option<String>,
    /// Stop after this many processed frames.
    #[arg(long)]
    max_frames: Option<usize>,
    /// Stop after this many seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Set the camera's frame size through /control on port 80 first (a driver's number).
    #[arg(long, conflicts_with = "replay")]
    framesize: Option<u32>,
    /// Set the camera's JPEG quality through /control on port 80 first.
    #[arg(long, conflicts_with = "replay")]
    quality: Option<u32>,
    /// Seconds without a byte before the stream counts as stalled (then reconnected).
    #[arg(long, default_value_t = 5.0)]
    read_timeout: f64,
    /// Seconds to wait for the camera's answer (a busy camera never answers).
    #[arg(long, default_value_t = 5.0)]
    response_timeout: f64,
    /// Prediction horizons in frames (horizons). Default: the config's with --config, else
    /// 1,5,15 (LIVE_HORIZONS).
    #[arg(long, value_delimiter = ',')]
    horizons: Option<Vec<usize>>,
    /// Detections moving as their motion says before a track is reported (tracker.confirm;
    /// default 5).
    #[arg(long)]
    confirm: Option<usize>,
    /// No log lines about the stream on stderr.
    #[arg(long)]
    quiet: bool,
}

/// What `summary.json` holds.
#[derive(serde::Serialize)]
struct Summary {
    processed: usize,
    seconds: f64,
    processed_fps: f64,
    input_fps: f64,
    counts: Counts,
    mean_ms: pins::live::pipeline::Stages,
    size_changes: usize,
}

pub(crate) fn live(a: LiveArgs) -> Result<()> {
    let secs = |v: f64, name: &str| -> Result<Duration> {
        if !(v.is_finite() && v > 0.0 && v <= 3600.0) {
            bail!("{name} must be in (0, 3600] seconds, got {v}");
        }
        Ok(Duration::from_secs_f64(v))
    };
    let duration = a.duration.map(|d| secs(d, "--duration")).transpose()?;
    if a.max_frames == Some(0) {
        bail!("--max-frames must be >= 1");
    }
    let stop = Arc::new(AtomicBool::new(false));
    for sig in [signal_hook::consts::SIGINT, signal_hook::consts::SIGTERM] {
        signal_hook::flag::register(sig, stop.clone()).context("installing the Ctrl-C handler")?;
    }
    let cfg = settings(&a)?;
    let track = cfg.options(Profile::Estimated, false)?;
    let predictor = cfg.flow.predictor(pins::flow::device::select(&a.device)?)?;
    let (iters, video) = cfg.flow.iters_for(&predictor);
    let stitcher = match &a.calib {
        Some(p) => {
            let text =
                std::fs::read_to_string(p).with_context(|| format!("reading {}", p.display()))?;
            let calib: pins::wide::Calibration = serde_json::from_str(&text)
                .with_context(|| format!("calibration {}", p.display()))?;
            Some(pins::wide::Stitcher::new(&calib)?)
        }
        None => None,
    };
    pins::imaging::resize::downscale(&pins::Image::zeros(1, 8, 8), a.scale)?;
    let mut pipeline = Pipeline::new(
        predictor,
        PipelineConfig {
            scale: a.scale,
            flow_scale: cfg.flow.scale,
            iters,
            video,
            stitcher,
            track,
        },
    )?;
    let view = match &a.serve {
        Some(addr) => {
            let state = Arc::new(ViewState::default());
            let (local, _h) = serve(addr, state.clone())?;
            eprintln!("live: view at http://{local}/");
            Some(state)
        }
        None => None,
    };
    let mut sink = Sink::new(a.out.as_ref())?;
    let mut source = match (&a.replay, &a.frames) {
        (Some(dir), _) => Source::Replay(Replay::open(dir, a.all_frames)?, 0, Counts::default()),
        (None, Some(dir)) => Source::Replay(Replay::from_images(dir, a.fps)?, 0, Counts::default()),
        (None, None) => {
            let url = HttpUrl::parse(a.url.as_deref().unwrap_or_default())?;
            let timeouts = Timeouts {
                response: secs(a.response_timeout, "--response-timeout")?,
                read: secs(a.read_timeout, "--read-timeout")?,
                ..Timeouts::default()
            };
            configure(&url, &timeouts, a.framesize, a.quality)?;
            let mut cfg = ReaderConfig::new(url);
            cfg.timeouts = timeouts;
            cfg.quiet = a.quiet;
            let (hook, processed) = match &a.record {
                Some(dir) => {
                    let mut rec = Recorder::create(dir)?;
                    let hook: pins::live::reader::FrameHook = Box::new(move |f| rec.save(f));
                    (Some(hook), Some(Recorder::processed(dir)?))
                }
                None => (None, None),
            };
            Source::Live(Reader::start(cfg, stop.clone(), hook)?, processed)
        }
    };
    let started = Instant::now();
    let mut processed = 0usize;
    let mut sums = pins::live::pipeline::Stages::default();
    let mut lines = 0usize;
    let mut first_size = None;
    let result = (|| -> Result<()> {
        while !stop.load(Ordering::Relaxed)
            && a.max_frames.is_none_or(|m| processed < m)
            && duration.is_none_or(|d| started.elapsed() < d)
        {
            let Some((frame, counts)) = source.next()? else {
                if source.finished() {
                    break;
                }
                continue;
            };
            if first_size.is_none() {
                let (c, h, w) = frame.image.shape();
                eprintln!("live: first frame {w}x{h}, {c} channel(s)");
                first_size = Some((w, h));
            }
            processed += 1;
            let Some(line) = pipeline.process(&frame, counts)? else {
                continue;
            };
            lines += 1;
            sums.prepare += line.ms.prepare;
            sums.flow += line.ms.flow;
            sums.track += line.ms.track;
            sums.latency += line.ms.latency;
            let text = serde_json::to_string(&line)?;
            sink.push(&text)?;
            if let Some(v) = &view {
                publish(v, &pipeline, &line, started, processed)?;
            }
        }
        Ok(())
    })();
    let seconds = started.elapsed().as_secs_f64();
    let counts = source.counts();
    let ended_with = source.close();
    if let Some(v) = &view {
        v.shut();
    }
    result?;
    let n = lines.max(1) as f64;
    let summary = Summary {
        processed,
        seconds,
        processed_fps: processed as f64 / seconds.max(1e-9),
        input_fps: counts.received as f64 / seconds.max(1e-9),
        counts,
        mean_ms: pins::live::pipeline::Stages {
            prepare: sums.prepare / n,
            flow: sums.flow / n,
            track: sums.track / n,
            latency: sums.latency / n,
        },
        size_changes: pipeline.size_changes,
    };
    sink.finish(&summary)?;
    eprintln!(
        "live: {} frames processed in {:.1} s ({:.2} fps), {} received ({:.2} fps), {} dropped, {} bad, \
         {} reconnections; mean ms: prepare {:.0}, flow {:.0}, track {:.1}, latency {:.0}",
        summary.processed,
        seconds,
        summary.processed_fps,
        counts.received,
        summary.input_fps,
        counts.dropped,
        counts.bad,
        counts.reconnects,
        summary.mean_ms.prepare,
        summary.mean_ms.flow,
        summary.mean_ms.track,
        summary.mean_ms.latency
    );
    if let Some(e) = ended_with {
        bail!("the stream ended: {e}");
    }
    Ok(())
}

/// The horizons of `pins live` without --horizons or --config: its frames come at about 15 per
/// second, so 1, 5 and 15 frames ahead reach a second.
pub(crate) const LIVE_HORIZONS: [usize; 3] = [1, 5, 15];

/// The tracking settings: the config file (or the estimated profile's defaults, with
/// `LIVE_HORIZONS`, `auto` iterations and `LIVE_WEIGHTS` at the frame's size) and the flags'
/// overrides.
fn settings(a: &LiveArgs) -> Result<TrackConfig> {
    let cfg = match &a.config {
        Some(p) => TrackConfig::from_file(p)?,
        None => {
            let mut cfg = TrackConfig {
                horizons: LIVE_HORIZONS.to_vec(),
                ..TrackConfig::default()
            };
            // At most the weights' own updates, stopping once the flow settles: on the
            // bench-live clips the same EPE as all twelve in 37–52 % of their time.
            cfg.flow.iters = Some(pins::flow::iters::Iters::Auto);
            // The frame budget first: stage 3 at the frame's own size, a quarter of the
            // offline tracker's flow time (the shipped weights at twice a 640×480 frame's
            // size, `TRACK_WIDTH`), which sees camouflaged movers that this misses.
            cfg.flow.weights = pins::flow::infer::LIVE_WEIGHTS.into();
            cfg.flow.scale = Some(1.0);
            cfg
        }
    };
    let flags = crate::cli::track::Overrides {
        profile: a.profile,
        weights: a.weights.as_deref(),
        iters: a.iters,
        warm_start: a.warm_start,
        no_reuse: a.no_reuse,
        confirm: a.confirm,
        horizons: a.horizons.as_deref(),
    };
    flags.apply(cfg)
}

/// Sets frame size and quality through the camera's `/control` (port 80), each answer checked.
fn configure(
    url: &HttpUrl,
    t: &Timeouts,
    framesize: Option<u32>,
    quality: Option<u32>,
) -> Result<()> {
    for (var, val) in [("framesize", framesize), ("quality", quality)] {
        if let Some(v) = val {
            let u = url.with(80, &format!("/control?var={var}&val={v}"));
            get_small(&u, t, 4096).with_context(|| format!("setting the camera's {var} to {v}"))?;
            eprintln!("live: camera {var} set to {v}");
        }
    }
    Ok(())
}

fn publish(
    v: &ViewState,
    p: &Pipeline,
    line: &Line,
    started: Instant,
    processed: usize,
) -> Result<()> {
    let jpeg = match &p.last_flow {
        Some((img, flow, objects)) => Some(render_view(img, flow, objects)?),
        None => None,
    };
    let t = started.elapsed().as_secs_f64().max(1e-9);
    let mut json = serde_json::to_value(line)?;
    json["processed_fps"] = (processed as f64 / t).into();
    json["input_fps"] = (line.received as f64 / t).into();
    v.publish(jpeg, json.to_string());
    Ok(())
}

/// Where frames come from.
enum Source {
    Live(Reader, Option<Lines>),
    /// The recording, the next index, the counts so far.
    Replay(Replay, usize, Counts),
}

impl Source {
    /// The next frame (with the counts at that moment); `None` on a timeout or a bad frame.
    fn next(&mut self) -> Result<Option<(Frame, Counts)>> {
        match self {
            Source::Live(r, processed) => {
                let Some(f) = r.latest.take(Duration::from_millis(200)) else {
                    return Ok(None);
                };
                if let Some(p) = processed {
                    p.push(&pins::live::record::Processed { seq: f.seq })?;
                }
                Ok(Some((f, r.latest.counters.snapshot())))
            }
            Source::Replay(rep, next, counts) => {
                let Some(r) = rep.frames.get(*next).cloned() else {
                    return Ok(None);
                };
                *next += 1;
                counts.received += 1;
                match rep.load(&r)? {
                    Ok(f) => Ok(Some((f, *counts))),
                    Err(bad) => {
                        counts.bad += 1;
                        eprintln!("live: skipped recorded frame {}: {bad}", r.seq);
                        Ok(None)
                    }
                }
            }
        }
    }

    fn finished(&self) -> bool {
        match self {
            Source::Live(r, _) => r.latest.ended.load(Ordering::Relaxed),
            Source::Replay(rep, next, _) => *next >= rep.frames.len(),
        }
    }

    fn counts(&self) -> Counts {
        match self {
            Source::Live(r, _) => r.latest.counters.snapshot(),
            Source::Replay(_, _, c) => *c,
        }
    }

    /// Stops the reader; the reason it ended by itself, if it did.
    fn close(self) -> Option<String> {
        match self {
            Source::Live(r, _) => {
                let ended = r.latest.ended.load(Ordering::Relaxed);
                let why = r.latest.last_error.lock().ok().and_then(|e| e.clone());
                r.stop();
                if ended {
                    why.or(Some("reader stopped".into()))
                } else {
                    None
                }
            }
            Source::Replay(..) => None,
        }
    }
}

/// The JSON lines: stdout, or `DIR/tracks.jsonl.part` renamed to `tracks.jsonl` at the end.
struct Sink {
    dir: Option<PathBuf>,
    file: Option<Lines>,
}

impl Sink {
    fn new(dir: Option<&PathBuf>) -> Result<Self> {
        let file = match dir {
            Some(d) => {
                std::fs::create_dir_all(d).with_context(|| format!("creating {}", d.display()))?;
                let part = d.join("tracks.jsonl.part");
                let _ = std::fs::remove_file(&part);
                Some(Lines::create(&part)?)
            }
            None => None,
        };
        Ok(Self {
            dir: dir.cloned(),
            file,
        })
    }

    fn push(&mut self, line: &str) -> Result<()> {
        match &mut self.file {
            Some(f) => f.push(&serde_json::from_str::<serde_json::Value>(line)?)?,
            None => {
                let mut out = std::io::stdout().lock();
                writeln!(out, "{line}")?;
                out.flush()?;
            }
        }
        Ok(())
    }

    fn finish(self, summary: &Summary) -> Result<()> {
        if let Some(d) = &self.dir {
            drop(self.file);
            std::fs::rename(d.join("tracks.jsonl.part"), d.join("tracks.jsonl"))
                .with_context(|| format!("finishing {}", d.join("tracks.jsonl").display()))?;
            pins::io::write_bytes_atomic(
                &d.join("summary.json"),
                serde_json::to_string_pretty(summary)?.as_bytes(),
            )?;
        }
        Ok(())
    }
}
