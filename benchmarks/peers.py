"""The peers the speed benchmarks put beside our engine, found at run time, each with a timing function,
so that one script prints the same rows on lavapipe and, unchanged, on a machine with a CUDA GPU:

- torch running the very network our engine runs (``TorchNetwork``: the layers that
  ``wgpu_rt.nn.graph.load_graph`` lowers an ONNX file to, with their weights, pads and fused
  activations, as torch functional ops, on channels-last tensors): on the CPU always (oneDNN); on CUDA
  (cuDNN with ``cudnn.benchmark``) in fp32 and fp16 where torch sees a CUDA device with cuDNN. torch
  lets cuDNN use TF32 for fp32 convolutions by default on Ampere and later GPUs: such a row says so.
- Intel Open Image Denoise through pyoidn (the RT filter, HDR colour with albedo and normal guides) at
  quality fast / balanced / high: on the CPU, and on CUDA where torch sees a CUDA device and OIDN's
  CUDA backend supports it (its images are then torch CUDA tensors and it runs on torch's stream).
- Mitsuba 3 in its fastest variant here (wgpu_rt/scene/mitsuba.py's variant_choice: cuda_ad_rgb, else llvm_ad_rgb,
  else scalar_rgb).

Discovery never raises: a peer that is missing or cannot run here comes back as one
"NAME: skipped (why)" line, which the benchmark prints in place of its rows. A time is the best of the
repeats after untimed warm-up calls (cuDNN's algorithm search, OIDN's first-run setup and Dr.Jit's
kernel compilation are not timed). On CUDA each timed call sits between two CUDA events on the
current stream; on the CPU it is wall clock, with this process's CPU seconds beside it (all threads:
the stable number on a shared machine).
"""

from __future__ import annotations

import time

import numpy as np

QUALITIES = ("fast", "balanced", "high")
PRECISIONS = ("fp32", "fp16")
DEVICE_NAMES = {"cpu": "CPU", "cuda": "CUDA"}
WARMUP_CALLS = {"cpu": 1, "cuda": 3}   # on CUDA the first calls also search cuDNN's algorithms


def skipped(peer: str, why: str) -> str:
    return f"{peer}: skipped ({why})"


def _import_torch():
    """(torch, None), or (None, why it cannot be imported)."""
    try:
        import torch
    except Exception as err:  # ImportError, or OSError from a broken CUDA library
        return None, f"torch not importable: {type(err).__name__}: {err}"
    return torch, None


def torch_devices() -> tuple[list[str], list[str]]:
    """(the devices torch can run our network on here: "cpu", and "cuda" where torch sees a CUDA device
    with cuDNN; a skipped line for each one that is absent)."""
    torch, why = _import_torch()
    if torch is None:
        return [], [skipped("torch", why)]
    if not torch.cuda.is_available():
        return ["cpu"], [skipped("torch cuDNN", f"torch {torch.__version__} sees no CUDA device")]
    if not torch.backends.cudnn.is_available():
        return ["cpu"], [skipped("torch cuDNN", f"torch {torch.__version__} finds no cuDNN")]
    return ["cpu", "cuda"], []


def torch_precisions(device: str) -> tuple[str, ...]:
    """fp16 runs on CUDA only: torch's CPU convolutions have no fast fp16 path."""
    return PRECISIONS if device == "cuda" else ("fp32",)


def oidn_devices() -> tuple[list[str], list[str]]:
    """(the devices OIDN can denoise on here: "cpu" where its CPU backend supports this processor,
    "cuda" where torch sees a CUDA device (pyoidn takes CUDA images as torch tensors) and OIDN's CUDA
    backend supports it; a skipped line for each one that is absent)."""
    try:
        import pyoidn
    except Exception as err:
        return [], [skipped("OIDN", f"pyoidn not importable: {type(err).__name__}: {err}")]
    devices, lines = [], []
    if pyoidn.Device.is_cpu_available():
        devices.append("cpu")
    else:
        lines.append(skipped("OIDN CPU", "OIDN's CPU backend does not support this processor"))
    torch, why = _import_torch()
    if torch is None:
        lines.append(skipped("OIDN CUDA", why))
    elif not torch.cuda.is_available():
        lines.append(skipped("OIDN CUDA", "torch sees no CUDA device"))
    elif not pyoidn.Device.is_cuda_available(torch.cuda.current_device()):
        lines.append(skipped("OIDN CUDA", f"OIDN's CUDA backend does not support {torch.cuda.get_device_name()}"))
    else:
        devices.append("cuda")
    return devices, lines


