//! Weight averaging (stochastic weight averaging, Izmailov et al. 2018; Wortsman et al.'s
//! "model soups" 2022): the mean, tensor by tensor, of several weights files of one network.
//! Snapshots of one training run taken at a high learning rate lie around a minimum that none
//! of them reaches; their mean lies nearer its centre (training campaign, Note S11).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use burn::prelude::*;

use super::model::MmsConfig;
use super::train::stamp::TrainingStamp;
use super::weights;
use crate::error::{Error, Result};
use crate::io;

/// Metadata key of the sources of an averaged weights file.
pub const AVERAGE_KEY: &str = "pins.average";

/// The tensors of a safetensors file by name: shape and values (F32 only, as pins writes).
pub type Tensors = BTreeMap<String, (Vec<usize>, Vec<f32>)>;

/// An averaged weights file.
pub struct Averaged {
    /// The weights file's bytes (config and sources in its metadata).
    pub bytes: Vec<u8>,
    pub config: MmsConfig,
    /// Each source's training step, where its stamp records one.
    pub steps: Vec<Option<usize>>,
    pub parameters: usize,
}

/// The mean of the weights files `files` (at least two, one config, the same tensors). The
/// result has no training stamp: it is not a point of any run's schedule, so
/// `--continue-from` refuses it and `--init` takes it.
pub fn average(files: &[PathBuf]) -> Result<Averaged> {
    if files.len() < 2 {
        return Err(Error::invalid(
            "weights",
            format!("averaging needs at least two files, got {}", files.len()),
        ));
    }
    let mut config: Option<MmsConfig> = None;
    let mut sum: BTreeMap<String, (Vec<usize>, Vec<f64>)> = BTreeMap::new();
    let mut steps = Vec::with_capacity(files.len());
    for (i, path) in files.iter().enumerate() {
        let bytes = io::read_bytes(path)?;
        let cfg = weights::read_config(&bytes, path)?;
        if let Some(first) = &config
            && *first != cfg
        {
            return Err(Error::format(
                path,
                format!(
                    "model config {} differs from that of {} ({}): only weights of one network \
                     average",
                    cfg.name,
                    files[0].display(),
                    first.name
                ),
            ));
        }
        steps.push(TrainingStamp::read(&bytes, path)?.map(|s| s.step));
        let tensors = read_tensors(&bytes, path)?;
        if i == 0 {
            sum = tensors
                .into_iter()
                .map(|(k, (shape, v))| (k, (shape, v.into_iter().map(f64::from).collect())))
                .collect();
        } else {
            add(&mut sum, tensors, path, &files[0])?;
        }
        config.get_or_insert(cfg);
    }
    let config = config.ok_or_else(|| Error::invalid("weights", "no file"))?;
    let n = files.len() as f64;
    let mean: Tensors = sum
        .into_iter()
        .map(|(k, (shape, v))| (k, (shape, v.into_iter().map(|s| (s / n) as f32).collect())))
        .collect();
    // Through the network and back: the result loads as any weights file does, and is written
    // in the same canonical layout.
    let what = Path::new("the average");
    let raw = write_tensors(&mean, &config)?;
    let (model, _) = weights::from_bytes(&raw, what, &Device::flex())?;
    let sources = serde_json::json!({
        "files": files.iter().map(|p| p.file_name().map_or_else(
            || p.display().to_string(),
            |f| f.to_string_lossy().into_owned(),
        )).collect::<Vec<_>>(),
        "steps": steps,
    });
    let bytes = weights::to_bytes_with(&model, &config, &[(AVERAGE_KEY, sources.to_string())])?;
    Ok(Averaged {
        bytes,
        parameters: weights::parameter_count(&model),
        config,
        steps,
    })
}

/// Adds `tensors` (of `path`) into `sum`, which holds those of `first`: the same names and
/// shapes, finite values.
fn add(
    sum: &mut BTreeMap<String, (Vec<usize>, Vec<f64>)>,
    tensors: Tensors,
    path: &Path,
    first: &Path,
) -> Result<()> {
    let differ = |what: String| {
        Error::format(
            path,
            format!("{what} (against {}): not the same network", first.display()),
        )
    };
    if let Some(k) = sum.keys().find(|k| !tensors.contains_key(*k)) {
        return Err(differ(format!("lacks tensor {k}")));
    }
    for (k, (shape, values)) in tensors {
        let Some((want, acc)) = sum.get_mut(&k) else {
            return Err(differ(format!("has an extra tensor {k}")));
        };
        if *want != shape {
            return Err(differ(format!("tensor {k} is {shape:?}, not {want:?}")));
        }
        for (a, v) in acc.iter_mut().zip(values) {
            *a += f64::from(v);
        }
    }
    Ok(())
}

