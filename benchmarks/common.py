"""Shared helpers of the evidence benchmarks (bench_time_error, bench_adaptive, bench_temporal): the
command header every output starts with, scene and model selection, gold renders (optionally cached),
steady-state timing, error metrics (wgpu_rt.metrics, and a trimmed relMSE), log-log curve crossings,
tables and plots.

Every script prints the exact command that produced its numbers first, so a pasted table always
says how to reproduce it. Times are wall-clock seconds on this machine's adapter (printed too);
the first call of anything that compiles kernels is a warm-up and is not timed.
"""

from __future__ import annotations

import os
import re
import shlex
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from wgpu_rt import metrics
from wgpu_rt.commands._denoiser_flags import add_denoiser_step_flags, denoiser_options  # noqa: F401 (the benchmarks')

REPO = Path(__file__).resolve().parents[1]
BUNNY = REPO.parent / "shared" / "meshes" / "stanford-bunny.obj"
PLOTS = Path(__file__).resolve().parent / "plots"
MESH_SCENE = "bunny"
GOLD_SEED = 12345
GOLD_TWIN_SEED = 54321   # the second gold of --gold-twin
TRIM_QUANTILE = 0.999
MITSUBA_MOTION_SPP = 64  # samples of our tracer behind a Mitsuba gold frame's motion vectors


def image_size(text: str) -> tuple[int, int]:
    """An argparse type for --size WIDTHxHEIGHT: (width, height), or a usage error naming what is wrong."""
    import argparse

    from wgpu_rt.errors import WgpuRtError
    from wgpu_rt.renderer import parse_size

    try:
        return parse_size(text)
    except WgpuRtError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def print_header(args) -> None:
    """The command line, the adapter and the model folder: the first lines of every benchmark."""
    from wgpu_rt.gpu import get_context

    print("command: " + shlex.join(["python3", os.path.relpath(sys.argv[0], REPO)] + sys.argv[1:]))
    print(f"adapter: {get_context().label}")
    if hasattr(args, "models"):
        print(f"models:  {args.models or 'packaged models/'}"
              + (" (UNTRAINED seed networks: mechanics only, quality numbers are meaningless)"
                 if getattr(args, "seed_models", False) else ""))
    sys.stdout.flush()


def add_model_arguments(parser) -> None:
    parser.add_argument("--models", metavar="DIR", help="folder of denoiser/error_predictor/confidence .onnx "
                        "(default: the packaged models/)")
    parser.add_argument("--seed-models", action="store_true",
                        help="export untrained seed networks into a temp folder and use those (checks the "
                             "script's mechanics before trained models exist)")
    parser.add_argument("--precision", choices=["fp32", "fp16"], default="fp32", help="network precision")
    add_denoiser_step_flags(parser)


def parse_with_quick_defaults(parser, quick: dict):
    """Add --quick and parse; with --quick, the values in ``quick`` replace the defaults (flags given
    still win)."""
    parser.add_argument("--quick", action="store_true",
                        help=f"small and fast defaults: {', '.join(f'{k}={v}' for k, v in quick.items())}")
    args = parser.parse_args()
    if args.quick:
        parser.set_defaults(**quick)
        args = parser.parse_args()
    return args


def resolve_models(args) -> None:
    """With --seed-models, export the seed networks and point ``args.models`` at them."""
    if args.seed_models:
        from wgpu_rt.train.networks import export_seed_models

        args.models = str(export_seed_models(tempfile.mkdtemp(prefix="wgpu-rt-seed-models-")))


