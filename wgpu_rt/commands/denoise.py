"""``wgpu-rt denoise``: denoise an EXR (colour + albedo/normal/depth layers) with a shipped or given model,
run by the WGSL network engine."""

from __future__ import annotations

from ._denoiser_flags import add_denoiser_flags, denoiser_options
from ._display_flags import add_display_flags, display_settings

HELP = "denoise an EXR that carries colour plus albedo, normal and (best) depth layers (and its sample count)"

REQUIRED_LAYERS = ("color", "albedo", "normal")     # and depth, which it can do without (denoise_render)
HALF_LAYERS = {"half_radiance": 3, "half_spp": 1}   # `wgpu-rt render --aov …,half_radiance,half_spp`
ROLES = (*REQUIRED_LAYERS, "depth", "spp", *HALF_LAYERS)   # what --layer can point at another layer
CHANNELS = {"color": 3, "albedo": 3, "normal": 3, "depth": 1}   # the channels each role's layer gives the network
# Blender's multilayer EXR: a view layer VL's passes are layers "VL.Combined", "VL.Denoising Albedo", … (the
# Denoising Data passes, 0 depth and normal where nothing was hit); its header's "cycles.VL.samples" the count.
BLENDER_PASSES = {"color": "Combined", "albedo": "Denoising Albedo", "normal": "Denoising Normal",
                  "depth": "Denoising Depth"}
NO_HIT_DEPTH = 1e9   # a depth this far is a miss: Blender's Z pass writes 1e10 there, ours and Mitsuba's 0


def add_arguments(parser) -> None:
    parser.add_argument("inputs", nargs="+", metavar="IN.exr",
                        help="noisy render with albedo, normal and (best) depth layers; several (a sequence's "
                             "frames) are denoised one after another with the model loaded once")
    parser.add_argument("-o", "--out", required=True, metavar="OUT.exr|OUT.png",
                        help="denoised EXR (other layers and the header's text and integer attributes kept), or "
                             "a PNG of it tone-mapped for display as `wgpu-rt render` writes one (ACES, sRGB); "
                             "{name} stands for the input's file name without its suffix, which several inputs "
                             "need, e.g. clean/{name}.exr")
    add_display_flags(parser)
    parser.add_argument("--model", help="denoiser ONNX (default: the shipped denoiser.onnx)")
    add_denoiser_flags(parser, "image")
    parser.add_argument("--layer", action="append", default=[], metavar="ROLE=NAME",
                        help=f"read ROLE ({', '.join(ROLES)}) from the file's layer NAME, as another renderer "
                             "named it (e.g. --layer normal=nn for Mitsuba 3's aov integrator); repeat for each. "
                             "A Blender multilayer EXR needs none: its view layer's Combined and Denoising Data "
                             "passes are found by their names (--layer color=VL.Combined picks view layer VL). "
                             "The denoised colour replaces the first three channels of the colour's layer")
    parser.add_argument("--albedo-samples", type=int, metavar="N",
                        help="point samples a pixel that the albedo layer averages: it is smoothed by a Gaussian "
                             "of 0.9/sqrt(N) px first, as the network was trained on an albedo averaged over "
                             "each pixel's area (0: as it is). Default: 0 for files of `wgpu-rt render "
                             "--aux-samples`, whose aux pass made that average, else the colour's samples a "
                             "pixel, which another renderer's albedo holds")
    parser.add_argument("--spp", type=int, metavar="N",
                        help="samples per pixel of the colour (default: the input's 'spp' layer, which "
                             "`wgpu-rt render` writes, else the samples in a Blender file's header, else 1). "
                             "With 'half_radiance' and 'half_spp' layers too (the mean after the first half of "
                             "the samples), each pixel hands over to the colour where that has converged, as "
                             "`wgpu-rt render --denoise` does")


def run(args) -> int:
    from pathlib import Path

    from ..errors import ImageError

    outputs = output_paths(args.inputs, args.out)
    display = display_settings(args, all(out.suffix.lower() == ".png" for out in outputs))
    missing = next((path for path in args.inputs if not Path(path).is_file()), None)
    if missing is not None:
        raise ImageError(f"{missing}: no such file")
    named = layer_names(args.layer)
    warned: set[str] = set()
    model = None

    def warn(kind: str, message: str) -> None:
        """A warning line of ``kind`` (what it is about), said once for all the inputs."""
        import sys

        if kind not in warned:
            warned.add(kind)
            also = " (and for any other input like it)" if len(args.inputs) > 1 else ""
            print(f"wgpu-rt denoise: warning: {message}{also}", file=sys.stderr)

    for path, out in zip(args.inputs, outputs):
        model = denoise_file(path, out, args, named, model, warn, display)
    return 0


