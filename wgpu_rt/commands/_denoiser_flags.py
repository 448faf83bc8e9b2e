"""The denoiser's flags, shared by ``render`` and ``denoise`` so that they mean the same in both."""

from __future__ import annotations

from ..errors import WgpuRtError
from ..frame.lowband import LOW_BAND_SETTINGS

SWITCHES = {"on": True, "off": False}
AUTO_SWITCHES = {"auto": None, **SWITCHES}


def add_denoiser_flags(parser, image: str) -> None:
    """--precision, --quality and the step flags (``add_denoiser_step_flags``); ``image`` names what is
    denoised."""
    parser.add_argument("--precision", choices=["auto", "fp32", "fp16"], default="auto",
                        help="network arithmetic (fp16 needs the shader-f16 feature; auto: fp16 on discrete "
                             "GPUs that have it, else fp32)")
    parser.add_argument("--quality", choices=["balanced", "high"], default="balanced",
                        help=f"denoiser quality; high: average the {image} denoised as given and turned three "
                             "ways (4 network passes, ≈ 0.3 dB cleaner)")
    add_denoiser_step_flags(parser, image)


def add_denoiser_step_flags(parser, image: str = "frame") -> None:
    """--white-balance, --auto-exposure, --low-band, --chroma and --post-filter: the steps around the network (also the
    benchmarks')."""
    parser.add_argument("--white-balance", choices=list(SWITCHES), default="on",
                        help="divide the irradiance the network reads by the frame's per-channel gains (the "
                             "square roots of its channels' means over their mean) and multiply them back "
                             "after, so that strongly coloured light does not come out greyed (default on)")
    parser.add_argument("--auto-exposure", choices=list(AUTO_SWITCHES), default="auto",
                        help="bring the irradiance the network reads to one key (the log-average of 8×8 tile "
                             f"means) and back after, so that a {image} denoises alike at any scale of its light "
                             "(the error predictor and confidence model read their input at a key too); auto, "
                             "the default: each model as it was trained, which its ONNX file records")
    parser.add_argument("--low-band", choices=list(LOW_BAND_SETTINGS), default="auto",
                        help="the denoiser's band below quarter resolution from passes at half (and, from "
                             "512² up, quarter) resolution, weighed by 1/spp: cleaner large-scale shading on big "
                             f"{image}s for 1.25–1.31× the network's work (auto: on for {image}s at least 256 "
                             "pixels a side, unless every pixel holds 16 samples or more)")
    parser.add_argument("--chroma", choices=list(SWITCHES), default="on",
                        help="hold the denoised colour balance over 4×4-pixel blocks to the samples' own "
                             "means where they are sure of it (default on)")
    parser.add_argument("--post-filter", choices=list(SWITCHES), default="on",
                        help="smooth what the denoiser leaves with an edge-aware à-trous filter guided by the "
                             "albedo, normal and depth (default on)")


def denoiser_options(args) -> dict:
    """The renderer's / ``denoise()``'s options from the flags (quality and precision left to the caller)."""
    return {"low_band": LOW_BAND_SETTINGS[args.low_band], "chroma": SWITCHES[args.chroma],
            "post_filter": SWITCHES[args.post_filter], "white_balance": SWITCHES[args.white_balance],
            "auto_exposure": AUTO_SWITCHES[args.auto_exposure]}


def check_denoiser_flags(args, small_networks: bool = False) -> None:
    """Without --denoise the denoiser's flags must be left at their defaults (``render``); --auto-exposure
    also steers the error predictor and the confidence model, so ``small_networks`` (--adaptive or
    --temporal) lets it through."""
    for flag, value, default in (("--quality", args.quality, "balanced"), ("--low-band", args.low_band, "auto"),
                                 ("--chroma", args.chroma, "on"), ("--post-filter", args.post_filter, "on"),
                                 ("--white-balance", args.white_balance, "on"),
                                 ("--auto-exposure", "auto" if small_networks else args.auto_exposure, "auto")):
        if value != default:
            raise WgpuRtError(f"{flag} {value} is the denoiser's: add --denoise"
                              + (" (or --adaptive / --temporal)" if flag == "--auto-exposure" else ""))
