"""``wgpu-rt denoise``: denoise an EXR (colour + albedo/normal/depth layers) with a shipped or given model,
run by the WGSL network engine."""

from __future__ import annotations

HELP = "denoise an EXR that carries colour plus albedo, normal and depth layers"

DEFAULT_MODEL = "denoiser.onnx"
REQUIRED_LAYERS = ("color", "albedo", "normal", "depth")
PAD_MULTIPLE = 16        # covers UNets of up to 5 levels; the padding is cropped off again


def add_arguments(parser) -> None:
    parser.add_argument("input", metavar="IN.exr", help="noisy render with albedo, normal and depth layers")
    parser.add_argument("--out", required=True, metavar="OUT.exr", help="denoised EXR (other layers kept)")
    parser.add_argument("--model", help=f"denoiser ONNX (default: the shipped {DEFAULT_MODEL})")
    parser.add_argument("--precision", choices=["fp32", "fp16"], default="fp32",
                        help="network arithmetic (fp16 needs the shader-f16 feature)")


def default_model_path():
    """The shipped denoiser, found through importlib.resources so an installed wheel works too."""
    from importlib import resources

    return resources.files("wgpu_rt.models").joinpath(DEFAULT_MODEL)


def load_model(path=None, precision: str = "fp32"):
    """A WgslModel of ``path`` (default: the shipped denoiser); a missing file is a ModelError naming it."""
    from pathlib import Path

    from ..errors import ModelError
    from ..nn import WgslModel

    path = Path(str(path or default_model_path()))
    if not path.is_file():
        raise ModelError(f"{path}: no such model file")
    return WgslModel(path, precision=precision)


def denoise(model, color, albedo, normal, depth):
    """(H, W, 3) linear HDR colour + G-buffers → the denoised (H, W, 3) colour (finite, ≥ 0)."""
    import numpy as np

    from ..frame.pack import pack_denoiser_input
    from ..frame.unpack import unpack_denoiser_output
    from ..train.trainer import pad_to_multiple

    height, width = color.shape[:2]
    x = pad_to_multiple(pack_denoiser_input(color, albedo, normal, depth)[None], PAD_MULTIPLE)
    out = np.asarray(model(x), np.float32)[0, :, :height, :width]
    return unpack_denoiser_output(out, albedo)


def run(args) -> int:
    import time

    from ..io import read_exr, require_layers, write_exr

    images = read_exr(args.input)
    require_layers(images, args.input, *REQUIRED_LAYERS)
    model = load_model(args.model, args.precision)
    started = time.perf_counter()
    color = denoise(model, *(images[name] for name in REQUIRED_LAYERS))
    seconds = time.perf_counter() - started
    write_exr(args.out, color, {k: v for k, v in images.items() if k != "color"})
    print(f"wrote {args.out} ({color.shape[1]}×{color.shape[0]}, {args.precision}, {seconds:.2f} s)")
    return 0