def output_paths(inputs: list[str], pattern: str) -> list:
    """Each input's output path from --out (its {name} field the input's file name without suffix), checked
    before any work: several inputs need the field, no two may share an output, none may overwrite an input."""
    from pathlib import Path

    from ..errors import WgpuRtError
    from ..io import check_output_path

    if len(inputs) > 1 and "{name}" not in pattern:
        raise WgpuRtError(f"--out {pattern}: several inputs need a {{name}} field, e.g. clean/{{name}}.exr")
    try:
        outputs = [Path(pattern.format(name=Path(path).stem)) for path in inputs]
    except (KeyError, IndexError, ValueError, AttributeError) as err:
        raise WgpuRtError(f"--out {pattern}: bad format field ({type(err).__name__}: {err}); only {{name}} is "
                          "known") from None
    for path, out in zip(inputs, outputs):
        check_output_path(out, "--out", (".exr", ".png"))
        if out.resolve() == Path(path).resolve():
            raise WgpuRtError(f"--out {pattern}: would overwrite its input {path}")
    if len(set(outputs)) < len(outputs):
        twice = next(out for out in outputs if outputs.count(out) > 1)
        raise WgpuRtError(f"--out {pattern}: two inputs would both write {twice}")
    return outputs


def denoise_file(path: str, out, args, named: dict, model, warn, display: tuple[str, float]):
    """Denoise one input file into ``out`` with ``model`` (loaded here on the first file, after its checks)
    and return the model; a .png shows it through ``display``'s (operator, exposure)."""
    import time

    from ..frame.denoise import denoise_render, load_model
    from ..frame.tonemap import tonemap
    from ..io import read_exr, write_exr, write_png

    file_layers = read_exr(path)
    channel_names, attributes = file_layers.channels, file_layers.attributes
    named = blender_layer_names(file_layers, named, path)
    images = network_inputs(file_layers, named, path)
    if "depth" not in images:   # OIDN's three inputs: denoised all the same, a little less well
        warn("depth", f"{path}: no 'depth' layer; denoised without one (read as one distance everywhere: 0.2 dB "
             "lower on the mean of nine of our scenes, up to 0.9; --layer depth=NAME reads it from another layer)")
    spp = sample_counts(images, args, path, warn, blender_samples(attributes, named))
    half = half_layers(images, path)
    albedo_samples = point_samples_in_albedo(args, attributes)
    if model is None:
        model = load_model("denoiser", args.precision, path=args.model, quality=args.quality)
    file_layers = finite_layers(file_layers, path)   # what the network reads, and what is written back
    images = network_inputs(file_layers, named, path)
    started = time.perf_counter()
    color = denoise_render(model, *(images[name] for name in REQUIRED_LAYERS), images.get("depth"), spp,
                           albedo_samples, **denoiser_options(args),
                           half=None if half is None else (images["half_radiance"], half))
    seconds = time.perf_counter() - started
    if out.suffix.lower() == ".png":
        write_png(out, tonemap(color, display[0], display[1], output="f32")[..., :3])
    else:
        write_exr(out, *denoised_file(file_layers, named.get("color", "color"), color),
                  channel_names=channel_names, attributes=attributes)
    height, width = color.shape[:2]
    print(f"wrote {out} ({width}×{height}, {model.precision.name}, {args.quality}, {seconds:.2f} s)", flush=True)
    return model


def layer_names(flags: list[str]) -> dict[str, str]:
    """--layer ROLE=NAME flags → {role: the file's layer name}, checked before any work."""
    from ..errors import WgpuRtError

    named = {}
    for flag in flags:
        role, equals, name = flag.partition("=")
        if not equals or role not in ROLES or not name:
            raise WgpuRtError(f"--layer {flag!r}: expected ROLE=NAME with ROLE one of {', '.join(ROLES)}")
        if role in named:
            raise WgpuRtError(f"--layer {flag!r}: {role} is already read from layer {named[role]!r}")
        named[role] = name
    return named


def blender_layer_names(file_layers: dict, named: dict, path) -> dict:
    """``named`` with the roles it leaves open read from a Blender multilayer EXR's passes (BLENDER_PASSES) of
    the view layer whose "VL.Combined" is the colour: the one --layer color names, else the file's only one.
    Files with a top-level colour (ours, Mitsuba's) are left as they are."""
    from ..errors import ImageError

    if "color" in file_layers and "color" not in named:
        return named
    suffix = "." + BLENDER_PASSES["color"]
    if "color" in named:   # (a colour layer the file lacks is reported as such by network_inputs)
        given = named["color"]
        view_layers = [given.removesuffix(suffix)] if given.endswith(suffix) and given in file_layers else []
    else:
        view_layers = sorted(name.removesuffix(suffix) for name in file_layers if name.endswith(suffix))
    if len(view_layers) > 1:
        raise ImageError(f"{path}: view layers {', '.join(view_layers)}: --layer color=VL.Combined picks one")
    if not view_layers:
        return named
    passes = {role: f"{view_layers[0]}.{name}" for role, name in BLENDER_PASSES.items()}
    missing = [role for role, layer in passes.items() if role not in named and layer not in file_layers]
    if missing:
        raise ImageError(f"{path}: no layer {passes[missing[0]]!r}: Blender writes the Denoising Data passes when "
                         "View Layer Properties ▸ Passes ▸ Data ▸ Denoising Data is on (--layer "
                         f"{missing[0]}=NAME reads it from another layer)")
    return {**passes, **named}