def preferred(devices: list[str]) -> str | None:
    """"cuda" when it is among ``devices``, else the first of them (None when there is none)."""
    return "cuda" if "cuda" in devices else (devices[0] if devices else None)


def mitsuba_peer():
    """(the mitsuba module set to the fastest variant here, or None; a skipped line for each faster
    variant that is absent, or for Mitsuba itself)."""
    try:
        from wgpu_rt.scene.mitsuba import load_mitsuba, variant_choice

        variant, lines = variant_choice()
        return load_mitsuba(variant), lines
    except Exception as err:  # not installed, or Dr.Jit failing to load its libraries
        return None, [skipped("Mitsuba", f"{type(err).__name__}: {err}")]


def best_seconds(run, repeats: int, device: str = "cpu") -> tuple[float, float | None]:
    """(best seconds of ``repeats`` calls of ``run``, best CPU seconds of this process or None on CUDA);
    warming up is the caller's. On CUDA the seconds are those between two CUDA events recorded on the
    current stream around the call (the GPU's time, launch gaps included)."""
    if device == "cuda":
        import torch

        best = float("inf")
        for _ in range(repeats):
            start, end = torch.cuda.Event(enable_timing=True), torch.cuda.Event(enable_timing=True)
            torch.cuda.synchronize()
            start.record()
            run()
            end.record()
            end.synchronize()
            best = min(best, start.elapsed_time(end) / 1e3)
        return best, None
    walls, cpus = [], []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        walls.append(time.perf_counter() - wall)
        cpus.append(time.process_time() - cpu)
    return min(walls), min(cpus)


class TorchNetwork:
    """An ONNX network our engine loads, run by torch: the layers ``load_graph`` lowers it to (the ones
    the WGSL kernels run) as torch functional ops on ``device`` ("cpu" or "cuda") in ``precision``.
    Tensors are channels-last: oneDNN's fast layout on the CPU (faster than NCHW for our U-Nets on this
    machine) and cuDNN's (tensor cores in fp16); on CUDA, cuDNN picks its algorithms by measuring
    (``cudnn.benchmark``)."""

    def __init__(self, path, device: str = "cpu", precision: str = "fp32"):
        import torch

        from wgpu_rt.nn.graph import load_graph

        if precision not in PRECISIONS:
            raise ValueError(f"precision must be one of {', '.join(PRECISIONS)}, not {precision!r}")
        self.torch = torch
        self.graph = load_graph(path)
        self.device = torch.device(device)
        self.precision = precision
        self.dtype = {"fp32": torch.float32, "fp16": torch.float16}[precision]
        cuda = self.device.type == "cuda"
        if cuda:
            torch.backends.cudnn.benchmark = True
        self.tf32 = cuda and precision == "fp32" and torch.backends.cudnn.allow_tf32
        self.weights = [self._weights(layer) for layer in self.graph.layers]
        self.last_reader = {name: index for index, layer in enumerate(self.graph.layers) for name in layer.inputs}

    @property
    def label(self) -> str:
        name = "torch cuDNN" if self.device.type == "cuda" else "torch CPU"
        return f"{name} {self.precision}" + (" (TF32 allowed)" if self.tf32 else "")

    def _tensor(self, array: np.ndarray):
        tensor = self.torch.from_numpy(np.array(array, np.float32)).to(self.device, self.dtype)   # a writable copy
        return tensor.contiguous(memory_format=self.torch.channels_last) if tensor.ndim == 4 else tensor

    def _weights(self, layer) -> dict:
        tensors = {}
        if layer.weight is not None:
            # The engine keeps transposed-conv weights as (Cout, Cin, 2, 2); torch wants (Cin, Cout, 2, 2).
            weight = layer.weight.transpose(1, 0, 2, 3) if layer.kind == "conv_transpose" else layer.weight
            tensors["weight"], tensors["bias"] = self._tensor(weight), self._tensor(layer.bias)
        if layer.constant is not None:
            tensors["constant"] = self._tensor(np.reshape(layer.constant, (1, -1, 1, 1)))
        return tensors

    def input(self, x: np.ndarray):
        """``x`` (N, C, H, W) on this network's device, dtype and layout; H and W must be multiples of
        the network's downscale factor (the engine pads to it; this peer takes sizes that need none)."""
        _, channels, height, width = x.shape
        multiple = self.graph.multiple
        if channels != self.graph.input_channels or height % multiple or width % multiple:
            raise ValueError(f"{self.graph.path}: input must be N×{self.graph.input_channels}×H×W with H and W "
                             f"multiples of {multiple}, not {tuple(x.shape)}")
        return self._tensor(x)

    def __call__(self, x):
        """The network's output for an ``input`` tensor (tensors nobody reads again are freed as it goes)."""
        tensors = {self.graph.input_name: x}
        with self.torch.inference_mode():
            for index, (layer, weights) in enumerate(zip(self.graph.layers, self.weights)):
                inputs = [tensors[n] for n in layer.inputs]
                output = self._layer(layer, weights, inputs)
                tensors[layer.output] = self._activate(output, layer.activation, in_place=output is not inputs[0])
                for name in set(layer.inputs):
                    if self.last_reader[name] == index and name != self.graph.output_name:
                        del tensors[name]
        return tensors[self.graph.output_name]

    def numpy(self, x: np.ndarray) -> np.ndarray:
        """The output for a numpy input, as float32 numpy."""
        return self(self.input(x)).float().cpu().numpy()

    def _layer(self, layer, weights: dict, inputs: list):
        functional = self.torch.nn.functional
        x = inputs[0]
        if layer.kind in ("conv", "gemm"):
            top, left, bottom, right = layer.pads
            if (top, left) != (bottom, right):
                x = functional.pad(x, (left, right, top, bottom))
                top = left = 0
            return functional.conv2d(x, weights["weight"], weights["bias"], stride=layer.stride, padding=(top, left))
        if layer.kind == "conv_transpose":
            return functional.conv_transpose2d(x, weights["weight"], weights["bias"], stride=2)
        if layer.kind == "maxpool":
            return functional.max_pool2d(x, 2)
        if layer.kind == "resize":
            return functional.interpolate(x, scale_factor=2, mode="nearest")
        if layer.kind == "concat":
            return self.torch.cat(inputs, dim=1)
        operand = inputs[1] if len(inputs) == 2 else weights.get("constant")   # elementwise
        if operand is None:
            return x
        return x + operand if layer.op == 0 else x * operand

    def _activate(self, x, activation, in_place: bool):
        """``activation`` of ``x``, in place (as torch's ``ReLU(inplace=True)`` does) when ``x`` is a fresh
        tensor that nothing else reads."""
        functional = self.torch.nn.functional
        if activation.kind == 1:
            return functional.relu(x, inplace=in_place)
        if activation.kind == 2:
            return functional.leaky_relu(x, activation.alpha, inplace=in_place)
        if activation.kind == 3:
            return x.sigmoid_() if in_place else x.sigmoid()
        if activation.kind == 4:
            return x.clamp_(activation.lo, activation.hi) if in_place else x.clamp(activation.lo, activation.hi)
        return x


