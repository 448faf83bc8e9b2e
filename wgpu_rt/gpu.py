"""GPU context: adapter choice, the device, and the few buffer/pipeline helpers every pass shares.

One device per process. Adapters are ranked so that a real GPU beats a CPU rasterizer and Vulkan beats
the other backends (Mesa's lavapipe is exposed twice, via Vulkan and via OpenGL; only the Vulkan one
has compute with f16 and subgroups). ``WGPU_RT_ADAPTER`` (or ``--adapter`` on the CLI) picks one by a
case-insensitive substring of its name or backend.
"""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import wgpu

from .errors import DeviceLimitError, NoAdapterError

ADAPTER_ENV = "WGPU_RT_ADAPTER"
# "1" keeps the bounds checks naga adds to every buffer access (a debugging aid: see shader_module)
BOUNDS_CHECKS_ENV = "WGPU_RT_BOUNDS_CHECKS"

NO_ADAPTER_HELP = (
    "no WebGPU adapter found. wgpu-rt needs a Vulkan driver: on Debian/Ubuntu without a GPU run "
    "`sudo apt-get install -y mesa-vulkan-drivers` (Mesa's lavapipe, a CPU Vulkan driver); with a GPU "
    "install its vendor's Vulkan driver."
)

# Features used when the adapter has them; none is required.
OPTIONAL_FEATURES = ("shader-f16", "timestamp-query", "subgroup")

_BACKEND_RANK = {"Vulkan": 0, "Metal": 0, "D3D12": 1, "OpenGL": 3}
_TYPE_RANK = {"DiscreteGPU": 0, "IntegratedGPU": 1, "VirtualGPU": 2, "CPU": 3, "Unknown": 4}


def adapter_label(adapter) -> str:
    """A one-line name such as 'llvmpipe (LLVM 15.0.6, 256 bits) (CPU) via Vulkan'."""
    return adapter.summary


def ensure_runtime_dir() -> None:
    """Point $XDG_RUNTIME_DIR at a private empty folder when it is unset or not an absolute path to a
    folder (containers, CI, ssh without a login session). Enumerating adapters probes for a Wayland
    display through EGL, and libwayland prints "error: XDG_RUNTIME_DIR is invalid or not set in the
    environment." on every probe otherwise: an "error" a user would read as ours. In an empty folder it
    finds no display and stays quiet."""
    runtime_dir = os.environ.get("XDG_RUNTIME_DIR", "")
    if os.path.isabs(runtime_dir) and os.path.isdir(runtime_dir):
        return
    private = tempfile.mkdtemp(prefix="wgpu-rt-runtime-")   # mode 0700, as the XDG spec asks
    atexit.register(shutil.rmtree, private, ignore_errors=True)
    os.environ["XDG_RUNTIME_DIR"] = private


def list_adapters() -> list:
    """All adapters wgpu can see, best first (see module docstring for the ranking)."""
    ensure_runtime_dir()
    adapters = wgpu.gpu.enumerate_adapters_sync()

    def rank(adapter):
        info = adapter.info
        return (_TYPE_RANK.get(info.get("adapter_type", "Unknown"), 4),
                _BACKEND_RANK.get(info.get("backend_type", ""), 2))

    return sorted(adapters, key=rank)


def select_adapter(name: str | None = None):
    """The adapter to use: the first whose label contains ``name`` (or $WGPU_RT_ADAPTER), else the best."""
    adapters = list_adapters()
    if not adapters:
        raise NoAdapterError(NO_ADAPTER_HELP)
    wanted = name or os.environ.get(ADAPTER_ENV)
    if not wanted:
        return adapters[0]
    for adapter in adapters:
        if wanted.lower() in adapter_label(adapter).lower():
            return adapter
    labels = "\n  ".join(adapter_label(a) for a in adapters)
    raise NoAdapterError(f"no adapter matches {wanted!r} (from --adapter or ${ADAPTER_ENV}); available:\n  {labels}")