def blender_samples(attributes: dict, named: dict) -> int | None:
    """The samples per pixel a Blender file's header gives for the colour's view layer ("cycles.VL.samples"),
    else None."""
    view_layer = named.get("color", "").removesuffix("." + BLENDER_PASSES["color"])
    text = str(attributes.get(f"cycles.{view_layer}.samples", ""))
    return int(text) if text.isdigit() and int(text) > 0 else None


def network_inputs(file_layers: dict, named: dict, path) -> dict:
    """The file's layers, and each --layer's NAME also as its ROLE (a role given another layer no longer reads
    its own name), the four the denoiser needs present, each cut to the channels the network reads
    (``network_channels``)."""
    from ..errors import ImageError
    from ..io import require_layers

    for role, name in named.items():
        if name not in file_layers:
            present = ", ".join(sorted(file_layers)) or "none"
            raise ImageError(f"{path}: no layer {name!r} (--layer {role}={name}); layers present: {present}")
    images = {**file_layers, **{role: file_layers[name] for role, name in named.items()}}
    missing = [role for role in REQUIRED_LAYERS if role not in images]
    if missing:
        try:
            require_layers(file_layers, path, missing[0])
        except ImageError as err:
            raise ImageError(f"{err} (--layer {missing[0]}=NAME reads it from another)") from None
    return {role: network_channels(role, layer, named.get(role, role), path) for role, layer in images.items()}


def network_channels(role: str, layer, name: str, path):
    """The channels of a role's layer that the network reads: the first three of colour, albedo and normal
    (R, G, B of an RGBA layer), depth's only one (NO_HIT_DEPTH and beyond: 0, a miss); other roles' layers as
    they are (checked later)."""
    import numpy as np

    from ..errors import ImageError

    wanted = CHANNELS.get(role)
    if wanted is None:
        return layer
    if layer.shape[2] < wanted or (wanted == 1 and layer.shape[2] != 1):
        raise ImageError(f"{path}: layer {name!r} has {layer.shape[2]} channel(s); {role} needs "
                         + ("exactly one" if wanted == 1 else f"{wanted}"))
    if role == "depth":
        return np.where(layer >= NO_HIT_DEPTH, np.float32(0), layer)
    return layer[..., :wanted]


def denoised_file(file_layers: dict, color_layer: str, color) -> tuple:
    """(top-level colour, other layers) of the output: the input file's layers with the denoised colour in
    the first three channels of the layer it was read from (an alpha kept), and at the top level as well
    when the file has no top-level colour of its own."""
    import numpy as np

    layers = dict(file_layers)
    source = layers[color_layer]
    layers[color_layer] = np.concatenate([color, source[..., 3:]], axis=-1)
    top = layers.pop("color", color)
    return top, layers


def sample_counts(images: dict, args, path, warn, header_samples: int | None = None):
    """The colour's samples per pixel: --spp, else the input's one-channel 'spp' layer, else the count its
    header gives (``header_samples``), else 1 (with a ``warn``ing)."""
    import numpy as np

    from ..errors import ImageError
    from ..renderer import check_int

    if args.spp is not None:
        return check_int("--spp", args.spp, 1)
    layer = images.get("spp")
    if layer is None and header_samples is not None:
        return header_samples
    if layer is None:   # the count sets the network's noise level and the albedo's smoothing: say what is assumed
        warn("spp", f"{path}: no 'spp' layer; taken as 1 sample a pixel (--spp N to say how many)")
        return 1
    if layer.shape[2] != 1 or not np.all(np.isfinite(layer)) or layer.min() < 0:
        raise ImageError(f"{path}: layer 'spp' must be one channel of sample counts ≥ 0 "
                         "(pass --spp N to override it)")
    return layer


def point_samples_in_albedo(args, attributes: dict) -> float | None:
    """How many point samples a pixel the albedo averages: --albedo-samples; else 0 for a file whose albedo
    came from our aux pass (its AUX_SAMPLES_ATTRIBUTE), else None: the colour's samples (denoise_render)."""
    from ..io import AUX_SAMPLES_ATTRIBUTE
    from ..renderer import check_int

    if args.albedo_samples is not None:
        return check_int("--albedo-samples", args.albedo_samples, 0)
    if attributes.get(AUX_SAMPLES_ATTRIBUTE, 0) > 0:
        return 0
    return None


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
