//! Running the real-data benchmark: for each set and camera, generate the dataset folder with
//! the generator (a cache under `OUT/data`, named by a hash of its config), score MMS at each
//! iteration count and the zero flow with `pins eval`'s code, and the OpenCV peers with
//! `scripts/flow_baselines.py` where Python has OpenCV; then the summary.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::prelude::Device;

use super::config::{self, BenchPlan, ResolvedCamera, ResolvedSet};
use super::peers::{self, PeersFile};
use super::report::{
    BenchRealReport, MethodScores, PairResult, PeersInfo, SetRun, Skipped, summarise,
};
use crate::dataset::{Generator, GeneratorConfig, Manifest, Shard};
use crate::error::{Error, Result};
use crate::flow::data::FlowDataset;
use crate::flow::eval::{EvalReport, EvalRow, evaluate, mms_method};
use crate::flow::infer::Predictor;

/// What the command line may change.
pub struct BenchOptions {
    /// Overrides the config's weights.
    pub weights: Option<String>,
    /// Overrides the config's iteration counts.
    pub iters: Option<Vec<usize>>,
    /// Run the OpenCV peers (when Python has OpenCV).
    pub peers: bool,
    /// The Python interpreter for the peers.
    pub python: String,
    pub device: Device,
    /// Score the refined flow beside the network's.
    pub refine: crate::flow::refine::Refine,
    /// Start the network from its half-resolution flow.
    pub coarse_start: bool,
}

/// Runs the benchmark of the config at `config_path`, generating data under `out/data`;
/// `log` receives one line per step. Writes nothing but the dataset caches: see
/// [`super::write_outputs`] for the report files.
pub fn run(
    config_path: &Path,
    out: &Path,
    opts: &BenchOptions,
    log: &dyn Fn(&str),
) -> Result<BenchRealReport> {
    let mut plan: BenchPlan = config::load(config_path)?;
    if let Some(w) = &opts.weights {
        plan.weights = w.clone();
    }
    if let Some(it) = &opts.iters {
        config::check_iters(it).map_err(|e| Error::invalid("--iters", e.to_string()))?;
        plan.iters = it.clone();
    }
    let predictor = Predictor::load_on(&plan.weights, opts.device.clone())?
        .with_refine(&opts.refine)
        .with_coarse_start(opts.coarse_start);
    let mut skipped = Vec::new();
    let mut sets: Vec<&ResolvedSet> = Vec::new();
    for s in &plan.sets {
        match &s.missing {
            Some(reason) => {
                log(&format!("set {}: skipped, {reason}", s.name));
                skipped.push(Skipped {
                    set: s.name.clone(),
                    reason: reason.clone(),
                });
            }
            None => sets.push(s),
        }
    }
    if sets.is_empty() {
        return Err(Error::invalid(
            "benchmark",
            format!(
                "{}: none of its {} sets can be run ({})",
                config_path.display(),
                plan.sets.len(),
                skipped
                    .iter()
                    .map(|s| format!("{}: {}", s.set, s.reason))
                    .collect::<Vec<_>>()
                    .join("; ")
            ),
        ));
    }
    let peers_info = if opts.peers {
        match peers::available(&opts.python) {
            Ok(version) => {
                let version_warning = peers::version_warning(&version);
                if let Some(w) = &version_warning {
                    log(&format!("warning: {w}"));
                }
                PeersInfo {
                    ran: true,
                    skipped_because: None,
                    opencv: Some(version),
                    version_warning,
                    threads: plan.peer_threads,
                }
            }
            Err(why) => {
                log(&format!("OpenCV peers skipped: {why}"));
                PeersInfo {
                    ran: false,
                    skipped_because: Some(why),
                    opencv: None,
                    version_warning: None,
                    threads: plan.peer_threads,
                }
            }
        }
    } else {
        log("OpenCV peers skipped: --no-peers");
        PeersInfo {
            ran: false,
            skipped_because: Some("--no-peers".into()),
            opencv: None,
            version_warning: None,
            threads: plan.peer_threads,
        }
    };
    let mut runs = Vec::new();
    for set in &sets {
        for cam in &plan.cameras {
            runs.push(run_one(
                set,
                cam,
                &plan,
                &predictor,
                out,
                opts,
                peers_info.ran,
                log,
            )?);
        }
    }
    let cameras: Vec<String> = plan.cameras.iter().map(|c| c.name.clone()).collect();
    let summary = summarise(&cameras, &runs);
    Ok(BenchRealReport {
        config: config_path.display().to_string(),
        weights: plan.weights.clone(),
        model: predictor.config.name.clone(),
        parameters: crate::flow::weights::parameter_count(&predictor.model),
        start: if opts.coarse_start { "coarse" } else { "zero" }.into(),
        threads: rayon::current_num_threads(),
        iters: plan.iters.clone(),
        cameras,
        peers: peers_info,
        skipped,
        runs,
        summary,
    })
}

