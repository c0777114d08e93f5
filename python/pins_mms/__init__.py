"""pins's MMS optical-flow network (Notes S9–S11) in PyTorch: loads any pins weights file by its
metadata and gives pins's network flow; exports to ONNX. torch is imported on first use, so
running an exported ONNX file needs only numpy, Pillow and onnxruntime."""

__all__ = ["FlowModel", "Mms", "MmsConfig", "WeightsError", "load"]


def __getattr__(name):
    if name in ("FlowModel", "Mms"):
        from . import model

        return getattr(model, name)
    if name in ("WeightsError", "load"):
        from . import weights

        return getattr(weights, name)
    if name == "MmsConfig":
        from .config import MmsConfig

        return MmsConfig
    raise AttributeError(f"module 'pins_mms' has no attribute {name!r}")
