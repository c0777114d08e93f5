//! Weights files: safetensors holding the MMS parameters with the model config in the header's
//! metadata (`pins.model_config`), so a file alone is enough to rebuild and run the network.

use std::path::Path;

use burn::module::{Module, ModuleVisitor, Param};
use burn::prelude::*;
use burn::store::{ModuleSnapshot, SafetensorsStore};

use super::model::{Mms, MmsConfig};
use crate::error::{Error, Result};
use crate::io;

/// Metadata key of the model config.
pub const CONFIG_KEY: &str = "pins.model_config";

/// Number of scalar parameters of a module.
pub fn parameter_count<M: Module>(module: &M) -> usize {
    struct Count(usize);
    impl ModuleVisitor for Count {
        fn visit_float<const D: usize>(&mut self, p: &Param<Tensor<D>>) {
            self.0 += p.val().shape().num_elements();
        }
    }
    let mut c = Count(0);
    module.visit(&mut c);
    c.0
}

/// Serialises `model` and its config to safetensors bytes.
pub fn to_bytes(model: &Mms, config: &MmsConfig) -> Result<Vec<u8>> {
    to_bytes_with(model, config, &[])
}

/// Serialises `model`, its config and further metadata entries (key, text) to safetensors
/// bytes, e.g. the training stamp of [`crate::flow::train::stamp`].
pub fn to_bytes_with(model: &Mms, config: &MmsConfig, extra: &[(&str, String)]) -> Result<Vec<u8>> {
    let json =
        serde_json::to_string(config).map_err(|e| Error::invalid("model config", e.to_string()))?;
    let mut store = SafetensorsStore::from_bytes(None).metadata(CONFIG_KEY, json);
    for (key, value) in extra {
        store = store.metadata(*key, value.clone());
    }
    model
        .save_into(&mut store)
        .map_err(|e| Error::invalid("weights", format!("cannot serialise: {e}")))?;
    let bytes = store
        .get_bytes()
        .map_err(|e| Error::invalid("weights", format!("cannot serialise: {e}")))?;
    canonical_safetensors(&bytes)
}

/// The same safetensors content in one canonical byte layout: header keys sorted (tensors and
/// metadata), tensor data in the order of the sorted names, the header padded with spaces to a
/// multiple of 8 bytes. Burn writes its metadata from a hash map, so the same weights could
/// otherwise give different files; with this, equal weights and config give equal bytes.
pub fn canonical_safetensors(bytes: &[u8]) -> Result<Vec<u8>> {
    use serde_json::{Map, Value};
    use std::collections::BTreeMap;
    let bad = |r: &str| Error::invalid("weights", format!("cannot canonicalise safetensors: {r}"));
    let (header, data) = split_header(bytes, Path::new("weights in memory"))?;
    let mut out_header = Map::new();
    let mut out_data = Vec::with_capacity(data.len());
    for (name, entry) in header {
        if name == "__metadata__" {
            let sorted: BTreeMap<String, Value> =
                serde_json::from_value(entry).map_err(|e| bad(&e.to_string()))?;
            out_header.insert(name, Value::Object(sorted.into_iter().collect()));
            continue;
        }
        let offsets = entry
            .get("data_offsets")
            .and_then(|o| o.as_array())
            .and_then(|o| Some((o.first()?.as_u64()? as usize, o.get(1)?.as_u64()? as usize)))
            .ok_or_else(|| bad(&format!("tensor {name} has no data_offsets")))?;
        let slice = data
            .get(offsets.0..offsets.1)
            .ok_or_else(|| bad(&format!("tensor {name} lies outside the data")))?;
        let begin = out_data.len();
        out_data.extend_from_slice(slice);
        let mut e: BTreeMap<String, Value> =
            serde_json::from_value(entry).map_err(|e| bad(&e.to_string()))?;
        e.insert(
            "data_offsets".into(),
            Value::from(vec![begin as u64, out_data.len() as u64]),
        );
        out_header.insert(name, Value::Object(e.into_iter().collect()));
    }
    let mut text =
        serde_json::to_vec(&Value::Object(out_header)).map_err(|e| bad(&e.to_string()))?;
    while !text.len().is_multiple_of(8) {
        text.push(b' ');
    }
    let mut out = Vec::with_capacity(8 + text.len() + out_data.len());
    out.extend_from_slice(&(text.len() as u64).to_le_bytes());
    out.extend_from_slice(&text);
    out.extend_from_slice(&out_data);
    Ok(out)
}

