//! OpenEXR images and flow fields through the `exr` crate (first layer, flat f16/f32/u32
//! channels in, f32 channels out), written in memory and then atomically to disk.

use std::io::Cursor;
use std::path::Path;

use exr::prelude as x;
use exr::prelude::{ReadChannels, ReadLayers, WritableImage};

use super::atomic::{read_bytes, write_bytes_atomic};
use super::budget;
use super::unknown::unknown_to_nan;
use crate::error::{Error, Result};
use crate::types::{Flow, Image};

/// One decoded channel: its name and samples as f32, row-major.
struct Channel {
    name: String,
    data: Vec<f32>,
}

/// Decodes the first valid layer of EXR bytes: `(height, width, channels sorted by name)`.
/// The layer sizes and channel counts of every header are checked against the pixel budget
/// before any pixel is read.
fn decode_channels(bytes: &[u8], path: &Path) -> Result<(usize, usize, Vec<Channel>)> {
    let bad = |e: x::Error| Error::format(path, format!("cannot decode OpenEXR: {e}"));
    let meta = x::MetaData::read_from_buffered(Cursor::new(bytes), false).map_err(bad)?;
    for header in &meta.headers {
        let size = header.layer_size;
        budget::check_pixels(
            path,
            "OpenEXR layer",
            size.width() as u64,
            size.height() as u64,
            header.channels.list.len() as u64,
        )?;
    }
    let img = x::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_buffered(Cursor::new(bytes))
        .map_err(bad)?;
    let layer = img.layer_data;
    let (w, h) = (layer.size.width(), layer.size.height());
    let mut out = Vec::with_capacity(layer.channel_data.list.len());
    for ch in layer.channel_data.list {
        let name = ch.name.to_string();
        let data: Vec<f32> = match ch.sample_data {
            x::FlatSamples::F16(v) => v.into_iter().map(|s| s.to_f32()).collect(),
            x::FlatSamples::F32(v) => v,
            x::FlatSamples::U32(v) => v.into_iter().map(|s| s as f32).collect(),
        };
        if data.len() != w * h {
            return Err(Error::format(
                path,
                format!(
                    "EXR channel {name:?} has {} samples for a {w}x{h} layer \
                     (subsampled channels are not supported)",
                    data.len()
                ),
            ));
        }
        out.push(Channel { name, data });
    }
    out.sort_by(|a, b| a.name.cmp(&b.name));
    Ok((h, w, out))
}

/// Index of the channel with exactly this name.
fn find(channels: &[Channel], name: &str) -> Option<usize> {
    channels.iter().position(|c| c.name == name)
}

fn names(channels: &[Channel]) -> String {
    let v: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
    format!("[{}]", v.join(", "))
}

/// Reads an EXR image: channels `R, G, B` (alpha dropped) when present, else a lone `Y`,
/// else every channel sorted by name. Samples are returned as stored (not clamped).
pub fn read_exr(path: &Path) -> Result<Image> {
    decode_exr(&read_bytes(path)?, path)
}

/// Decodes EXR bytes as [`read_exr`] does; `path` is used only in error messages.
pub fn decode_exr(bytes: &[u8], path: &Path) -> Result<Image> {
    let (h, w, chans) = decode_channels(bytes, path)?;
    planes_to_image(h, w, chans, path)
}

/// Decodes EXR bytes as a picture for the camera ([`crate::io::read_image`]): like
/// [`decode_exr`], but only 1 (`Y` or a lone channel) or 3 (`R, G, B` or three channels)
/// channels are accepted, and anything else is refused with the channel names (a 2-channel
/// `u, v` file is a flow field, not an image).
pub(crate) fn decode_exr_as_image(bytes: &[u8], path: &Path) -> Result<Image> {
    let (h, w, chans) = decode_channels(bytes, path)?;
    let listed = names(&chans);
    let flow_like = find(&chans, "u").is_some() && find(&chans, "v").is_some();
    let im = planes_to_image(h, w, chans, path)?;
    if matches!(im.channels(), 1 | 3) {
        return Ok(im);
    }
    let hint = if flow_like {
        "; channels u and v make it a flow field, which is read as flow, not as an image"
    } else {
        ""
    };
    Err(Error::format(
        path,
        format!(
            "an image needs 1 channel (Y) or 3 (R, G, B), this EXR has {} channels {listed}{hint}",
            im.channels()
        ),
    ))
}