def time_torch(network: TorchNetwork, x: np.ndarray, repeats: int) -> tuple[float, float | None]:
    """``best_seconds`` of ``network`` on ``x`` (already on its device), after warm-up calls."""
    tensor = network.input(x)
    for _ in range(WARMUP_CALLS[network.device.type]):
        network(tensor)
    return best_seconds(lambda: network(tensor), repeats, network.device.type)


def oidn_inputs(height: int, width: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Random (H, W, 3) HDR colour, albedo in [0, 1] and unit normals (OIDN's time does not depend on
    what the pixels hold)."""
    rng = np.random.default_rng(seed)
    color = rng.exponential(1.0, (height, width, 3)).astype(np.float32)
    albedo = rng.uniform(0, 1, (height, width, 3)).astype(np.float32)
    normal = rng.normal(size=(height, width, 3))
    normal = (normal / np.linalg.norm(normal, axis=-1, keepdims=True)).astype(np.float32)
    return color, albedo, normal


def oidn_denoise(color, albedo, normal, quality: str = "high", device: str = "cpu") -> np.ndarray:
    """OIDN on (H, W, 3) numpy images, as numpy: on "cuda" the images go to the GPU as torch tensors
    and the result comes back (the copies are part of the call)."""
    import pyoidn

    images = [np.ascontiguousarray(image, np.float32) for image in (color, albedo, normal)]
    if device == "cuda":
        import torch

        return pyoidn.denoise(*(torch.from_numpy(image).cuda() for image in images), hdr=True,
                              quality=quality).cpu().numpy()
    return pyoidn.denoise(*images, hdr=True, quality=quality)


def oidn_quality(pyoidn, quality: str) -> int:
    """OIDN's constant for ``quality`` (one of QUALITIES)."""
    return {"fast": pyoidn.OIDN_QUALITY_FAST, "balanced": pyoidn.OIDN_QUALITY_BALANCED,
            "high": pyoidn.OIDN_QUALITY_HIGH}[quality]


def oidn_prefiltered(color, albedo, normal, quality: str = "high") -> np.ndarray:
    """OIDN on the CPU as its documentation recommends for noisy aux images, and as Blender's "Accurate"
    prefilter runs it: the albedo and the normal are denoised first (``oidn_clean_guides``), then the colour
    with them as noise-free guides (``cleanAux``)."""
    import pyoidn

    guides = oidn_clean_guides(albedo, normal, quality)
    return pyoidn.denoise(np.ascontiguousarray(color, np.float32), *guides, hdr=True, clean_aux=True,
                          quality=quality)


def oidn_clean_guides(albedo, normal, quality: str = "high") -> tuple[np.ndarray, np.ndarray]:
    """The albedo and the normal each denoised by OIDN's RT filter given that image alone."""
    import pyoidn

    device = pyoidn.Device()
    device.commit()

    def run(name: str, image) -> np.ndarray:
        image = np.ascontiguousarray(image, np.float32)
        output = np.empty_like(image)
        oidn_filter = pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT)
        try:
            oidn_filter.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
            oidn_filter.set_image("output", output, pyoidn.OIDN_FORMAT_FLOAT3)
            oidn_filter.set_quality(oidn_quality(pyoidn, quality))
            oidn_filter.commit()
            oidn_filter.execute()
            error = device.get_error()
            if error:
                raise RuntimeError(f"OIDN failed on the {name}: {error}")
        finally:
            oidn_filter.release()
        return output

    try:
        return run("albedo", albedo), run("normal", normal)
    finally:
        device.release()


