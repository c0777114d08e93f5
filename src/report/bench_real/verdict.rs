//! Where MMS stands in a real-data benchmark, read off its scores: per set and camera against
//! OpenCV's DIS medium on the same pairs (EPE and the 1-px share), and whether its iterations
//! pay (Table S4's shape, Note S11: the error falls from 4 to 12 updates and no longer rises
//! after).

use std::fmt::Write;

use super::report::{BenchRealReport, MethodScores, SetRun};

/// The peer every MMS row is held against.
pub const PEER: &str = "OpenCV DIS medium";
/// The iteration count of the comparison with the peer: the network's default (Note S11).
pub const ITERS: usize = 12;
/// Table S4's shape: from 4 to 12 updates the EPE falls to at most this share where the mean
/// motion exceeds [`MOVING_PX`] ...
pub const FALL_4_TO_12: f64 = 0.95;
/// ... and from 12 to 16 it rises by no more than this share anywhere.
pub const RISE_12_TO_16: f64 = 1.01;
/// The mean motion (px) above which the iterations are expected to pay.
pub const MOVING_PX: f64 = 5.0;

/// One MMS method against the peer on one set through one camera.
#[derive(Clone, Debug, PartialEq)]
pub struct AgainstPeer {
    pub set: String,
    pub camera: String,
    pub mms: MethodScores,
    pub peer: MethodScores,
}

impl AgainstPeer {
    /// Lower EPE than the peer.
    pub fn epe_wins(&self) -> bool {
        self.mms.epe < self.peer.epe
    }
    /// A higher share of pixels within 1 px than the peer.
    pub fn px1_wins(&self) -> bool {
        self.mms.px1 > self.peer.px1
    }
}

/// One MMS method's EPE across iteration counts on one set through one camera.
#[derive(Clone, Debug, PartialEq)]
pub struct IterShape {
    pub set: String,
    pub camera: String,
    pub method: String,
    /// The set's mean true motion (px).
    pub mean_gt: f64,
    /// EPE(12) / EPE(4), where both were measured.
    pub fall: Option<f64>,
    /// EPE(16) / EPE(12), where both were measured.
    pub rise: Option<f64>,
}

impl IterShape {
    /// Whether this row has Table S4's shape (`None`: nothing measured to judge by).
    pub fn holds(&self) -> Option<bool> {
        let fall = self
            .fall
            .map(|f| self.mean_gt <= MOVING_PX || f <= FALL_4_TO_12);
        let rise = self.rise.map(|r| r <= RISE_12_TO_16);
        match (fall, rise) {
            (None, None) => None,
            (a, b) => Some(a.unwrap_or(true) && b.unwrap_or(true)),
        }
    }
}

/// The distinct names among `names`, in their first order.
fn distinct<'a>(names: impl Iterator<Item = &'a str>) -> Vec<&'a str> {
    let mut out: Vec<&str> = Vec::new();
    for n in names {
        if !out.contains(&n) {
            out.push(n);
        }
    }
    out
}

fn epe_of(run: &SetRun, method: &str, iters: usize) -> Option<f64> {
    run.methods
        .iter()
        .find(|m| m.method == method && m.iters == Some(iters))
        .map(|m| m.epe)
}

/// Every MMS method at [`ITERS`] against [`PEER`], for each set and camera where both ran.
pub fn against_peer(r: &BenchRealReport) -> Vec<AgainstPeer> {
    let mut out = Vec::new();
    for run in &r.runs {
        let Some(peer) = run.methods.iter().find(|m| m.method == PEER) else {
            continue;
        };
        for mms in run.methods.iter().filter(|m| m.iters == Some(ITERS)) {
            out.push(AgainstPeer {
                set: run.set.clone(),
                camera: run.camera.clone(),
                mms: mms.clone(),
                peer: peer.clone(),
            });
        }
    }
    out
}

/// Every MMS method's iteration ratios, for each set and camera where at least one was measured.
pub fn iteration_shape(r: &BenchRealReport) -> Vec<IterShape> {
    let mut out = Vec::new();
    for run in &r.runs {
        let mms = run.methods.iter().filter(|m| m.iters.is_some());
        for method in distinct(mms.map(|m| m.method.as_str())) {
            let ratio = |a: usize, b: usize| match (epe_of(run, method, a), epe_of(run, method, b))
            {
                (Some(x), Some(y)) if y > 0.0 => Some(x / y),
                _ => None,
            };
            let row = IterShape {
                set: run.set.clone(),
                camera: run.camera.clone(),
                method: method.to_string(),
                mean_gt: run.mean_gt,
                fall: ratio(12, 4),
                rise: ratio(16, 12),
            };
            if row.holds().is_some() {
                out.push(row);
            }
        }
    }
    out
}

fn mark(ok: bool) -> &'static str {
    if ok { "yes" } else { "**no**" }
}