/// Writes `model` and its config to `path` atomically.
pub fn save(path: &Path, model: &Mms, config: &MmsConfig) -> Result<()> {
    io::write_bytes_atomic(path, &to_bytes(model, config)?)
}

/// Writes `model`, its config and further metadata entries to `path` atomically.
pub fn save_with(
    path: &Path,
    model: &Mms,
    config: &MmsConfig,
    extra: &[(&str, String)],
) -> Result<()> {
    io::write_bytes_atomic(path, &to_bytes_with(model, config, extra)?)
}

/// The model config stored in a safetensors header.
pub fn read_config(bytes: &[u8], what: &Path) -> Result<MmsConfig> {
    let json = read_metadata(bytes, what, CONFIG_KEY)?.ok_or_else(|| {
        Error::format(
            what,
            format!("not a pins weights file: no {CONFIG_KEY} in the metadata"),
        )
    })?;
    let cfg: MmsConfig = serde_json::from_str(&json)
        .map_err(|e| Error::format(what, format!("not a pins weights file: model config: {e}")))?;
    cfg.validate()
        .map_err(|e| Error::format(what, format!("model config: {e}")))?;
    Ok(cfg)
}

/// The text stored under `key` in a safetensors header's metadata, if any.
pub fn read_metadata(bytes: &[u8], what: &Path, key: &str) -> Result<Option<String>> {
    let (header, _) = split_header(bytes, what)?;
    Ok(header
        .get("__metadata__")
        .and_then(|m| m.get(key))
        .and_then(|v| v.as_str())
        .map(str::to_string))
}

/// A safetensors header: its entries by name (`__metadata__` among them).
pub type Header = std::collections::BTreeMap<String, serde_json::Value>;

/// A safetensors file's header (entries by name, `__metadata__` among them) and the data after
/// it: the one reader of the format's framing (an 8-byte little-endian length, then that many
/// bytes of JSON). A short file, a length past the end and bad JSON are named errors.
pub fn split_header<'a>(bytes: &'a [u8], what: &Path) -> Result<(Header, &'a [u8])> {
    let bad = |r: String| Error::format(what, format!("not a pins weights file: {r}"));
    let n = bytes
        .get(..8)
        .and_then(|b| b.try_into().ok())
        .map(u64::from_le_bytes)
        .ok_or_else(|| bad("shorter than a safetensors header".into()))?;
    let end = usize::try_from(n)
        .ok()
        .filter(|&n| n <= 100 << 20)
        .and_then(|n| n.checked_add(8))
        .filter(|&end| end <= bytes.len())
        .ok_or_else(|| bad(format!("header of {n} bytes in a file of {}", bytes.len())))?;
    let header =
        serde_json::from_slice(&bytes[8..end]).map_err(|e| bad(format!("header JSON: {e}")))?;
    Ok((header, &bytes[end..]))
}

