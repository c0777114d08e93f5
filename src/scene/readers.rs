//! Readers for existing flow datasets (FlyingChairs, FlyingChairs2, Sintel, Middlebury, KITTI
//! layouts), so real image pairs can pass through the metalens camera and keep their flow.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// A dataset's folder layout.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Layout {
    /// Try every layout below and use the first that finds pairs.
    #[default]
    Auto,
    /// `NNNNN_img1.ppm`, `NNNNN_img2.ppm`, `NNNNN_flow.flo` (also the `-img0/-img1/-gt` and
    /// FlyingChairs2 `-img_0/-img_1/-flow_01` namings), in the folder or its `data/`.
    Chairs,
    /// `{clean,final}/SCENE/frame_NNNN.png` with `flow/SCENE/frame_NNNN.flo`, or one scene's
    /// frames and flows side by side in one folder.
    Sintel,
    /// `other-data/NAME/frame10.png`, `frame11.png` with `other-gt-flow/NAME/flow10.flo`, or the
    /// three files in one folder.
    Middlebury,
    /// `image_2/NNNNNN_10.png`, `NNNNNN_11.png` with `flow_occ/NNNNNN_10.png` (16-bit PNG flow),
    /// or `frame1.png`, `frame2.png`, `flow_gt.png` in one folder.
    Kitti,
}

/// One image pair and, if the dataset has it, its ground-truth forward flow.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PairPaths {
    /// A name unique within the dataset (scene and frame).
    pub name: String,
    pub img1: PathBuf,
    pub img2: PathBuf,
    pub flow: Option<PathBuf>,
}

/// Finds the pairs of the dataset at `root`, sorted by name. Errors when the folder is missing
/// or holds no pair in the requested layout.
pub fn discover(root: &Path, layout: Layout) -> Result<Vec<PairPaths>> {
    if !root.is_dir() {
        return Err(Error::invalid(
            "dataset path",
            format!("{} is not a folder", root.display()),
        ));
    }
    let found = match layout {
        Layout::Auto => [
            Layout::Chairs,
            Layout::Sintel,
            Layout::Middlebury,
            Layout::Kitti,
        ]
        .into_iter()
        .map(|l| discover_layout(root, l))
        .find(|r| matches!(r, Ok(v) if !v.is_empty()))
        .unwrap_or(Ok(Vec::new()))?,
        l => discover_layout(root, l)?,
    };
    if found.is_empty() {
        return Err(Error::invalid(
            "dataset",
            format!(
                "no image pairs found in {} with layout {layout:?}",
                root.display()
            ),
        ));
    }
    Ok(found)
}

fn discover_layout(root: &Path, layout: Layout) -> Result<Vec<PairPaths>> {
    let mut v = match layout {
        Layout::Auto => unreachable!("resolved by discover"),
        Layout::Chairs => {
            let data = root.join("data");
            chairs(if data.is_dir() { &data } else { root })?
        }
        Layout::Sintel => sintel(root)?,
        Layout::Middlebury => middlebury(root)?,
        Layout::Kitti => kitti(root)?,
    };
    v.sort_by(|a, b| a.name.cmp(&b.name));
    Ok(v)
}

/// File names in `dir` (not recursive), sorted.
fn names(dir: &Path) -> Result<Vec<String>> {
    let mut out: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| Error::io(dir, e))?
        .filter_map(|e| e.ok())
        .filter(|e| e.path().is_file())
        .filter_map(|e| e.file_name().to_str().map(str::to_owned))
        .collect();
    out.sort();
    Ok(out)
}

fn subdirs(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(|e| e.ok())
                .map(|e| e.path())
                .filter(|p| p.is_dir())
                .collect()
        })
        .unwrap_or_default();
    v.sort();
    v
}

const IMAGE_EXTS: [&str; 5] = ["png", "ppm", "jpg", "jpeg", "pgm"];

fn chairs(dir: &Path) -> Result<Vec<PairPaths>> {
    let files = names(dir)?;
    let has = |n: &str| files.iter().any(|f| f == n);
    // (first-image suffix, second-image suffix, flow suffix)
    let schemes: [(&str, &str, &str); 3] = [
        ("_img1", "_img2", "_flow"),
        ("-img0", "-img1", "-gt"),
        ("-img_0", "-img_1", "-flow_01"),
    ];
    let mut out = Vec::new();
    for f in &files {
        for (s1, s2, sf) in schemes {
            for ext in IMAGE_EXTS {
                if let Some(stem) = f.strip_suffix(&format!("{s1}.{ext}")) {
                    let img2 = format!("{stem}{s2}.{ext}");
                    if has(&img2) {
                        let flow = format!("{stem}{sf}.flo");
                        out.push(PairPaths {
                            name: stem.to_string(),
                            img1: dir.join(f),
                            img2: dir.join(img2),
                            flow: has(&flow).then(|| dir.join(flow)),
                        });
                    }
                }
            }
        }
    }
    Ok(out)
}