class OidnFilter:
    """OIDN's RT filter (HDR colour, albedo and normal guides) on ``device`` at ``quality``, set up and
    committed once for its images; calling it denoises them into ``output``. On CUDA the images are
    torch CUDA tensors and the OIDN device is bound to torch's current stream."""

    def __init__(self, device: str, quality: str, color, albedo, normal):
        import pyoidn

        if quality not in QUALITIES:
            raise ValueError(f"OIDN quality must be one of {', '.join(QUALITIES)}, not {quality!r}")
        images = {"color": color, "albedo": albedo, "normal": normal}
        images = {name: np.ascontiguousarray(image, np.float32) for name, image in images.items()}
        if device == "cuda":
            import torch

            images = {name: torch.from_numpy(image).cuda() for name, image in images.items()}
            self.output = torch.empty_like(images["color"])
            self.device = pyoidn.Device.from_torch(self.output.device)
        else:
            self.output = np.empty_like(images["color"])
            self.device = pyoidn.Device()
        self.images = images   # the filter reads this memory: keep it alive
        self.device.commit()
        self.filter = pyoidn.Filter(self.device, pyoidn.OIDN_FILTER_TYPE_RT)
        for name, image in {**images, "output": self.output}.items():
            self.filter.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
        self.filter.set_bool("hdr", True)
        self.filter.set_quality(oidn_quality(pyoidn, quality))
        self.filter.commit()
        self.check("set-up")

    def check(self, stage: str) -> None:
        error = self.device.get_error()
        if error:
            raise RuntimeError(f"OIDN {stage} failed: {error}")

    def __call__(self) -> None:
        self.filter.execute()

    def release(self) -> None:
        self.filter.release()
        self.device.release()


def time_oidn(device: str, quality: str, height: int, width: int, repeats: int) -> tuple[float, float | None]:
    """``best_seconds`` of OIDN denoising ``oidn_inputs`` already on ``device``, after warm-up calls."""
    denoiser = OidnFilter(device, quality, *oidn_inputs(height, width))
    try:
        for _ in range(WARMUP_CALLS[device]):
            denoiser()
        denoiser.check("execution")
        return best_seconds(denoiser, repeats, device)
    finally:
        denoiser.release()


def time_mitsuba(mi, scene, size, spp: int, max_depth: int, seed: int = 0) -> tuple[np.ndarray, float]:
    """(image, seconds) of one Mitsuba render after a 1-spp warm-up (Dr.Jit compiles its kernels then;
    renders at other sample counts reuse them); the scene load is not timed."""
    from wgpu_rt.scene.mitsuba import timed_render

    timed_render(mi, scene, size, 1, max_depth, seed)
    return timed_render(mi, scene, size, spp, max_depth, seed)
