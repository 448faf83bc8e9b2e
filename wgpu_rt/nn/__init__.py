"""The ONNX → WGSL inference engine: ``from wgpu_rt.nn import WgslModel``.

``graph`` loads and lowers ONNX, ``kernels`` holds one class per shader of ``nn_kernels/``, ``model``
plans buffers per resolution and runs, ``profile`` times every dispatch (``wgpu-rt profile``). See
``model`` for the numerics contract (NaN/Inf handling, fp16).
"""

from .model import Plan, WgslModel

__all__ = ["WgslModel", "Plan"]
