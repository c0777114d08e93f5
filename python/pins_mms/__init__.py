"""pins's MMS optical-flow network (Notes S9–S11) in PyTorch: loads any pins weights file by its
metadata and gives pins's network flow; exports to ONNX."""

from .config import MmsConfig
from .model import FlowModel, Mms
from .weights import WeightsError, load

__all__ = ["FlowModel", "Mms", "MmsConfig", "WeightsError", "load"]