def load_scenes(names: list[str], world_frames: int = 1) -> list:
    """The scenes named (built-ins; ``bunny``: the mesh scene with ../shared/meshes' Stanford bunny,
    skipped with a message when the file is absent; ``world-SEED``: the generated world of that seed, as
    the dataset names them, e.g. world-2147483648 is the held-out family's first, with its camera and an
    object moving over ``world_frames`` frames when that is above 1; ``world-A..B``: the worlds of seeds A to B,
    B included, e.g. world-2147483648..2147483671 for §42's 24 held-out worlds; a scene file, e.g.
    benchmarks/scenes/*.toml, skipped with a message when it names a mesh file that is absent)."""
    from wgpu_rt.dataset.worlds import generate_world
    from wgpu_rt.scene import SCENE_SUFFIXES, load_scene

    scenes = []
    for name in [one for given in names for one in world_range(given)]:
        if Path(name).suffix.lower() in SCENE_SUFFIXES:
            missing = missing_mesh_files(Path(name))
            if missing:
                print(f"skipping {name}: {missing[0]} not found")
                continue
            scenes.append(load_scene(name))
            continue
        if name.startswith("world-") and name[len("world-"):].isdigit():
            scene = generate_world(int(name[len("world-"):]), frames=world_frames)
            scene.name = name
        elif name == MESH_SCENE:
            if not BUNNY.exists():
                print(f"skipping {MESH_SCENE}: {BUNNY} not found")
                continue
            scene = load_scene("mesh", mesh=BUNNY)
            scene.name = MESH_SCENE
        else:
            scene = load_scene(name)
        scenes.append(scene)
    return scenes


def world_range(name: str) -> list[str]:
    """``world-A..B`` as the names world-A … world-B (B included); any other name as it is."""
    match = re.fullmatch(r"world-(\d+)\.\.(\d+)", name)
    if match is None:
        return [name]
    first, last = int(match[1]), int(match[2])
    if last < first:
        raise SystemExit(f"{name}: the range's last seed is below its first")
    return [f"world-{seed}" for seed in range(first, last + 1)]


def missing_mesh_files(scene_file: Path) -> list[Path]:
    """The mesh files that the scene file's meshes name (relative to its folder) and that do not exist: the
    user scenes in benchmarks/scenes name ../shared/meshes, which the project does not ship."""
    from wgpu_rt.errors import SceneError
    from wgpu_rt.scene.loader import read_scene_file

    try:
        meshes = read_scene_file(scene_file).get("meshes", [])
        files = [scene_file.parent / entry["file"] for entry in meshes if "file" in entry]
    except (SceneError, TypeError, AttributeError):
        return []   # the scene loader then says what is wrong with the file
    return [path for path in files if not path.exists()]


def add_gold_arguments(parser, default_spp: int) -> None:
    parser.add_argument("--gold-spp", type=int, default=default_spp)
    parser.add_argument("--gold-cache", metavar="DIR",
                        help="keep gold renders in DIR as .npy, keyed by scene name, size, spp and max depth, "
                             "and reuse them (the gold is most of a full-size run; benchmarks at the same "
                             "size share it). Stale if the scene or tracer changed: delete the folder then")
    parser.add_argument("--gold-twin", action="store_true",
                        help="render a second gold of independent noise (seed %d) and score against the "
                             "truth as the two estimate it (twin_corrected_psnr): for golds of few spp, whose "
                             "own noise otherwise caps every score and narrows the gaps between them"
                             % GOLD_TWIN_SEED)
    parser.add_argument("--gold-renderer", choices=["ours", "mitsuba"], default="ours",
                        help="who renders the gold: our tracer, or Mitsuba 3 in its fastest variant here "
                             "(an independent reference; llvm_ad_rgb is ~7x our lavapipe speed on meshes)")


def gold_render(scene, size, args, seed: int = GOLD_SEED, spp: int | None = None) -> np.ndarray:
    """(H, W, 3) radiance of our own render (or Mitsuba's, with --gold-renderer mitsuba: ``mitsuba_gold``)
    at ``spp`` samples a pixel (default ``args.gold_spp``) with seed 12345 (no other run uses that seed, so
    the gold's noise is independent of every image measured against it; the twin's: seed GOLD_TWIN_SEED),
    from ``args.gold_cache`` when it holds one."""
    from wgpu_rt.renderer import render

    by_mitsuba = _gold_by_mitsuba(args)
    spp = args.gold_spp if spp is None else spp

    def compute():
        if by_mitsuba:
            return {"color": mitsuba_gold(scene, size, spp, args.max_depth, seed)}
        return {"color": render(scene, spp=spp, size=size, max_depth=args.max_depth, seed=seed,
                                aovs=()).color}

    key = (f"{scene.name}_{size[0]}x{size[1]}_{spp}spp_depth{args.max_depth}"
           + ("" if seed == GOLD_SEED else f"_seed{seed}") + ("_mitsuba" if by_mitsuba else ""))
    return _cached(args, key, compute, ["color"])["color"]