/// The image planes of decoded channels: `R, G, B` when present, else `Y`, else all of them.
fn planes_to_image(h: usize, w: usize, mut chans: Vec<Channel>, path: &Path) -> Result<Image> {
    let order: Vec<usize> = match (find(&chans, "R"), find(&chans, "G"), find(&chans, "B")) {
        (Some(r), Some(g), Some(b)) => vec![r, g, b],
        _ => match find(&chans, "Y") {
            Some(y) => vec![y],
            None => (0..chans.len()).collect(),
        },
    };
    if order.is_empty() {
        return Err(Error::format(path, "EXR layer has no channels"));
    }
    let mut data = Vec::with_capacity(order.len() * w * h);
    for &i in &order {
        data.append(&mut chans[i].data);
    }
    Image::from_vec(order.len(), h, w, data)
}

/// Reads a flow EXR: channels `u`,`v`, else `R`,`G`, else `X`,`Y` give the u and v planes.
/// Unknown vectors (a component non-finite or of magnitude `>= 1e9`) become NaN.
pub fn read_flow_exr(path: &Path) -> Result<Flow> {
    decode_flow_exr(&read_bytes(path)?, path)
}

/// Decodes flow EXR bytes as [`read_flow_exr`] does; `path` is used only in error messages.
pub fn decode_flow_exr(bytes: &[u8], path: &Path) -> Result<Flow> {
    let (h, w, mut chans) = decode_channels(bytes, path)?;
    let pair = [("u", "v"), ("R", "G"), ("X", "Y")]
        .iter()
        .find_map(|(a, b)| Some((find(&chans, a)?, find(&chans, b)?)));
    let Some((iu, iv)) = pair else {
        return Err(Error::format(
            path,
            format!(
                "no flow channels in EXR: expected u,v or R,G or X,Y, found {}",
                names(&chans)
            ),
        ));
    };
    let mut data = std::mem::take(&mut chans[iu].data);
    data.append(&mut chans[iv].data);
    unknown_to_nan(&mut data);
    Flow::from_vec(h, w, data)
}

/// Encodes named f32 planes of a `w x h` layer into EXR bytes (ZIP compression).
fn encode(path: &Path, w: usize, h: usize, planes: Vec<(String, Vec<f32>)>) -> Result<Vec<u8>> {
    let what = || format!("EXR data for {}", path.display());
    if w == 0 || h == 0 {
        return Err(Error::invalid(
            what(),
            format!("cannot write an empty {w}x{h} image"),
        ));
    }
    let mut list = Vec::with_capacity(planes.len());
    for (name, data) in planes {
        let text = x::Text::new_or_none(&name)
            .ok_or_else(|| Error::invalid(what(), format!("bad channel name {name:?}")))?;
        list.push(x::AnyChannel::new(text, x::FlatSamples::F32(data)));
    }
    let channels = x::AnyChannels::sort(x::SmallVec::from_vec(list));
    let image = x::Image::from_encoded_channels((w, h), x::Encoding::SMALL_LOSSLESS, channels);
    let mut cur = Cursor::new(Vec::new());
    image
        .write()
        .non_parallel()
        .to_buffered(&mut cur)
        .map_err(|e| Error::invalid(what(), format!("OpenEXR encoding failed: {e}")))?;
    Ok(cur.into_inner())
}

