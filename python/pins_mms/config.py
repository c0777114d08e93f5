"""The MMS network's sizes (Notes S9–S11), read from a pins weights file's metadata.

The same fields, names and checks as pins's `MmsConfig` (src/flow/model/config.rs): a config
with an unknown or missing key, or a size out of range, is refused with the key named.
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass

NORMS = ("instance", "group", "none")


@dataclass(frozen=True)
class MmsConfig:
    name: str
    encoder_dims: tuple[int, int, int]
    feature_dim: int
    hidden_dim: int
    context_dim: int
    motion_dims: tuple[int, int, int]
    head_dim: int
    dilations: tuple[int, ...]
    corr_levels: int
    corr_radius: int
    iters: int
    feature_norm: str
    context_norm: str

    @classmethod
    def from_json(cls, text: str) -> "MmsConfig":
        """The config of a `pins.model_config` metadata entry; `ValueError` naming the problem."""
        try:
            raw = json.loads(text)
        except json.JSONDecodeError as e:
            raise ValueError(f"model config is not JSON: {e}") from None
        if not isinstance(raw, dict):
            raise ValueError("model config is not a JSON object")
        fields = list(cls.__dataclass_fields__)
        unknown = sorted(set(raw) - set(fields))
        missing = [f for f in fields if f not in raw]
        if unknown:
            raise ValueError(f"model config has unknown keys {unknown}")
        if missing:
            raise ValueError(f"model config lacks {missing}")
        try:
            cfg = cls(
                name=str(raw["name"]),
                encoder_dims=_ints(raw["encoder_dims"], 3, "encoder_dims"),
                feature_dim=_int(raw["feature_dim"], "feature_dim"),
                hidden_dim=_int(raw["hidden_dim"], "hidden_dim"),
                context_dim=_int(raw["context_dim"], "context_dim"),
                motion_dims=_ints(raw["motion_dims"], 3, "motion_dims"),
                head_dim=_int(raw["head_dim"], "head_dim"),
                dilations=_ints(raw["dilations"], None, "dilations"),
                corr_levels=_int(raw["corr_levels"], "corr_levels"),
                corr_radius=_int(raw["corr_radius"], "corr_radius"),
                iters=_int(raw["iters"], "iters"),
                feature_norm=str(raw["feature_norm"]),
                context_norm=str(raw["context_norm"]),
            )
        except TypeError as e:
            raise ValueError(f"model config: {e}") from None
        cfg.validate()
        return cfg

    @classmethod
    def named(cls, name: str) -> "MmsConfig":
        """`mms` (RAFT-sized) or `mms-small` (sized to train on a 2-core CPU)."""
        if name == "mms":
            return cls("mms", (64, 96, 128), 256, 128, 128, (256, 128, 128), 256,
                       (6, 12, 18), 4, 4, 12, "instance", "group")
        if name == "mms-small":
            return cls("mms-small", (32, 48, 64), 96, 64, 48, (64, 32, 64), 96,
                       (6, 12, 18), 4, 4, 12, "instance", "group")
        raise ValueError(f"unknown model {name!r}; use mms or mms-small")

    def validate(self) -> None:
        checks = [
            ("encoder_dims", all(d > 0 for d in self.encoder_dims)),
            ("feature_dim", self.feature_dim > 0),
            ("hidden_dim", self.hidden_dim > 0),
            ("context_dim", self.context_dim > 0),
            ("motion_dims", all(d > 0 for d in self.motion_dims) and self.motion_dims[2] > 2),
            ("head_dim", self.head_dim > 0),
            ("corr_levels", 1 <= self.corr_levels <= 6),
            ("corr_radius", 1 <= self.corr_radius <= 8),
            ("iters", 1 <= self.iters <= 64),
            ("dilations", all(1 <= d <= 64 for d in self.dilations)),
        ]
        for key, ok in checks:
            if not ok:
                raise ValueError(f"model.{key} out of range")
        for key, norm, dims in [
            ("feature_norm", self.feature_norm, self.feature_dim),
            ("context_norm", self.context_norm, self.hidden_dim + self.context_dim),
        ]:
            if norm not in NORMS:
                raise ValueError(f"model.{key} is {norm!r}; expected one of {NORMS}")
            if norm == "group" and (any(d % 8 for d in self.encoder_dims) or dims % 8):
                raise ValueError(f"model.{key}: group norm needs every width divisible by 8")

    @property
    def corr_channels(self) -> int:
        """Channels of one correlation feature vector: levels · (2r+1)²."""
        return self.corr_levels * (2 * self.corr_radius + 1) ** 2

    @property
    def min_side(self) -> int:
        """The smallest input side the pyramid supports: every level needs at least 2 cells."""
        return 8 * max(1 << max(self.corr_levels - 1, 0), 2)

    def to_json(self) -> str:
        d = asdict(self)
        return json.dumps({k: list(v) if isinstance(v, tuple) else v for k, v in d.items()})


def _int(v, key: str) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise ValueError(f"model.{key} must be an integer, got {v!r}")
    return v


def _ints(v, n: int | None, key: str) -> tuple[int, ...]:
    if not isinstance(v, list) or (n is not None and len(v) != n):
        want = f"{n} integers" if n else "a list of integers"
        raise ValueError(f"model.{key} must be {want}, got {v!r}")
    return tuple(_int(x, key) for x in v)