def _gold_by_mitsuba(args) -> bool:
    return getattr(args, "gold_renderer", "ours") == "mitsuba"


def mitsuba_gold(scene, size, spp: int, max_depth: int, seed: int, frame: int = 0) -> np.ndarray:
    """(H, W, 3) float32: Mitsuba's render of ``scene`` at ``frame`` (wgpu_rt.scene.mitsuba.render_in_passes:
    passes seeded ``seed``, ``seed`` + 1, …); exit status 2 with a one-line message when Mitsuba 3 does not
    load, or cannot render the scene's light (lights_through_panes)."""
    from wgpu_rt.scene.mitsuba import lights_through_panes, render_in_passes

    if lights_through_panes(scene):
        print(f"--gold-renderer mitsuba: {scene.name}: Mitsuba's shadow rays stop at thin panes, so its gold would "
              "miss the point, spot or directional light through them; leave the gold to our tracer", file=sys.stderr)
        raise SystemExit(2)

    try:
        mi, _ = mitsuba()
    except ImportError as err:
        print(f"--gold-renderer mitsuba: Mitsuba 3 does not load here ({err}); pip install mitsuba, or "
              "leave the gold to our tracer", file=sys.stderr)
        raise SystemExit(2) from None
    return render_in_passes(mi, scene, size, spp, max_depth, seed, frame)


def twin_corrected_psnr(gold, twin, image) -> float:
    """PSNR (display space, as metrics.psnr) of ``image`` against the truth, estimated from two golds of
    independent noise: its squared error against their mean, less that mean's own noise, a quarter of
    the golds' squared difference (which holds twice one gold's variance). inf if nothing is left."""
    display = metrics.to_display
    mean = display(0.5 * (np.asarray(gold, np.float64) + np.asarray(twin, np.float64)))
    own_noise = np.mean((display(gold) - display(twin)) ** 2) / 4.0
    error = np.mean((display(np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0)) - mean) ** 2)
    return float("inf") if error <= own_noise else float(10.0 * np.log10(1.0 / (error - own_noise)))


def gold_frame(scene, size, args, frame: int) -> tuple[np.ndarray, np.ndarray]:
    """(radiance (H, W, 3), motion (H, W, 2)) of frame ``frame`` of an animated scene at ``args.gold_spp``
    (seed 12345 + frame), cached like ``gold_render``. With --gold-renderer mitsuba the radiance is
    Mitsuba's (seeds 12345 + 1000 × frame + pass) and the motion our tracer's at MITSUBA_MOTION_SPP (Mitsuba
    has no motion vectors; a pixel's motion is a mean over its footprint, which that many samples settle)."""
    from wgpu_rt.renderer import render

    by_mitsuba = _gold_by_mitsuba(args)

    def compute():
        spp = MITSUBA_MOTION_SPP if by_mitsuba else args.gold_spp
        result = render(scene, spp=spp, size=size, max_depth=args.max_depth, seed=GOLD_SEED,
                        frames=frame, aovs=("motion",))   # frame f is seeded GOLD_SEED + f
        color = (mitsuba_gold(scene, size, args.gold_spp, args.max_depth, GOLD_SEED + 1000 * frame, frame)
                 if by_mitsuba else result.color)
        return {"color": color, "motion": result.aovs["motion"]}

    key = (f"{scene.name}_{size[0]}x{size[1]}_{args.gold_spp}spp_depth{args.max_depth}_frame{frame}"
           + ("_mitsuba" if by_mitsuba else ""))
    images = _cached(args, key, compute, ["color", "motion"])
    return images["color"], images["motion"]


