//! Flow files of any supported format, chosen by extension: `.flo`, KITTI `.png`, `.pfm`, `.exr`.
//!
//! Every reader returns unknown vectors as NaN (both components): the Middlebury marker
//! (a component of magnitude `>= 1e9`), a non-finite component, or KITTI's invalid bit.

use std::path::Path;

use super::atomic::read_bytes;
use super::exr::{decode_flow_exr, write_flow_exr};
use super::ext_lower;
use super::flo::{decode_flo, write_flo};
use super::kitti::{decode_kitti_flow, write_kitti_flow};
use super::pfm::{decode_pfm_flow, write_pfm_flow};
use crate::error::{Error, Result};
use crate::types::Flow;

/// Reads a flow field by extension: `.flo` (Middlebury), `.png` (KITTI 16-bit), `.pfm`
/// (3-channel, first two are u and v), `.exr` (channels u,v / R,G / X,Y). Unknown or invalid
/// vectors are NaN.
pub fn read_flow(path: &Path) -> Result<Flow> {
    check_readable_ext(path)?;
    decode_flow(&read_bytes(path)?, path)
}

/// Decodes the bytes of a flow file as [`read_flow`] does; the extension of `path` picks the
/// format and `path` names the file in errors.
pub fn decode_flow(bytes: &[u8], path: &Path) -> Result<Flow> {
    check_readable_ext(path)?;
    match ext_lower(path).as_str() {
        "flo" => decode_flo(bytes, path),
        "png" => Ok(decode_kitti_flow(bytes, path)?.0),
        "pfm" => decode_pfm_flow(bytes, path),
        _ => decode_flow_exr(bytes, path),
    }
}

/// Refuses an extension that no flow reader knows, before the file is read.
fn check_readable_ext(path: &Path) -> Result<()> {
    match ext_lower(path).as_str() {
        "flo" | "png" | "pfm" | "exr" => Ok(()),
        other => Err(Error::invalid(
            format!("flow file {}", path.display()),
            format!(
                "unsupported extension {other:?}; readable flow formats: .flo, .png (KITTI), \
                 .pfm, .exr"
            ),
        )),
    }
}

/// Writes a flow field by extension: `.flo`, `.png` (KITTI 16-bit; unknown → invalid,
/// values clamped to about ±512 px), `.pfm` (FlyingThings3D layout: colour `PF`, u, v and a
/// zero third channel, little endian, rows bottom to top; NaN kept), `.exr` (f32 channels
/// u, v).
pub fn write_flow(path: &Path, flow: &Flow) -> Result<()> {
    match ext_lower(path).as_str() {
        "flo" => write_flo(path, flow),
        "png" => write_kitti_flow(path, flow),
        "pfm" => write_pfm_flow(path, flow),
        "exr" => write_flow_exr(path, flow),
        other => Err(Error::invalid(
            format!("flow file {}", path.display()),
            format!(
                "unsupported extension {other:?}; writable flow formats: .flo, .png (KITTI), \
                 .pfm, .exr"
            ),
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::is_unknown;

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
        for ext in ["flo", "png", "exr", "pfm", "FLO", "PFM"] {
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

    #[test]
    fn unknown_markers_are_nan_through_every_reader() {
        // is_unknown: the Middlebury marker and non-finite components, on either axis.
        assert!(!is_unknown(0.0, -999_999_999.0 / 1000.0));
        for (u, v) in [
            (1e9, 0.0),
            (0.0, -1e9),
            (f32::NAN, 0.0),
            (0.0, f32::INFINITY),
        ] {
            assert!(is_unknown(u, v), "({u}, {v})");
        }
        // A field with one good vector and one unknown one per marker, through each writer and
        // back through decode_flow: every unknown vector is NaN in both components.
        let dir = tempfile::tempdir().unwrap();
        let markers = [(1e10f32, 0.5f32), (0.5, f32::NAN), (f32::INFINITY, 1.0)];
        for ext in ["flo", "pfm", "exr", "png"] {
            let mut f = Flow::zeros(1, 4);
            f.set(0, 0, 1.5, -2.0);
            for (x, &(u, v)) in markers.iter().enumerate() {
                f.set(0, x + 1, u, v);
            }
            let p = dir.path().join(format!("m.{ext}"));
            write_flow(&p, &f).unwrap();
            let back = decode_flow(&std::fs::read(&p).unwrap(), &p).unwrap();
            assert_eq!(back.get(0, 0), (1.5, -2.0), "{ext}");
            for x in 1..4 {
                let (u, v) = back.get(0, x);
                assert!(u.is_nan() && v.is_nan(), "{ext} pixel {x}: ({u}, {v})");
            }
        }
    }
}