/// The cache folder of one generator config: `OUT/data/SET-CAMERA-HASH`, the hash (SHA-256 of
/// the config's JSON, 8 hex digits) so that an edited config never meets an old folder.
pub fn data_dir(out: &Path, set: &str, camera: &str, cfg: &GeneratorConfig) -> Result<PathBuf> {
    use sha2::{Digest, Sha256};
    let json =
        serde_json::to_string(cfg).map_err(|e| Error::invalid("set config", e.to_string()))?;
    let digest = Sha256::digest(json.as_bytes());
    let hash: String = digest.iter().take(4).map(|b| format!("{b:02x}")).collect();
    Ok(out.join("data").join(format!("{set}-{camera}-{hash}")))
}

#[allow(clippy::too_many_arguments)]
fn run_one(
    set: &ResolvedSet,
    cam: &ResolvedCamera,
    plan: &BenchPlan,
    predictor: &Predictor,
    out: &Path,
    opts: &BenchOptions,
    with_peers: bool,
    log: &dyn Fn(&str),
) -> Result<SetRun> {
    let mut gen_cfg = set.generator.clone();
    gen_cfg.camera = cam.camera.clone();
    let dir = data_dir(out, &set.name, &cam.name, &gen_cfg)?;
    let context =
        |e: Error| Error::invalid(format!("set {} ({})", set.name, cam.name), e.to_string());
    let summary = Generator::new(gen_cfg)
        .and_then(|g| g.run(&dir, Shard::ALL, false))
        .map_err(context)?;
    if !summary.manifest_written {
        return Err(context(Error::invalid(
            "generator",
            format!("{} of {} samples complete", summary.complete, summary.total),
        )));
    }
    let sources = sources(&dir)?;
    let data = FlowDataset::open(&dir).map_err(context)?;
    data.check_has_known_flow().map_err(context)?;
    log(&format!(
        "set {} ({}): {} pairs in {}; MMS at {:?} iterations",
        set.name,
        cam.name,
        data.pairs.len(),
        dir.display(),
        plan.iters
    ));
    let eval = evaluate(predictor, &data, &plan.iters).map_err(context)?;
    let peers = if with_peers {
        log(&format!("set {} ({}): OpenCV peers", set.name, cam.name));
        let json = dir.with_extension("peers.json");
        Some(peers::run(&opts.python, &dir, &json, plan.peer_threads).map_err(context)?)
    } else {
        None
    };
    merge(set, cam, &dir, &eval, peers.as_ref(), &sources).map_err(context)
}

/// Sample name (`00000`) → the source pair's name in the original dataset, from the manifest.
fn sources(dir: &Path) -> Result<BTreeMap<String, String>> {
    let m = Manifest::read(&dir.join("manifest.json"))?;
    Ok(m.samples
        .iter()
        .filter_map(|s| Some((format!("{:05}", s.index), s.source.clone()?)))
        .collect())
}

fn mms_scores(model: &str, r: &EvalRow) -> MethodScores {
    MethodScores {
        method: mms_method(model, r.refined),
        iters: Some(r.iters),
        epe: r.epe,
        ae_deg: r.ae_deg,
        px1: r.px1,
        px3: r.px3,
        px5: r.px5,
        ms_per_pair: r.ms_per_pair,
        by_speed: r.by_speed,
    }
}