def _cached(args, key: str, compute, names: list[str]) -> dict[str, np.ndarray]:
    """``compute()``'s images, kept in ``args.gold_cache`` (when set) as KEY.npy, or KEY_NAME.npy for
    names other than color, written atomically."""
    if not getattr(args, "gold_cache", None):
        return compute()
    folder = Path(args.gold_cache)
    paths = {name: folder / (f"{key}.npy" if name == "color" else f"{key}_{name}.npy") for name in names}
    if all(path.exists() for path in paths.values()):
        return {name: np.load(path) for name, path in paths.items()}
    images = compute()
    folder.mkdir(parents=True, exist_ok=True)
    for name, path in paths.items():
        save_array(path, images[name])
    return images


def save_array(path: Path, array: np.ndarray) -> None:
    """``np.save`` through a temporary file (never a half-written .npy in a cache)."""
    from wgpu_rt.io import atomic_output

    with atomic_output(path) as temp, open(temp, "wb") as file:
        np.save(file, array)


def steady(function, repeats: int = 1):
    """(result of the last call, median seconds of ``repeats`` calls) after one untimed warm-up call."""
    function()
    seconds, result = [], None
    for _ in range(repeats):
        started = time.perf_counter()
        result = function()
        seconds.append(time.perf_counter() - started)
    return result, float(np.median(seconds))


def hdr_pipeline(scene, size, args, **settings):
    """A renderer set up once (``wgpu_rt.renderer.Renderer``) that returns linear HDR colour, no AOVs."""
    from wgpu_rt.renderer import Renderer

    if settings.get("denoise"):
        for name, value in denoiser_options(args).items():
            settings.setdefault(name, value)
    return Renderer(scene, size=size, max_depth=args.max_depth, precision=args.precision,
                    models_dir=args.models, aovs=(), **settings)


def device_ms(ctx, timer, record) -> float:
    """Device ms, from ``timer``'s timestamp queries (a wgpu_rt StageTimer of capacity ≥ 2), of what
    ``record(encoder)`` records, submitted alone and waited for."""
    encoder = ctx.device.create_command_encoder()
    timer.start()
    timer.mark(encoder, "start")
    record(encoder)
    timer.mark(encoder, "recorded")
    encoder.resolve_query_set(timer.query_set, 0, 2, timer.resolved, 0)
    ctx.device.queue.submit([encoder.finish()])
    return timer.stage_ms(timer.names, ctx.device.queue.read_buffer(timer.resolved, 0, 16))["recorded"]


def linear_frame(renderer, frame: int = 0) -> np.ndarray:
    """One rendered frame of an ``hdr_pipeline`` as (H, W, 3) radiance."""
    return next(renderer.frames(frame)).color


def denoise_exr(path: Path, out: Path, args, *flags: str) -> dict:
    """`wgpu-rt denoise PATH --out OUT FLAGS` as a user runs it, with the benchmark's --precision and --models
    (its "wrote …" line kept off the table); the layers of the file it wrote."""
    import contextlib
    import io

    from wgpu_rt.cli import main
    from wgpu_rt.io import read_exr

    flags = ["--precision", args.precision, *flags]
    flags += ["--model", str(Path(args.models) / "denoiser.onnx")] if args.models else []
    with contextlib.redirect_stdout(io.StringIO()):
        status = main(["denoise", str(path), "--out", str(out), *flags])
    if status:
        raise SystemExit(f"wgpu-rt denoise {path} failed with status {status}")
    return read_exr(out)


def oidn(color, albedo, normal, quality: str = "high") -> np.ndarray:
    """Intel Open Image Denoise (pyoidn, HDR mode, ``quality``, with albedo and normal guides) on the
    CPU."""
    from peers import oidn_denoise

    return oidn_denoise(color, albedo, normal, quality=quality, device="cpu")