/// The F32 tensors of safetensors `bytes`; non-finite values and other types are errors.
pub fn read_tensors(bytes: &[u8], what: &Path) -> Result<Tensors> {
    let bad = |r: String| Error::format(what, format!("not a pins weights file: {r}"));
    let (header, data) = weights::split_header(bytes, what)?;
    let mut out = Tensors::new();
    for (name, entry) in header {
        if name == "__metadata__" {
            continue;
        }
        let field = |key: &str| {
            entry
                .get(key)
                .ok_or_else(|| bad(format!("tensor {name} has no {key}")))
        };
        if field("dtype")?.as_str() != Some("F32") {
            return Err(bad(format!(
                "tensor {name} is {}, not F32",
                field("dtype")?
            )));
        }
        let ints = |key: &str| -> Result<Vec<usize>> {
            field(key)?
                .as_array()
                .and_then(|a| a.iter().map(|v| v.as_u64().map(|v| v as usize)).collect())
                .ok_or_else(|| bad(format!("tensor {name}: {key} is not a list of integers")))
        };
        let (shape, offsets) = (ints("shape")?, ints("data_offsets")?);
        let bytes_held = shape
            .iter()
            .try_fold(4usize, |n, &d| n.checked_mul(d))
            .ok_or_else(|| bad(format!("tensor {name}: shape {shape:?} too large")))?;
        let slice = match offsets[..] {
            [a, b] if a <= b && b <= data.len() && b - a == bytes_held => &data[a..b],
            _ => {
                return Err(bad(format!(
                    "tensor {name}: data {offsets:?} does not hold {shape:?} F32 in {} bytes",
                    data.len()
                )));
            }
        };
        let values: Vec<f32> = slice
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect();
        if values.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!("tensor {name} holds non-finite values")));
        }
        out.insert(name, (shape, values));
    }
    Ok(out)
}

/// Safetensors bytes of `tensors` with `config` in the metadata.
fn write_tensors(tensors: &Tensors, config: &MmsConfig) -> Result<Vec<u8>> {
    let json = |e: serde_json::Error| Error::invalid("weights", e.to_string());
    let mut header = serde_json::Map::new();
    header.insert(
        "__metadata__".into(),
        serde_json::json!({ weights::CONFIG_KEY: serde_json::to_string(config).map_err(json)? }),
    );
    let mut data = Vec::new();
    for (name, (shape, values)) in tensors {
        let begin = data.len();
        for v in values {
            data.extend_from_slice(&v.to_le_bytes());
        }
        header.insert(
            name.clone(),
            serde_json::json!({"dtype": "F32", "shape": shape, "data_offsets": [begin, data.len()]}),
        );
    }
    let text = serde_json::to_vec(&serde_json::Value::Object(header)).map_err(json)?;
    let mut out = (text.len() as u64).to_le_bytes().to_vec();
    out.extend_from_slice(&text);
    out.extend_from_slice(&data);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flow::model::Mms;

    fn saved(dir: &Path, name: &str, cfg: &MmsConfig, seed: u64) -> PathBuf {
        let dev = Device::flex();
        dev.seed(seed);
        let p = dir.join(name);
        weights::save(&p, &Mms::new(cfg, &dev), cfg).unwrap();
        p
    }

    #[test]
    fn the_average_is_the_mean_of_every_tensor_and_loads() {
        let dir = tempfile::tempdir().unwrap();
        let cfg = MmsConfig::mms_small();
        let files: Vec<PathBuf> = (0..3)
            .map(|i| saved(dir.path(), &format!("w{i}.safetensors"), &cfg, 10 + i))
            .collect();
        let avg = average(&files).unwrap();
        assert_eq!(avg.config, cfg);
        assert_eq!(avg.steps, vec![None; 3]);
        let got = read_tensors(&avg.bytes, Path::new("avg")).unwrap();
        let inputs: Vec<Tensors> = files
            .iter()
            .map(|p| read_tensors(&std::fs::read(p).unwrap(), p).unwrap())
            .collect();
        assert_eq!(got.len(), inputs[0].len());
        for (name, (shape, values)) in &got {
            assert_eq!(shape, &inputs[0][name].0);
            for (j, v) in values.iter().enumerate() {
                let want = inputs.iter().map(|t| f64::from(t[name].1[j])).sum::<f64>() / 3.0;
                assert!(
                    (f64::from(*v) - want).abs() <= 1e-6 * want.abs().max(1.0),
                    "{name}"
                );
            }
        }
        // A weights file like any other, with its sources, and no stamp to continue from.
        let (_, back) = weights::from_bytes(&avg.bytes, Path::new("avg"), &Device::flex()).unwrap();
        assert_eq!(back, cfg);
        let sources = weights::read_metadata(&avg.bytes, Path::new("avg"), AVERAGE_KEY)
            .unwrap()
            .unwrap();
        assert!(sources.contains("w2.safetensors"), "{sources}");
        assert!(
            TrainingStamp::read(&avg.bytes, Path::new("avg"))
                .unwrap()
                .is_none()
        );
        // The mean of one file's copies is that file's tensors, bit for bit.
        let same = average(&[files[0].clone(), files[0].clone()]).unwrap();
        assert_eq!(
            read_tensors(&same.bytes, Path::new("same")).unwrap(),
            inputs[0]
        );
    }

    #[test]
    fn other_networks_and_single_files_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let small = saved(dir.path(), "small.safetensors", &MmsConfig::mms_small(), 1);
        let mut other_cfg = MmsConfig::mms_small();
        other_cfg.corr_radius = 3;
        let other = saved(dir.path(), "other.safetensors", &other_cfg, 2);
        let err = average(&[small.clone(), other]).err().unwrap().to_string();
        assert!(err.contains("only weights of one network"), "{err}");
        let err = average(std::slice::from_ref(&small))
            .err()
            .unwrap()
            .to_string();
        assert!(err.contains("at least two"), "{err}");
        let text = dir.path().join("text.safetensors");
        std::fs::write(&text, b"not weights").unwrap();
        let err = average(&[small, text]).err().unwrap().to_string();
        assert!(err.contains("not a pins weights file"), "{err}");
    }
}
