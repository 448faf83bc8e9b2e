"""The one exception family users see.

Every error a user can cause (a bad scene file, a missing mesh, an unsupported ONNX node, a bad CLI
argument, no GPU) is a ``WgpuRtError`` whose message names the file, node or field at fault; the CLI
prints it without a traceback and exits non-zero.
"""


class WgpuRtError(Exception):
    """Base class for errors caused by input or environment, reported to users as one clear line."""


class NoAdapterError(WgpuRtError):
    """No WebGPU adapter could be found on this machine."""


class SceneError(WgpuRtError):
    """A scene, scene file or mesh is malformed."""


class ModelError(WgpuRtError):
    """An ONNX model cannot be loaded or lowered to our kernels."""


class DeviceLimitError(WgpuRtError):
    """Work exceeds a limit of the WebGPU device (buffer size, bindings, workgroup memory)."""


class ImageError(WgpuRtError):
    """An image file is missing, unreadable, or lacks a layer that is needed."""


class OutputError(WgpuRtError):
    """An output path cannot be written: a folder, inside a file, read-only, or the wrong kind of file."""
