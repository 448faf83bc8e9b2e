"""``wgpu-rt denoise``: denoise an EXR (colour + albedo/normal/depth layers) with a shipped or given model,
run by the WGSL network engine."""

from __future__ import annotations

from ._denoiser_flags import add_denoiser_flags, denoiser_options

HELP = "denoise an EXR that carries colour plus albedo, normal and depth layers (and its sample count)"

REQUIRED_LAYERS = ("color", "albedo", "normal", "depth")
HALF_LAYERS = {"half_radiance": 3, "half_spp": 1}   # `wgpu-rt render --aov …,half_radiance,half_spp`


def add_arguments(parser) -> None:
    parser.add_argument("input", metavar="IN.exr", help="noisy render with albedo, normal and depth layers")
    parser.add_argument("-o", "--out", required=True, metavar="OUT.exr", help="denoised EXR (other layers kept)")
    parser.add_argument("--model", help="denoiser ONNX (default: the shipped denoiser.onnx)")
    add_denoiser_flags(parser, "image")
    parser.add_argument("--spp", type=int, metavar="N",
                        help="samples per pixel of the colour (default: the input's 'spp' layer, which "
                             "`wgpu-rt render` writes, else 1). With 'half_radiance' and 'half_spp' layers too "
                             "(the mean after the first half of the samples), each pixel hands over to the "
                             "colour where that has converged, as `wgpu-rt render --denoise` does")


def run(args) -> int:
    import time

    from ..frame.denoise import denoise, load_model
    from ..io import check_output_path, read_exr, require_layers, write_exr

    check_output_path(args.out, "--out", (".exr",))
    images = read_exr(args.input)
    require_layers(images, args.input, *REQUIRED_LAYERS)
    spp = sample_counts(images, args)
    half = half_layers(images, args.input)
    model = load_model("denoiser", args.precision, path=args.model, quality=args.quality)
    images = finite_layers(images, args.input)
    started = time.perf_counter()
    color = denoise(model, *(images[name] for name in REQUIRED_LAYERS), spp, **denoiser_options(args),
                    half=None if half is None else (images["half_radiance"], half))
    seconds = time.perf_counter() - started
    write_exr(args.out, color, {k: v for k, v in images.items() if k != "color"})
    print(f"wrote {args.out} ({color.shape[1]}×{color.shape[0]}, {model.precision.name}, {args.quality}, {seconds:.2f} s)")
    return 0


def sample_counts(images: dict, args):
    """The colour's samples per pixel: --spp, else the input's one-channel 'spp' layer, else 1."""
    import numpy as np

    from ..errors import ImageError
    from ..renderer import check_int

    if args.spp is not None:
        return check_int("--spp", args.spp, 1)
    layer = images.get("spp")
    if layer is None:
        return 1
    if layer.shape[2] != 1 or not np.all(np.isfinite(layer)) or layer.min() < 0:
        raise ImageError(f"{args.input}: layer 'spp' must be one channel of sample counts ≥ 0 "
                         "(pass --spp N to override it)")
    return layer


def half_layers(images: dict, path):
    """The input's 'half_spp' counts when it has both half layers (else None), checked."""
    import numpy as np

    from ..errors import ImageError

    present = [name for name in HALF_LAYERS if name in images]
    if not present:
        return None
    if len(present) < len(HALF_LAYERS):
        missing = next(name for name in HALF_LAYERS if name not in images)
        raise ImageError(f"{path}: layer {present[0]!r} needs layer {missing!r} too (or neither)")
    for name, channels in HALF_LAYERS.items():
        if images[name].shape[2] != channels:
            raise ImageError(f"{path}: layer {name!r} must have {channels} channel(s), got {images[name].shape[2]}")
    counts = images["half_spp"][..., 0]
    if not np.all(np.isfinite(counts)) or counts.min() < 0:
        raise ImageError(f"{path}: layer 'half_spp' must hold sample counts ≥ 0")
    return counts.astype(np.int64)


def finite_layers(images: dict, path) -> dict:
    """``images`` with NaN/Inf set to 0, the networks' own sanitising rule, and one warning line per layer
    that held any: a renderer's output can hold such pixels, and the written EXR must not."""
    import sys

    import numpy as np

    from ..frame.kernel import finite

    for name, layer in images.items():
        count = np.count_nonzero(~np.isfinite(layer))
        if count:
            print(f"wgpu-rt denoise: warning: {path}: layer {name!r} holds {count} NaN/Inf values; "
                  "treated as 0", file=sys.stderr)
    return {name: finite(layer) for name, layer in images.items()}
