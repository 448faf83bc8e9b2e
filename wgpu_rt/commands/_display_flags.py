"""The display flags of a .png output, shared by ``render`` and ``denoise`` so that they mean the same in both."""

from __future__ import annotations

from ..errors import WgpuRtError

DEFAULT_OPERATOR = "aces"


def add_display_flags(parser) -> None:
    """--exposure and --tonemap: how a .png shows the linear radiance (an .exr keeps it as it is)."""
    from ..frame.tonemap import OPERATORS

    parser.add_argument("--exposure", type=float, metavar="STOPS",
                        help="for a .png: scale the radiance by 2^STOPS before the tone curve (default 0)")
    parser.add_argument("--tonemap", choices=OPERATORS,
                        help=f"for a .png: the tone curve before sRGB (default {DEFAULT_OPERATOR}; none clips at 1)")


def display_settings(args, png: bool) -> tuple[str, float]:
    """(operator, exposure) for a .png output; flags given for an .exr are refused (it keeps the linear
    radiance), and a bad exposure is named, before any work."""
    from ..frame.tonemap import check_settings

    given = [flag for flag, value in (("--exposure", args.exposure), ("--tonemap", args.tonemap)) if value is not None]
    if given and not png:
        raise WgpuRtError(f"{given[0]} is for a .png output; an .exr keeps the linear radiance as it is")
    operator = args.tonemap or DEFAULT_OPERATOR
    exposure = 0.0 if args.exposure is None else args.exposure
    try:
        check_settings(operator, "f32", exposure)
    except WgpuRtError as err:
        raise WgpuRtError(f"--exposure {args.exposure}: {err}") from None
    return operator, exposure