/// Consecutive `frame_NNNN.*` images in `frames`, with `frame_NNNN.flo` looked up in `flows`.
fn sintel_scene(frames: &Path, flows: &Path, prefix: &str) -> Result<Vec<PairPaths>> {
    let files = names(frames)?;
    let mut numbered = BTreeMap::new();
    for f in &files {
        if let Some((stem, ext)) = f.rsplit_once('.')
            && IMAGE_EXTS.contains(&ext)
            && let Some(n) = stem
                .strip_prefix("frame_")
                .and_then(|n| n.parse::<u32>().ok())
        {
            numbered.insert(n, (stem.to_string(), frames.join(f)));
        }
    }
    let mut out = Vec::new();
    for (n, (stem, p1)) in &numbered {
        if let Some((_, p2)) = numbered.get(&(n + 1)) {
            let flow = flows.join(format!("{stem}.flo"));
            out.push(PairPaths {
                name: format!("{prefix}{stem}"),
                img1: p1.clone(),
                img2: p2.clone(),
                flow: flow.is_file().then_some(flow),
            });
        }
    }
    Ok(out)
}

fn sintel(root: &Path) -> Result<Vec<PairPaths>> {
    let pass = ["clean", "final"]
        .into_iter()
        .map(|p| root.join(p))
        .find(|p| p.is_dir());
    match pass {
        Some(pass) => {
            let mut out = Vec::new();
            for scene in subdirs(&pass) {
                let name = scene
                    .file_name()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                out.extend(sintel_scene(
                    &scene,
                    &root.join("flow").join(&name),
                    &format!("{name}/"),
                )?);
            }
            Ok(out)
        }
        None => sintel_scene(root, root, ""),
    }
}

fn middlebury_one(frames: &Path, flows: &Path, name: &str) -> Option<PairPaths> {
    let (f1, f2) = (frames.join("frame10.png"), frames.join("frame11.png"));
    let flow = flows.join("flow10.flo");
    (f1.is_file() && f2.is_file()).then(|| PairPaths {
        name: name.to_string(),
        img1: f1,
        img2: f2,
        flow: flow.is_file().then_some(flow),
    })
}

fn middlebury(root: &Path) -> Result<Vec<PairPaths>> {
    let data = root.join("other-data");
    if data.is_dir() {
        let gt = root.join("other-gt-flow");
        Ok(subdirs(&data)
            .into_iter()
            .filter_map(|d| {
                let name = d.file_name()?.to_string_lossy().into_owned();
                middlebury_one(&d, &gt.join(&name), &name)
            })
            .collect())
    } else {
        let name = root
            .file_name()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Ok(middlebury_one(root, root, &name).into_iter().collect())
    }
}

fn kitti(root: &Path) -> Result<Vec<PairPaths>> {
    let images = root.join("image_2");
    if images.is_dir() {
        let flow_dir = ["flow_occ", "flow_noc"]
            .into_iter()
            .map(|d| root.join(d))
            .find(|p| p.is_dir());
        let files = names(&images)?;
        Ok(files
            .iter()
            .filter_map(|f| {
                let stem = f.strip_suffix("_10.png")?;
                let img2 = images.join(format!("{stem}_11.png"));
                img2.is_file().then(|| PairPaths {
                    name: stem.to_string(),
                    img1: images.join(f),
                    img2,
                    flow: flow_dir.as_ref().map(|d| d.join(f)).filter(|p| p.is_file()),
                })
            })
            .collect())
    } else {
        let (f1, f2, fl) = (
            root.join("frame1.png"),
            root.join("frame2.png"),
            root.join("flow_gt.png"),
        );
        Ok((f1.is_file() && f2.is_file())
            .then(|| PairPaths {
                name: "000000".into(),
                img1: f1,
                img2: f2,
                flow: fl.is_file().then_some(fl),
            })
            .into_iter()
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn touch(p: &Path) {
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(p, b"x").unwrap();
    }

    #[test]
    fn finds_each_layout() {
        let d = tempfile::tempdir().unwrap();
        let r = d.path();
        for f in [
            "chairs/00001_img1.ppm",
            "chairs/00001_img2.ppm",
            "chairs/00001_flow.flo",
            "chairs/00002_img1.ppm",
        ] {
            touch(&r.join(f));
        }
        let v = discover(&r.join("chairs"), Layout::Auto).unwrap();
        assert_eq!(v.len(), 1);
        assert!(v[0].flow.is_some());

        for f in [
            "sintel/clean/alley/frame_0001.png",
            "sintel/clean/alley/frame_0002.png",
            "sintel/clean/alley/frame_0003.png",
            "sintel/flow/alley/frame_0001.flo",
        ] {
            touch(&r.join(f));
        }
        let v = discover(&r.join("sintel"), Layout::Sintel).unwrap();
        assert_eq!(v.len(), 2);
        assert_eq!(v[0].name, "alley/frame_0001");
        assert!(v[0].flow.is_some() && v[1].flow.is_none());

        for f in [
            "mb/other-data/Rubber/frame10.png",
            "mb/other-data/Rubber/frame11.png",
            "mb/other-gt-flow/Rubber/flow10.flo",
        ] {
            touch(&r.join(f));
        }
        let v = discover(&r.join("mb"), Layout::Auto).unwrap();
        assert_eq!((v.len(), v[0].name.as_str()), (1, "Rubber"));

        std::fs::create_dir_all(r.join("empty")).unwrap();
        assert!(
            discover(&r.join("empty"), Layout::Auto)
                .unwrap_err()
                .to_string()
                .contains("no image pairs")
        );
        assert!(discover(&r.join("missing"), Layout::Auto).is_err());
    }
}