def shader_module(device, code: str, label: str = ""):
    """A WGSL shader module without naga's per-access bounds checks, which wgpu-native's
    ``wgpuDeviceCreateShaderModuleTrusted`` allows and wgpu-py does not expose (its descriptor is built
    here as wgpu-py builds it for ``create_shader_module``). Every buffer index in wgpu-rt's shaders is in
    range by construction, and the test suite runs them all this way; dropping the clamps made `cornell`
    trace about 5 % faster on lavapipe (BENCHMARKS.md §11). Loops stay bounded, so a shader that failed
    to terminate could not hang the device. ``WGPU_RT_BOUNDS_CHECKS=1``, or a wgpu-py without the call,
    gives the checked module of ``device.create_shader_module``."""
    from wgpu.backends.wgpu_native import _api
    trusted = getattr(_api.libf, "wgpuDeviceCreateShaderModuleTrusted", None)
    if os.environ.get(BOUNDS_CHECKS_ENV) == "1" or trusted is None:
        return device.create_shader_module(code=code, label=label)
    source = _api.new_struct_p("WGPUShaderSourceWGSL *", code=_api.to_c_string_view(code))
    source[0].chain.next = _api.ffi.NULL
    source[0].chain.sType = _api.lib.WGPUSType_ShaderSourceWGSL
    descriptor = _api.new_struct_p("WGPUShaderModuleDescriptor *",
                                   nextInChain=_api.ffi.cast("WGPUChainedStruct *", source),
                                   label=_api.to_c_string_view(label))
    handle = trusted(device._internal, descriptor, _api.lib.WGPUShaderRuntimeChecks_ForceLoopBounding)
    if handle == _api.ffi.NULL:
        raise RuntimeError(f"shader module {label!r} could not be created")
    return _api.GPUShaderModule(label, handle, device)