def errors(reference, image) -> dict[str, float]:
    """relMSE, FLIP (when flip-evaluator is installed) and PSNR of ``image`` against ``reference``."""
    image = np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    result = {"relMSE": metrics.rel_mse(reference, image)}
    if metrics.flip_available():
        result["FLIP"] = metrics.flip(reference, image)
    result["PSNR"] = metrics.psnr(reference, image)
    return result


def equivalent_spp(spp: list[int], error: list[float], target: float) -> str:
    """The sample count at which brute force's ``error`` (lower is better) first falls to ``target``,
    interpolated in log-log on the first segment that crosses it; "< 1" / "> N" outside the measured
    range (the curve is noisy at high spp when gold itself has few samples, so only crossings count)."""
    x, y = np.log(np.asarray(spp, float)), np.log(np.asarray(error, float))
    t = np.log(target)
    if t > y[0]:
        return f"< {spp[0]}"
    for i in range(len(x) - 1):
        if y[i] >= t >= y[i + 1]:
            return f"{np.exp(x[i] + (t - y[i]) * (x[i + 1] - x[i]) / (y[i + 1] - y[i])):.1f}"
    return f"> {spp[-1]}"


def trimmed_rel_mse(reference, image, quantile: float = TRIM_QUANTILE) -> float:
    """relMSE with each pixel's error (relMSE averaged over its channels) clipped at the image's
    ``quantile`` (default: the top 0.1% of pixels count as the 99.9th-percentile error): a robust twin of
    relMSE, which a handful of fireflies otherwise dominate at low spp."""
    reference = np.asarray(reference, np.float64)
    image = np.nan_to_num(np.asarray(image, np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    per_pixel = np.mean((image - reference) ** 2 / (reference ** 2 + metrics.REL_MSE_EPSILON), axis=-1)
    return float(np.mean(np.minimum(per_pixel, np.quantile(per_pixel, quantile))))


def crossing(xs, ys, target: float) -> float | None:
    """The first x where the curve (xs ascending, ys an error) falls to ``target``, interpolated in
    log-log between the two points around it; the first x if it starts at or below it; None if the
    curve never gets there."""
    xs, ys = np.asarray(xs, float), np.asarray(ys, float)
    if ys[0] <= target:
        return float(xs[0])
    for i in range(1, len(xs)):
        if ys[i] <= target:
            x0, x1, y0, y1 = np.log(xs[i - 1]), np.log(xs[i]), np.log(ys[i - 1]), np.log(ys[i])
            return float(np.exp(x0 + (np.log(target) - y0) * (x1 - x0) / (y1 - y0)))
    return None


def print_table(title: str, headers: list[str], rows: list[list]) -> None:
    """A plain-text table; floats print with 4 significant digits, None as '—'."""
    def cell(value):
        if value is None:
            return "—"
        if isinstance(value, float):
            return f"{value:.4g}"
        return str(value)

    text = [[cell(v) for v in row] for row in rows]
    widths = [max(len(h), *(len(r[i]) for r in text)) for i, h in enumerate(headers)]
    print(f"\n{title}")
    print("  ".join(h.ljust(w) for h, w in zip(headers, widths)))
    print("  ".join("-" * w for w in widths))
    for row in text:
        print("  ".join(v.ljust(w) for v, w in zip(row, widths)))
    sys.stdout.flush()


def save_figure(figure, name: str) -> Path:
    """Write ``figure`` to benchmarks/plots/``name`` through a temp file (never a half-written PNG)."""
    PLOTS.mkdir(parents=True, exist_ok=True)
    from wgpu_rt.io import atomic_output

    path = PLOTS / name
    with atomic_output(path) as temp:
        figure.savefig(temp, format="png", dpi=110, bbox_inches="tight")
    return path


def mitsuba():
    """Mitsuba 3 in its fastest variant here (cuda_ad_rgb with a CUDA GPU, else llvm_ad_rgb with LLVM 19,
    else scalar_rgb; wgpu_rt.scene.mitsuba.variant_choice) and that variant's name."""
    from wgpu_rt.scene.mitsuba import load_mitsuba

    mi = load_mitsuba()
    return mi, mi.variant()
