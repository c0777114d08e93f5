"""Images in and flow out as pins reads and writes them: 8-bit samples / 255, 16-bit / 65535,
grey repeated to RGB, alpha dropped; Middlebury `.flo` (magic 202021.25, width, height, then
(u, v) interleaved row by row, little-endian float32)."""

from __future__ import annotations

import os
import struct
import tempfile
from pathlib import Path

import numpy as np

FLO_MAGIC = 202021.25


def read_image(path: str | Path) -> np.ndarray:
    """`[3, H, W]` float32 in [0, 1]."""
    from PIL import Image  # only the command line needs Pillow

    path = Path(path)
    try:
        with Image.open(path) as im:
            mode = im.mode
            bits16 = mode in ("I;16", "I;16B", "I;16L", "I") or _png_bit_depth(path) == 16
            if bits16 and mode not in ("I;16", "I;16B", "I;16L", "I"):
                raise ValueError(f"{path}: 16-bit {mode} cannot be read exactly by Pillow; "
                                 "convert it to 8 bits or pass arrays to FlowModel")
            if mode in ("I;16", "I;16B", "I;16L", "I"):
                a = np.asarray(im, dtype=np.float64).astype(np.float32) / np.float32(65535.0)
                a = np.repeat(a[None], 3, 0)
            elif mode in ("L", "LA", "1"):
                a = np.asarray(im.convert("L"), dtype=np.uint8).astype(np.float32) / np.float32(255.0)
                a = np.repeat(a[None], 3, 0)
            else:  # colour, palette (expanded to RGB as pins's decoder does)
                a = np.asarray(im.convert("RGB"), dtype=np.uint8).astype(np.float32) / np.float32(255.0)
                a = a.transpose(2, 0, 1)
    except OSError as e:
        raise ValueError(f"{path}: cannot read the image: {e}") from None
    return np.ascontiguousarray(a, dtype=np.float32)


def _png_bit_depth(path: Path) -> int | None:
    with open(path, "rb") as f:
        head = f.read(25)
    if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) == 25:
        return head[24]
    return None


def read_flo(path: str | Path) -> np.ndarray:
    """`[2, H, W]` float32."""
    data = Path(path).read_bytes()
    if len(data) < 12 or struct.unpack("<f", data[:4])[0] != FLO_MAGIC:
        raise ValueError(f"{path}: not a .flo file")
    w, h = struct.unpack("<ii", data[4:12])
    if w <= 0 or h <= 0 or len(data) != 12 + 8 * w * h:
        raise ValueError(f"{path}: .flo of {w}x{h} in {len(data)} bytes")
    return np.frombuffer(data[12:], "<f4").reshape(h, w, 2).transpose(2, 0, 1).copy()


def write_flo(path: str | Path, flow: np.ndarray) -> None:
    """Writes `[2, H, W]` atomically (a temporary file beside it, renamed)."""
    path = Path(path)
    _, h, w = flow.shape
    body = np.ascontiguousarray(flow.transpose(1, 2, 0), dtype="<f4").tobytes()
    fd, tmp = tempfile.mkstemp(dir=path.parent if str(path.parent) else ".", prefix=".flo-")
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(struct.pack("<fii", FLO_MAGIC, w, h) + body)
        publish(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def publish(tmp: str | Path, path: str | Path) -> None:
    """Renames a finished temporary file onto `path` with the permissions a new file gets
    (mkstemp makes it private)."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(tmp, 0o666 & ~mask)
    os.replace(tmp, path)