@dataclass
class GpuContext:
    """The adapter, its device and what it can do."""

    adapter: object
    device: object
    features: frozenset = field(default_factory=frozenset)

    @property
    def label(self) -> str:
        return adapter_label(self.adapter)

    @property
    def has_f16(self) -> bool:
        return "shader-f16" in self.features

    @property
    def has_timestamps(self) -> bool:
        return "timestamp-query" in self.features

    @property
    def has_subgroups(self) -> bool:
        return "subgroup" in self.features

    @cached_property
    def limits(self) -> dict:
        return dict(self.device.limits)

    @property
    def binding_limit(self) -> int:
        """The most bytes one storage binding can hold: its own limit, or a buffer's where that is lower."""
        return min(self.limits["max-storage-buffer-binding-size"], self.limits["max-buffer-size"])

    @cached_property
    def subgroup_sizes(self) -> np.ndarray | None:
        """Each invocation's subgroup size in a 1-D workgroup of 64 (wgsl/subgroup_probe.wgsl), or None
        without the subgroup feature. get_context probes it when the context is made, so that no frame
        ever pays the readback."""
        if not self.has_subgroups:
            return None
        from . import shaders

        pipeline = self.compute_pipeline(shaders.compose("subgroup_probe.wgsl"), label="subgroup probe")
        sizes = self.storage(64 * 4, label="subgroup probe")
        encoder = self.device.create_command_encoder()
        compute = encoder.begin_compute_pass()
        compute.set_pipeline(pipeline)
        compute.set_bind_group(0, self.bind_group(pipeline, [sizes]))
        compute.dispatch_workgroups(1)
        compute.end()
        self.device.queue.submit([encoder.finish()])
        return self.read(sizes, np.uint32, shape=(64,))

    def check_buffer_size(self, nbytes: int, what: str) -> None:
        """Raise a DeviceLimitError naming ``what`` if one storage binding cannot hold ``nbytes``."""
        limit = self.binding_limit
        if nbytes > limit:
            raise DeviceLimitError(
                f"{what} needs {nbytes / 2**20:.1f} MiB in one storage buffer, over this device's "
                f"max-storage-buffer-binding-size of {limit / 2**20:.1f} MiB ({self.label}); a smaller frame or "
                "scene fits, or an adapter that binds more (a GPU's binds gigabytes: `wgpu-rt info` lists them)")

    # -- buffers -------------------------------------------------------------------------------------
    def upload(self, array: np.ndarray, usage=0, label: str = "") -> object:
        """A storage buffer holding ``array`` (padded to 4 bytes; at least 16 bytes so empty arrays bind)."""
        data = np.ascontiguousarray(array).tobytes()
        self.check_buffer_size(len(data), label or "an uploaded array")
        padded = data + b"\0" * ((-len(data)) % 4 + max(0, 16 - len(data)))
        return self.device.create_buffer_with_data(
            data=padded, usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC
            | wgpu.BufferUsage.COPY_DST | usage, label=label)

    def storage(self, nbytes: int, label: str = "", usage=0, windowed: bool = False) -> object:
        """An uninitialised (zeroed) storage buffer of ``nbytes`` (rounded up to 16). ``windowed``: it is
        only ever bound in windows, so it may exceed one binding (up to max-buffer-size)."""
        if windowed and nbytes > self.limits["max-buffer-size"]:
            raise DeviceLimitError(f"{label or 'a storage buffer'} needs {nbytes / 2**20:.1f} MiB, over this "
                                   f"device's max-buffer-size of {self.limits['max-buffer-size'] / 2**20:.1f} MiB")
        if not windowed:
            self.check_buffer_size(nbytes, label or "a storage buffer")
        return self.device.create_buffer(
            size=max(16, (nbytes + 15) // 16 * 16), label=label,
            usage=wgpu.BufferUsage.STORAGE | wgpu.BufferUsage.COPY_SRC | wgpu.BufferUsage.COPY_DST | usage)

    def uniform(self, data: bytes, label: str = "") -> object:
        padded = data + b"\0" * ((-len(data)) % 16)
        return self.device.create_buffer_with_data(
            data=padded, usage=wgpu.BufferUsage.UNIFORM | wgpu.BufferUsage.COPY_DST, label=label)

    def read(self, buffer, dtype=np.float32, shape=None, nbytes: int | None = None) -> np.ndarray:
        """Copy a GPU buffer back into a numpy array (the only way data leaves the device)."""
        raw = self.device.queue.read_buffer(buffer, 0, nbytes)
        out = np.frombuffer(raw, dtype=dtype)
        if shape is not None:
            out = out[: int(np.prod(shape))].reshape(shape)
        return out.copy()

    # -- pipelines -----------------------------------------------------------------------------------
    def compute_pipeline(self, code: str, entry_point: str = "main", constants: dict | None = None,
                         label: str = "", layout=None) -> object:
        """A compute pipeline for WGSL ``code``; cached by (code, entry point, override constants, layout).

        ``layout`` (a GPUPipelineLayout) defaults to "auto", which drops bindings that the specialized
        code no longer uses; pass the unspecialized pipeline's layout to keep bind groups uniform."""
        key = (code, entry_point, tuple(sorted((constants or {}).items())), layout)
        pipeline = self._pipelines.get(key)
        if pipeline is None:
            module = self._modules.get(code)
            if module is None:
                module = self._modules[code] = shader_module(self.device, code, label)
            compute = {"module": module, "entry_point": entry_point}
            if constants:
                compute["constants"] = {k: float(v) for k, v in constants.items()}
            pipeline = self.device.create_compute_pipeline(layout=layout or "auto", compute=compute,
                                                           label=label)
            self._pipelines[key] = pipeline
        return pipeline

    def bind_group(self, pipeline, buffers: list, group: int = 0) -> object:
        """A bind group for ``pipeline``'s ``group``: binding i gets buffers[i] (whole buffer)."""
        return self.device.create_bind_group(
            layout=pipeline.get_bind_group_layout(group),
            entries=[{"binding": i, "resource": {"buffer": b, "offset": 0, "size": b.size}}
                     for i, b in enumerate(buffers) if b is not None])

    @cached_property
    def _pipelines(self) -> dict:
        return {}

    @cached_property
    def _modules(self) -> dict:
        return {}


_CONTEXTS: dict[str, GpuContext] = {}


def get_context(adapter_name: str | None = None) -> GpuContext:
    """The process-wide context for ``adapter_name`` (default: $WGPU_RT_ADAPTER or the best adapter)."""
    key = adapter_name or os.environ.get(ADAPTER_ENV) or ""
    if key not in _CONTEXTS:
        adapter = select_adapter(adapter_name)
        features = [f for f in OPTIONAL_FEATURES if f in adapter.features]
        limit_names = ("max-storage-buffer-binding-size", "max-buffer-size",
                       "max-storage-buffers-per-shader-stage", "max-compute-workgroup-storage-size",
                       "max-compute-invocations-per-workgroup", "max-compute-workgroup-size-x",
                       "max-compute-workgroup-size-y", "max-compute-workgroups-per-dimension",
                       "max-bind-groups")
        limits = {n: adapter.limits[n] for n in limit_names if n in adapter.limits}
        device = adapter.request_device_sync(required_features=features, required_limits=limits,
                                             label="wgpu-rt")
        context = GpuContext(adapter=adapter, device=device, features=frozenset(features))
        context.subgroup_sizes  # noqa: B018 - probe now, outside any frame
        _CONTEXTS[key] = context
    return _CONTEXTS[key]