fn zero_scores(z: &crate::flow::eval::ZeroFlow) -> MethodScores {
    MethodScores {
        method: "zero flow".into(),
        iters: None,
        epe: z.epe,
        ae_deg: z.ae_deg,
        px1: z.px1,
        px3: z.px3,
        px5: z.px5,
        ms_per_pair: 0.0,
        by_speed: z.by_speed,
    }
}

/// One set's rows: MMS, then the peers, then the zero flow; the same for each pair. The peers'
/// zero flow must have scored the same pixels as ours, pair by pair.
fn merge(
    set: &ResolvedSet,
    cam: &ResolvedCamera,
    dir: &Path,
    eval: &EvalReport,
    peers: Option<&PeersFile>,
    sources: &BTreeMap<String, String>,
) -> Result<SetRun> {
    let mut methods: Vec<MethodScores> = eval
        .rows
        .iter()
        .map(|r| mms_scores(&eval.model, r))
        .collect();
    if let Some(p) = peers {
        if p.pairs != eval.pairs {
            return Err(Error::invalid(
                "peers",
                format!("scored {} pairs, pins {}", p.pairs, eval.pairs),
            ));
        }
        methods.extend(p.methods.iter().map(|m| MethodScores {
            method: m.name.clone(),
            iters: None,
            epe: m.epe,
            ae_deg: m.ae_deg,
            px1: m.px1,
            px3: m.px3,
            px5: m.px5,
            ms_per_pair: m.ms_per_pair,
            by_speed: m.by_speed,
        }));
    }
    methods.push(zero_scores(&eval.zero_flow));
    let mut per_pair = Vec::with_capacity(eval.per_pair.len());
    for pair in &eval.per_pair {
        let mut rows: Vec<MethodScores> = pair
            .rows
            .iter()
            .map(|r| mms_scores(&eval.model, r))
            .collect();
        if let Some(p) = peers {
            let find = |m: &peers::PeerMethod| {
                m.per_pair
                    .iter()
                    .find(|q| q.name == pair.name)
                    .cloned()
                    .ok_or_else(|| {
                        Error::invalid(
                            "peers",
                            format!("{} has no row for pair {}", m.name, pair.name),
                        )
                    })
            };
            let z = find(&p.zero_flow)?;
            if z.pixels != pair.pixels || (z.epe - pair.mean_gt).abs() > 1e-6 * (1.0 + pair.mean_gt)
            {
                return Err(Error::invalid(
                    "peers",
                    format!(
                        "pair {}: the peers script scored {} known pixels with mean |flow| {}, \
                         pins {} with {}; they must read the same ground truth",
                        pair.name, z.pixels, z.epe, pair.pixels, pair.mean_gt
                    ),
                ));
            }
            for m in &p.methods {
                let q = find(m)?;
                rows.push(MethodScores {
                    method: m.name.clone(),
                    iters: None,
                    epe: q.epe,
                    ae_deg: q.ae_deg,
                    px1: q.px1,
                    px3: q.px3,
                    px5: q.px5,
                    ms_per_pair: q.ms,
                    by_speed: q.by_speed,
                });
            }
        }
        rows.push(zero_scores(&pair.zero_flow));
        per_pair.push(PairResult {
            name: pair.name.clone(),
            source: sources
                .get(&pair.name)
                .cloned()
                .unwrap_or_else(|| pair.name.clone()),
            width: pair.width,
            height: pair.height,
            pixels: pair.pixels,
            mean_gt: pair.mean_gt,
            methods: rows,
        });
    }
    Ok(SetRun {
        set: set.name.clone(),
        camera: cam.name.clone(),
        data: dir.display().to_string(),
        pairs: eval.pairs,
        pixels: eval.pixels,
        mean_gt: eval.zero_flow.epe,
        methods,
        per_pair,
    })
}
