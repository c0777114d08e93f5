"""pins weights files: safetensors holding the MMS parameters with the model config in the
header's metadata (`pins.model_config`), read without any other package than numpy and torch.
Every tensor is matched by name and shape; a file of another model is refused with the
differences named."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import torch

from .config import MmsConfig
from .model import Mms

CONFIG_KEY = "pins.model_config"
DTYPES = {"F32": np.float32, "F16": np.float16, "F64": np.float64, "BF16": np.uint16}
# The weights shipped in the repository, by the names `pins infer --weights` knows.
BUILTIN = {"default": "mms-small-real", "mms-small-real": "mms-small-real", "mms-small": "mms-small"}
REPO_WEIGHTS = Path(__file__).resolve().parents[2] / "datasets" / "weights"


class WeightsError(ValueError):
    """A weights file that is not a readable pins weights file, with the reason."""


def resolve(name: str) -> Path:
    """A weights file path, or a built-in name (`default`, `mms-small`) in the repository."""
    if name in BUILTIN and not Path(name).exists():
        return REPO_WEIGHTS / f"{BUILTIN[name]}.safetensors"
    return Path(name)


def read(path: str | Path) -> tuple[MmsConfig, dict[str, torch.Tensor], dict[str, str]]:
    """The config, the tensors (float32) and the metadata of a pins weights file."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as e:
        raise WeightsError(f"{path}: cannot read: {e.strerror or e}") from None
    if len(data) < 8:
        raise WeightsError(f"{path}: not a safetensors file: {len(data)} bytes")
    (n,) = struct.unpack("<Q", data[:8])
    if n > len(data) - 8:
        raise WeightsError(f"{path}: not a safetensors file: header of {n} bytes in a file of {len(data)}")
    try:
        header = json.loads(data[8:8 + n])
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise WeightsError(f"{path}: not a safetensors file: header: {e}") from None
    if not isinstance(header, dict):
        raise WeightsError(f"{path}: not a safetensors file: header is not an object")
    meta = header.pop("__metadata__", None) or {}
    if CONFIG_KEY not in meta:
        raise WeightsError(f"{path}: not a pins weights file: no {CONFIG_KEY} in the metadata")
    try:
        config = MmsConfig.from_json(meta[CONFIG_KEY])
    except ValueError as e:
        raise WeightsError(f"{path}: {e}") from None
    body = memoryview(data)[8 + n:]
    tensors = {}
    for name, entry in header.items():
        try:
            dtype, shape, (begin, end) = entry["dtype"], entry["shape"], entry["data_offsets"]
        except (KeyError, TypeError, ValueError):
            raise WeightsError(f"{path}: tensor {name}: malformed entry {entry!r}") from None
        if dtype not in DTYPES:
            raise WeightsError(f"{path}: tensor {name}: dtype {dtype} (expected one of {sorted(DTYPES)})")
        count = int(np.prod(shape)) if shape else 1
        size = np.dtype(DTYPES[dtype]).itemsize
        if not (0 <= begin <= end <= len(body)) or end - begin != count * size:
            raise WeightsError(f"{path}: tensor {name}: data {begin}..{end} does not hold {shape} {dtype}"
                               f" (the file is {len(data)} bytes: truncated?)")
        a = np.frombuffer(body[begin:end], dtype=DTYPES[dtype]).reshape(shape)
        if dtype == "BF16":
            a = (a.astype(np.uint32) << 16).view(np.float32)
        tensors[name] = torch.from_numpy(a.astype(np.float32, copy=True))
    return config, tensors, meta


def load(path: str | Path, device: str | torch.device = "cpu") -> Mms:
    """The network of a pins weights file (`pins train` / `pins export`), in eval mode."""
    path = resolve(str(path))
    config, tensors, _ = read(path)
    tensors = {torch_name(k): v for k, v in tensors.items()}
    model = Mms(config)
    own = model.state_dict()
    missing = sorted(set(own) - set(tensors))
    unexpected = sorted(set(tensors) - set(own))
    wrong = sorted(f"{k} {list(tensors[k].shape)} (expected {list(own[k].shape)})"
                   for k in set(own) & set(tensors) if tensors[k].shape != own[k].shape)
    if missing or unexpected or wrong:
        parts = [f"{what} {_few(names)}" for what, names in
                 [("missing", missing), ("unexpected", unexpected), ("wrong shapes", wrong)] if names]
        raise WeightsError(f"{path}: the tensors do not fit the {config.name} config in its metadata: "
                           + "; ".join(parts))
    bad = [k for k, t in tensors.items() if not torch.isfinite(t).all()]
    if bad:
        raise WeightsError(f"{path}: non-finite values in {_few(sorted(bad))}")
    model.load_state_dict(tensors, strict=True)
    return model.to(device).eval()


def torch_name(pins_name: str) -> str:
    """The module's parameter name of a pins tensor name (`global` is a Python keyword)."""
    return pins_name.replace(".daspp.global.", ".daspp.global_.")


def _few(names: list[str]) -> str:
    return ", ".join(names[:5]) + (f" and {len(names) - 5} more" if len(names) > 5 else "")