/// Builds the network described by the bytes' config on `device` and loads its weights. Every
/// tensor must be present with its shape: a file of another config is an error.
pub fn from_bytes(bytes: &[u8], what: &Path, device: &Device) -> Result<(Mms, MmsConfig)> {
    let cfg = read_config(bytes, what)?;
    let mut model = Mms::new(&cfg, device);
    let mut store = SafetensorsStore::from_bytes(Some(bytes.to_vec()))
        .validate(true)
        .allow_partial(false);
    let applied = model.load_from(&mut store).map_err(|e| {
        Error::format(
            what,
            format!("weights do not fit the {} config: {e}", cfg.name),
        )
    })?;
    if !applied.errors.is_empty() || !applied.missing.is_empty() || !applied.unused.is_empty() {
        return Err(Error::format(
            what,
            format!(
                "weights do not fit the {} config: {} errors, {} missing and {} unused tensors",
                cfg.name,
                applied.errors.len(),
                applied.missing.len(),
                applied.unused.len()
            ),
        ));
    }
    Ok((model, cfg))
}

/// Loads a weights file.
pub fn load(path: &Path, device: &Device) -> Result<(Mms, MmsConfig)> {
    let bytes = io::read_bytes(path)?;
    from_bytes(&bytes, path, device)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A safetensors file by hand: `entries` are (name, f32 values) written in the given order,
    /// the metadata keys in the given order.
    fn handmade(entries: &[(&str, &[f32])], meta: &[(&str, &str)]) -> Vec<u8> {
        let mut header = String::from("{");
        let mut data = Vec::new();
        for (k, v) in meta.iter().enumerate() {
            if k == 0 {
                header += "\"__metadata__\":{";
            }
            header += &format!("\"{}\":\"{}\"", v.0, v.1);
            header += if k + 1 == meta.len() { "}," } else { "," };
        }
        for (i, (name, values)) in entries.iter().enumerate() {
            let begin = data.len();
            for v in *values {
                data.extend_from_slice(&v.to_le_bytes());
            }
            header += &format!(
                "\"{name}\":{{\"dtype\":\"F32\",\"shape\":[{}],\"data_offsets\":[{begin},{}]}}",
                values.len(),
                data.len()
            );
            if i + 1 < entries.len() {
                header += ",";
            }
        }
        header += "}";
        let mut out = (header.len() as u64).to_le_bytes().to_vec();
        out.extend_from_slice(header.as_bytes());
        out.extend_from_slice(&data);
        out
    }

    #[test]
    fn the_same_content_in_any_order_gives_the_same_bytes() {
        let a = handmade(
            &[("b", &[1.0, 2.0]), ("a", &[3.0])],
            &[("x", "1"), ("format", "pt")],
        );
        let b = handmade(
            &[("a", &[3.0]), ("b", &[1.0, 2.0])],
            &[("format", "pt"), ("x", "1")],
        );
        assert_ne!(a, b);
        let (ca, cb) = (
            canonical_safetensors(&a).unwrap(),
            canonical_safetensors(&b).unwrap(),
        );
        assert_eq!(ca, cb);
        let n = u64::from_le_bytes(ca[..8].try_into().unwrap()) as usize;
        assert_eq!(n % 8, 0, "header padded to 8 bytes");
        // The data follows the sorted names: a (3.0) then b (1.0, 2.0).
        assert_eq!(&ca[8 + n..8 + n + 4], &3.0f32.to_le_bytes());
        assert_eq!(canonical_safetensors(&ca).unwrap(), ca, "idempotent");
        assert!(canonical_safetensors(&a[..20]).is_err());
    }

    #[test]
    fn equal_models_serialise_to_equal_bytes_and_load_back() {
        let dev = Device::flex();
        let cfg = MmsConfig::named("mms-small").unwrap();
        dev.seed(7);
        let m = Mms::new(&cfg, &dev);
        let first = to_bytes(&m, &cfg).unwrap();
        for _ in 0..4 {
            assert_eq!(to_bytes(&m, &cfg).unwrap(), first);
        }
        let (back, back_cfg) = from_bytes(&first, Path::new("mem"), &dev).unwrap();
        assert_eq!(back_cfg, cfg);
        assert_eq!(to_bytes(&back, &back_cfg).unwrap(), first);
    }
}