fn ratio_cell(v: Option<f64>) -> String {
    v.map(|x| format!("{x:.3}")).unwrap_or_else(|| "–".into())
}

/// The report's section: both tables with a count of wins, or a line saying why one is absent.
pub fn markdown(s: &mut String, r: &BenchRealReport) {
    let _ = writeln!(s, "## Against DIS medium, and across iterations\n");
    let peer = against_peer(r);
    if peer.is_empty() {
        let _ = writeln!(
            s,
            "No comparison with {PEER}: the peers did not run or MMS was not measured at {ITERS} \
             iterations.\n"
        );
    } else {
        let _ = writeln!(
            s,
            "MMS at {ITERS} iterations against {PEER} on the same pairs: a win is a lower EPE, \
             or a higher share within 1 px.\n"
        );
        let _ = writeln!(
            s,
            "| set | camera | method | EPE | DIS EPE | lower | 1 px | DIS 1 px | higher |\n|---|---|---|---|---|---|---|---|---|"
        );
        for p in &peer {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.3} | {:.3} | {} | {:.3} | {:.3} | {} |",
                p.set,
                p.camera,
                p.mms.method,
                p.mms.epe,
                p.peer.epe,
                mark(p.epe_wins()),
                p.mms.px1,
                p.peer.px1,
                mark(p.px1_wins())
            );
        }
        s.push('\n');
        for m in distinct(peer.iter().map(|p| p.mms.method.as_str())) {
            let rows: Vec<&AgainstPeer> = peer.iter().filter(|p| p.mms.method == m).collect();
            let both = rows.iter().filter(|p| p.epe_wins() && p.px1_wins()).count();
            let _ = writeln!(
                s,
                "- {m}: lower EPE on {} of {} set-cameras, a higher 1-px share on {}, both on {both}.",
                rows.iter().filter(|p| p.epe_wins()).count(),
                rows.len(),
                rows.iter().filter(|p| p.px1_wins()).count(),
            );
        }
        s.push('\n');
    }
    let shape = iteration_shape(r);
    if shape.is_empty() {
        let _ = writeln!(
            s,
            "No iteration ratios: they need MMS at 4 and 12 or at 12 and 16 iterations.\n"
        );
        return;
    }
    let _ = writeln!(
        s,
        "Table S4's shape: from 4 to 12 iterations the EPE falls to at most {FALL_4_TO_12} of itself \
         where the mean motion exceeds {MOVING_PX} px, and from 12 to 16 it rises by at most \
         {:.0} %.\n",
        (RISE_12_TO_16 - 1.0) * 100.0
    );
    if r.start != "zero" {
        let _ = writeln!(
            s,
            "These runs start from {}; Table S4 starts the network from zero (`--start zero`).\n",
            if r.start.is_empty() {
                "an unrecorded start".to_string()
            } else {
                format!("a {} start", r.start)
            }
        );
    }
    let _ = writeln!(
        s,
        "| set | camera | method | mean motion (px) | EPE 12 / 4 | EPE 16 / 12 | shape |\n|---|---|---|---|---|---|---|"
    );
    for row in &shape {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2} | {} | {} | {} |",
            row.set,
            row.camera,
            row.method,
            row.mean_gt,
            ratio_cell(row.fall),
            ratio_cell(row.rise),
            mark(row.holds() == Some(true))
        );
    }
    s.push('\n');
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::report::bench_real::report::PeersInfo;

    fn m(method: &str, iters: Option<usize>, epe: f64, px1: f64) -> MethodScores {
        MethodScores {
            method: method.into(),
            iters,
            epe,
            ae_deg: 0.0,
            px1,
            px3: 0.0,
            px5: 0.0,
            ms_per_pair: 1.0,
            by_speed: Default::default(),
        }
    }

    fn run(set: &str, mean_gt: f64, methods: Vec<MethodScores>) -> SetRun {
        SetRun {
            set: set.into(),
            camera: "camera".into(),
            data: String::new(),
            pairs: 1,
            pixels: 100,
            mean_gt,
            methods,
            per_pair: Vec::new(),
        }
    }

    fn report(runs: Vec<SetRun>) -> BenchRealReport {
        BenchRealReport {
            config: String::new(),
            weights: "w".into(),
            model: "mms-small".into(),
            parameters: 1,
            start: "zero".into(),
            threads: 1,
            iters: vec![4, 12, 16],
            cameras: vec!["camera".into()],
            peers: PeersInfo {
                ran: true,
                skipped_because: None,
                opencv: None,
                version_warning: None,
                threads: 1,
            },
            skipped: Vec::new(),
            runs,
            summary: Vec::new(),
        }
    }

    /// A run on another OpenCV than the pinned one says so at the top of its report; one on the
    /// pinned version does not.
    #[test]
    fn the_report_warns_of_another_opencv() {
        let mut r = report(vec![run("kitti", 50.0, vec![m(PEER, None, 24.3, 0.32)])]);
        let pinned = super::super::peers::pinned_opencv().expect("pinned");
        r.peers.opencv = Some(pinned.clone());
        r.peers.version_warning = super::super::peers::version_warning(&pinned);
        let md = super::super::markdown::markdown(&r, "pins bench-real");
        assert!(!md.contains("**Warning:**"), "{md}");
        r.peers.opencv = Some("4.14.0".into());
        r.peers.version_warning = super::super::peers::version_warning("4.14.0");
        let md = super::super::markdown::markdown(&r, "pins bench-real");
        assert!(
            md.contains("**Warning:** the peers ran on OpenCV 4.14.0"),
            "{md}"
        );
    }

    /// The wins are read per set from the right rows: the MMS row at 12 iterations, DIS medium
    /// (not DIS fast), and a tie is not a win.
    #[test]
    fn wins_against_dis_medium_are_per_set_at_twelve_iterations() {
        let r = report(vec![
            run(
                "kitti",
                50.0,
                vec![
                    m("mms-small", Some(4), 1.0, 0.9),
                    m("mms-small", Some(12), 14.1, 0.27),
                    m(PEER, None, 24.3, 0.32),
                    m("OpenCV DIS fast", None, 1.0, 0.99),
                ],
            ),
            run(
                "middlebury",
                1.3,
                vec![
                    m("mms-small", Some(12), 0.2, 0.95),
                    m(PEER, None, 0.2, 0.90),
                ],
            ),
        ]);
        let v = against_peer(&r);
        assert_eq!(v.len(), 2);
        assert!(v[0].epe_wins() && !v[0].px1_wins(), "{:?}", v[0]);
        assert_eq!(v[0].peer.epe, 24.3);
        assert!(
            !v[1].epe_wins() && v[1].px1_wins(),
            "a tie in EPE is no win"
        );
        let mut s = String::new();
        markdown(&mut s, &r);
        assert!(
            s.contains(
                "- mms-small: lower EPE on 1 of 2 set-cameras, a higher 1-px share on 1, both on 0."
            ),
            "{s}"
        );
    }

    /// Table S4's shape: a fall of 5 % is asked only where things move more than 5 px; a rise
    /// after 12 iterations fails anywhere.
    #[test]
    fn iteration_shape_asks_for_a_fall_only_on_moving_sets() {
        let r = report(vec![
            run(
                "large, falls",
                20.0,
                vec![
                    m("mms-small", Some(4), 10.0, 0.0),
                    m("mms-small", Some(12), 9.0, 0.0),
                    m("mms-small", Some(16), 9.05, 0.0),
                ],
            ),
            run(
                "large, flat",
                20.0,
                vec![
                    m("mms-small", Some(4), 10.0, 0.0),
                    m("mms-small", Some(12), 9.8, 0.0),
                ],
            ),
            run(
                "small, flat, then rises",
                1.0,
                vec![
                    m("mms-small", Some(4), 1.0, 0.0),
                    m("mms-small", Some(12), 1.0, 0.0),
                    m("mms-small", Some(16), 1.1, 0.0),
                ],
            ),
            run("peer only", 1.0, vec![m(PEER, None, 1.0, 0.5)]),
        ]);
        let shape = iteration_shape(&r);
        assert_eq!(shape.len(), 3, "a set without MMS iterations has no row");
        assert_eq!(shape[0].holds(), Some(true));
        assert!((shape[0].fall.unwrap() - 0.9).abs() < 1e-12);
        assert_eq!(shape[1].holds(), Some(false), "2 % is not the 5 % asked");
        assert_eq!(shape[1].rise, None);
        assert_eq!(shape[2].holds(), Some(false), "a 10 % rise after 12");
        let small_flat = IterShape {
            rise: None,
            ..shape[2].clone()
        };
        assert_eq!(
            small_flat.holds(),
            Some(true),
            "no fall asked of a 1-px set"
        );
        let mut s = String::new();
        markdown(&mut s, &r);
        assert!(!s.contains("starts the network from zero"), "{s}");
        let coarse = BenchRealReport {
            start: "coarse".into(),
            ..r
        };
        let mut s = String::new();
        markdown(&mut s, &coarse);
        assert!(
            s.contains(
                "These runs start from a coarse start; Table S4 starts the network from zero"
            ),
            "a coarse start is named beside the shape: {s}"
        );
    }

    /// Without peers or iteration pairs the section says so instead of printing empty tables.
    #[test]
    fn missing_measurements_are_named() {
        let r = report(vec![run(
            "one",
            3.0,
            vec![m("mms-small", Some(8), 1.0, 0.5)],
        )]);
        let mut s = String::new();
        markdown(&mut s, &r);
        assert!(s.contains("No comparison with OpenCV DIS medium"), "{s}");
        assert!(s.contains("No iteration ratios"), "{s}");
        assert!(!s.contains("| set |"), "{s}");
    }
}
