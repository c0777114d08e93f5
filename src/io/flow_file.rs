//! Flow files of any supported format, chosen by extension: `.flo`, KITTI `.png`, `.pfm`, `.exr`.

use std::path::Path;

use super::exr::{read_flow_exr, write_flow_exr};
use super::ext_lower;
use super::flo::{read_flo, write_flo};
use super::kitti::{read_kitti_flow, write_kitti_flow};
use super::pfm::read_pfm_flow;
use crate::error::{Error, Result};
use crate::types::Flow;

/// Reads a flow field by extension: `.flo` (Middlebury), `.png` (KITTI 16-bit), `.pfm`
/// (3-channel, first two are u and v), `.exr` (channels u,v / R,G / X,Y). Unknown or invalid
/// vectors are NaN.
pub fn read_flow(path: &Path) -> Result<Flow> {
    match ext_lower(path).as_str() {
        "flo" => read_flo(path),
        "png" => Ok(read_kitti_flow(path)?.0),
        "pfm" => read_pfm_flow(path),
        "exr" => read_flow_exr(path),
        other => Err(Error::invalid(
            format!("flow file {}", path.display()),
            format!(
                "unsupported extension {other:?}; readable flow formats: .flo, .png (KITTI), \
                 .pfm, .exr"
            ),
        )),
    }
}

/// Writes a flow field by extension: `.flo`, `.png` (KITTI 16-bit; non-finite → invalid,
/// values clamped to about ±512 px), `.exr` (f32 channels u, v).
pub fn write_flow(path: &Path, flow: &Flow) -> Result<()> {
    match ext_lower(path).as_str() {
        "flo" => write_flo(path, flow),
        "png" => write_kitti_flow(path, flow),
        "exr" => write_flow_exr(path, flow),
        other => Err(Error::invalid(
            format!("flow file {}", path.display()),
            format!(
                "unsupported extension {other:?}; writable flow formats: .flo, .png (KITTI), .exr"
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dispatch_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        let mut f = Flow::from_vec(
            2,
            3,
            vec![
                0.5, -1.0, 2.0, 0.0, 3.25, -7.5, 1.0, 1.0, 1.0, 0.0, 0.0, -0.25,
            ],
        )
        .unwrap();
        f.set(1, 2, f32::NAN, f32::NAN);
        for ext in ["flo", "png", "exr", "FLO"] {
            let p = dir.path().join(format!("f.{ext}"));
            write_flow(&p, &f).unwrap();
            let back = read_flow(&p).unwrap();
            assert_eq!(back.valid_mask(), f.valid_mask(), "{ext}");
            assert_eq!(back.get(0, 1), f.get(0, 1), "{ext}");
        }
    }

    #[test]
    fn unknown_extension_lists_supported() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.txt");
        let e = write_flow(&p, &Flow::zeros(1, 1)).unwrap_err().to_string();
        assert!(
            e.contains(".flo") && e.contains(".exr") && e.contains("f.txt"),
            "{e}"
        );
        let e = read_flow(&p).unwrap_err().to_string();
        assert!(e.contains(".pfm"), "{e}");
        assert!(!p.exists());
    }
}