/// Writes an image as f32 EXR atomically: 1 channel is `Y`, 3 are `R`,`G`,`B`, any other
/// count is `C0`, `C1`, ... (named so that they sort in order up to 10 channels; beyond
/// that the zero-padded form `C00`.. is used).
pub fn write_exr(path: &Path, image: &Image) -> Result<()> {
    let (c, h, w) = image.shape();
    if c == 0 {
        return Err(Error::invalid(
            format!("image for {}", path.display()),
            "cannot write an image with no channels",
        ));
    }
    let names: Vec<String> = match c {
        1 => vec!["Y".into()],
        3 => vec!["R".into(), "G".into(), "B".into()],
        _ if c <= 10 => (0..c).map(|i| format!("C{i}")).collect(),
        _ => {
            let digits = (c - 1).to_string().len();
            (0..c).map(|i| format!("C{i:0digits$}")).collect()
        }
    };
    let planes = names
        .into_iter()
        .enumerate()
        .map(|(i, n)| (n, image.plane(i).to_vec()))
        .collect();
    let bytes = encode(path, w, h, planes)?;
    write_bytes_atomic(path, &bytes)
}

/// Writes a flow field as f32 EXR atomically with channels `u` and `v` (NaN kept as NaN).
pub fn write_flow_exr(path: &Path, flow: &Flow) -> Result<()> {
    let planes = vec![
        ("u".into(), flow.u().to_vec()),
        ("v".into(), flow.v().to_vec()),
    ];
    let bytes = encode(path, flow.width(), flow.height(), planes)?;
    write_bytes_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(c: usize, h: usize, w: usize) -> Image {
        let data = (0..c * h * w).map(|i| i as f32 * 0.01 - 0.3).collect();
        Image::from_vec(c, h, w, data).unwrap()
    }

    #[test]
    fn image_round_trips() {
        let dir = tempfile::tempdir().unwrap();
        for c in [1, 2, 3, 4, 12] {
            let p = dir.path().join(format!("i{c}.exr"));
            let im = ramp(c, 5, 7);
            write_exr(&p, &im).unwrap();
            assert_eq!(read_exr(&p).unwrap(), im, "{c} channels");
        }
    }

    #[test]
    fn flow_round_trip_keeps_nan() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.exr");
        let mut f = Flow::from_vec(3, 4, (0..24).map(|i| i as f32 - 12.5).collect()).unwrap();
        f.set(1, 1, f32::NAN, f32::NAN);
        write_flow_exr(&p, &f).unwrap();
        let back = read_flow_exr(&p).unwrap();
        assert_eq!(back.valid_mask(), f.valid_mask());
        assert_eq!(back.get(2, 3), f.get(2, 3));
        assert_eq!(back.get(0, 1), f.get(0, 1));
        // An RGB image can be read as flow (R, G); a grey one cannot.
        write_exr(&p, &ramp(3, 2, 2)).unwrap();
        assert_eq!(read_flow_exr(&p).unwrap().u(), ramp(3, 2, 2).plane(0));
        write_exr(&p, &ramp(1, 2, 2)).unwrap();
        let e = read_flow_exr(&p).unwrap_err().to_string();
        assert!(e.contains("[Y]"), "{e}");
    }

    #[test]
    fn corrupt_and_empty() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("c.exr");
        std::fs::write(&p, b"not an exr at all").unwrap();
        assert!(matches!(read_exr(&p).unwrap_err(), Error::Format { .. }));
        let q = dir.path().join("e.exr");
        assert!(write_exr(&q, &Image::zeros(1, 0, 3)).is_err());
        assert!(!q.exists());
    }

    #[test]
    fn unknown_flow_is_nan_in_both_components() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("u.exr");
        // Written as an image so that the values go in unfiltered: R = u, G = v.
        let mut im = ramp(3, 1, 5);
        for (x, (u, v)) in [
            (f32::NAN, 1.0),
            (2.0, f32::INFINITY),
            (1e9, 0.5),
            (0.5, -1e10),
            (1.5, -2.5),
        ]
        .into_iter()
        .enumerate()
        {
            im.set(0, 0, x, u);
            im.set(1, 0, x, v);
        }
        write_exr(&p, &im).unwrap();
        let f = read_flow_exr(&p).unwrap();
        for x in 0..4 {
            let (u, v) = f.get(0, x);
            assert!(u.is_nan() && v.is_nan(), "pixel {x}: ({u}, {v})");
        }
        assert_eq!(f.get(0, 4), (1.5, -2.5));
    }
}
