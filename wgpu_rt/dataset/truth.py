"""The truth engine: renders training data (noisy renders at several spp, G-buffers, gold images).

Layout of a dataset folder::

    DIR/config.json              what was asked for (checked on resume: a mismatch is an error)
    DIR/manifest.json            every finished view (rebuilt from the per-view records at each run end)
    DIR/views/v00012/view.json   one view's record, written last: its presence means "finished"
    DIR/views/v00012/f0_spp1.exr noisy colour + albedo/normal/depth/motion layers, frame 0, 1 spp
    DIR/views/v00012/f0_spp1_c1.exr  another, independent render at the lowest spp (``noisy_copies`` > 1)
    DIR/views/v00012/f0_gold.exr the converged image (+ layers) of frame 0

A *view* is a still (one frame) or a temporal sequence (consecutive frames with camera and object
motion, a gold image for each). View ``i`` of scene ``s`` is seeded from (seed, s, i) alone, so any
subset of views can be rendered in any order, on any shard, and reruns reproduce it bit for bit.
Every file is written atomically and a finished view is skipped, so an interrupted run loses at most
the image being rendered.

``noisy_copies`` N renders each frame N times at the lowest spp with independent seeds. At 1 spp a
copy costs 1/gold of the gold render, yet it is a new noise realization of the same view: a denoiser
that sees one realization per view hundreds of times learns that noise by heart. Copies are not a
setting that must match on resume: raising N later renders just the missing copies.

Splits: the last tenth of each scene's views are ``test`` (with shapes no training view has) and the
tenth before them ``val``. ``worlds`` N adds N generated worlds (``worlds.generate_world``), one view
each: of the ``training`` family, the last tenth are ``val`` and the rest ``train``; of the
``held_out`` family, all are ``test``.

``gold_renderer`` "mitsuba" leaves the gold's colour to Mitsuba 3 (``wgpu_rt.scene.mitsuba.render_in_passes``:
the same light transport, several times faster on a CPU than our tracer on lavapipe), and its G-buffers
(motion for sequences) to our tracer at GOLD_AOV_SPP samples.

Every setting is checked, every scene loaded and every mesh of ``mesh_dir`` read before the folder or
its config.json is created, so a rejected run leaves nothing behind. A config.json whose dataset holds
no rendered image yet does not bind a rerun.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from ..errors import OutputError, WgpuRtError
from ..io import write_json
from ..termination import raise_if_terminated
from .variety import HELD_OUT_SHAPES, MESH_SUFFIXES, TRAINING_SHAPES, load_mesh_file, load_mesh_folder, vary_scene
from .worlds import FAMILIES, WORLDS_VERSION, generate_world, world_seed

WORLD_VIEW_PREFIX = "world-"   # a generated world's view names its scene world-SEED in the manifest
GBUFFERS = ("albedo", "normal", "depth", "motion")
# View numbers, seeds and images depend on all of these, so a resumed run must keep them; ``guide_albedo``
# and ``worlds_version`` are no settings but the renderer's and the world generator's conventions
# (trace_pass.GUIDE_ALBEDO, worlds.WORLDS_VERSION), recorded beside them.
CONFIG_KEYS_THAT_MUST_MATCH = ("scenes", "views", "size", "spp", "gold", "seed", "max_depth",
                               "sequence_length", "sequence_fraction", "mesh_dir", "worlds", "family",
                               "aux_samples", "gold_renderer", "guide_albedo", "worlds_version")
MAX_WORLDS = 2 ** 20     # world numbers of one dataset seed stay distinct (see plan_views)
GOLD_RENDERERS = ("ours", "mitsuba")
GOLD_AOV_SPP = 64        # samples of our tracer behind a Mitsuba gold's G-buffers (a pixel's mean settles)


class DatasetError(WgpuRtError):
    """A dataset folder, its manifest or one of its images is missing, corrupt or inconsistent."""


@dataclass(frozen=True)
class DatasetConfig:
    scenes: tuple[str, ...]
    views: int = 16                      # per scene
    size: int = 256
    spp: tuple[int, ...] = (1, 4, 16)
    gold: int = 4096
    seed: int = 0
    max_depth: int = 8
    sequence_length: int = 3
    sequence_fraction: float = 0.25
    mesh_dir: str | None = None
    noisy_copies: int = 1                # independent renders per frame at the lowest spp
    worlds: int = 0                      # generated worlds, one view each
    family: str = "training"             # the worlds' family: training (train/val) or held_out (test)
    # Noisy renders' albedo re-estimated from this many delta-chain paths per pixel, as a denoising render
    # does (TracePass.execute_aux), so training sees what inference feeds; 0: the tracer's own (datasets
    # rendered before the aux pass lack the key and mean 0).
    aux_samples: int = 0
    gold_renderer: str = "ours"          # who renders the gold's colour: our tracer or Mitsuba 3

    def __post_init__(self):
        """Refuse settings that cannot make a dataset, naming the command-line flag."""
        at_least = {"--views": (self.views, 1), "--size": (self.size, 1), "--gold": (self.gold, 1),
                    "--max-depth": (self.max_depth, 1), "--noisy-copies": (self.noisy_copies, 1),
                    "--seed": (self.seed, 0), "--worlds": (self.worlds, 0), "--aux-samples": (self.aux_samples, 0),
                    "--spp": (min(self.spp, default=0), 1),
                    # a sequence is consecutive frames; stills only need no length
                    "--sequence-length": (self.sequence_length, 2 if self.sequence_fraction > 0 else 1)}
        for flag, (value, least) in at_least.items():
            if not value >= least:
                raise DatasetError(f"{flag} must be at least {least}, got {value}")
        if not self.scenes and not self.worlds:
            raise DatasetError("nothing to render: give --scenes, --worlds N or both")
        if self.worlds > MAX_WORLDS:
            raise DatasetError(f"--worlds must be at most {MAX_WORLDS}, got {self.worlds}")
        if self.gold_renderer not in GOLD_RENDERERS:
            raise DatasetError(f"--gold-renderer must be one of {', '.join(GOLD_RENDERERS)}, "
                               f"got {self.gold_renderer!r}")
        if self.family not in FAMILIES:
            raise DatasetError(f"--family must be one of {', '.join(FAMILIES)}, got {self.family!r}")
        if not (math.isfinite(self.sequence_fraction) and 0 <= self.sequence_fraction <= 1):
            raise DatasetError(f"--sequence-fraction must be in [0, 1], got {self.sequence_fraction}")

    @classmethod
    def from_record(cls, record: dict) -> "DatasetConfig":
        """The config a dataset's ``config.json`` (or its manifest's ``config``) records; keys that are not
        settings (``guide_albedo``, ``worlds_version``: conventions) are left out, lists become tuples."""
        settings = {f.name: record[f.name] for f in fields(cls) if f.name in record}
        return cls(**{key: tuple(value) if isinstance(value, list) else value for key, value in settings.items()})


@dataclass(frozen=True)
class ViewPlan:
    view_id: str
    scene: str
    index: int              # within its scene (or among the worlds)
    scene_index: int
    split: str              # train | val | test
    frames: int
    world_seed: int | None = None    # set for a generated world

    def renders(self, config: DatasetConfig) -> list[tuple[str, int, tuple[int, ...]]]:
        """(file, spp, seed salt) of every render of the view. The salts of the spp ladder and of gold
        predate copies, so a dataset rendered before them extends with the same images."""
        frames, lowest = range(self.frames), min(config.spp)
        return ([(frame_file(f, spp), spp, (f, spp)) for f in frames for spp in config.spp]
                + [(frame_file(f, "gold"), config.gold, (f, 0)) for f in frames]
                + [(frame_file(f, lowest, c), lowest, (f, lowest, c))
                   for f in frames for c in range(1, config.noisy_copies)])

    def files(self, config: DatasetConfig) -> list[str]:
        return [name for name, _, _ in self.renders(config)]


def frame_file(frame: int, spp: int | str, copy: int = 0) -> str:
    """File name of one frame's render: ``spp`` is a sample count or ``"gold"``; ``copy`` > 0 names an
    extra independent render at that spp."""
    if spp == "gold":
        return f"f{frame}_gold.exr"
    return f"f{frame}_spp{spp}.exr" if copy == 0 else f"f{frame}_spp{spp}_c{copy}.exr"


def _held_back(views: int) -> int:
    """How many views of ``views`` one held-out split gets."""
    return max(1, round(0.1 * views)) if views >= 3 else 0


def split_of(index: int, views: int) -> str:
    held = _held_back(views)
    if index >= views - held:
        return "test"
    if index >= views - 2 * held:
        return "val"
    return "train"


def world_split_of(index: int, worlds: int, family: str) -> str:
    if family == "held_out":
        return "test"
    return "val" if index >= worlds - _held_back(worlds) else "train"


def _generator(config: DatasetConfig, scene_index: int, index: int, *salt: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([config.seed, scene_index, index, *salt]))


def _render_seed(config: DatasetConfig, view: ViewPlan, *salt: int) -> int:
    state = np.random.SeedSequence([config.seed, view.scene_index, view.index, 7919, *salt]).generate_state(1)
    return int(state[0] & 0x7FFFFFFF)


def plan_views(config: DatasetConfig, shard: tuple[int, int] = (0, 1)) -> list[ViewPlan]:
    """Every view of the dataset that belongs to ``shard`` (i, n): global view numbers ≡ i mod n. The
    worlds come after the scenes' views; world ``i`` of dataset seed ``s`` is world number
    ``s·MAX_WORLDS + i`` of its family."""
    groups = [(scene, config.views, split_of, None) for scene in config.scenes]
    if config.worlds:
        groups.append((None, config.worlds, lambda i, n: world_split_of(i, n, config.family),
                       lambda i: world_seed(config.family, config.seed * MAX_WORLDS + i)))
    plans = []
    first_number = 0
    for scene_index, (scene, count, split_fn, seed_fn) in enumerate(groups):
        for index in range(count):
            number = first_number + index
            if number % shard[1] != shard[0]:
                continue
            rng = _generator(config, scene_index, index, 1)
            split = split_fn(index, count)
            # The first held-out view of each split is always a sequence, so the confidence model
            # has validation and test pairs however few views there are.
            first_of_split = split != "train" and (index == 0 or split_fn(index - 1, count) != split)
            sequence = config.sequence_fraction > 0 and (first_of_split or rng.uniform() < config.sequence_fraction)
            frames = config.sequence_length if sequence else 1
            seed = seed_fn(index) if seed_fn else None
            name = f"{WORLD_VIEW_PREFIX}{seed}" if seed_fn else scene
            plans.append(ViewPlan(f"v{number:05d}", name, index, scene_index, split, frames, seed))
        first_number += count
    return plans


@dataclass
class ViewRecord:
    """What view.json holds: the plan, the files and how long it took."""

    view_id: str
    scene: str
    split: str
    frames: int
    size: int
    spp: list[int]
    gold: int
    objects: list[str] = field(default_factory=list)
    seconds: float = 0.0
    noisy_copies: int = 1


def check_config(out: Path, config: DatasetConfig) -> None:
    """Record ``config`` in ``out``, with the albedo convention this renderer writes (``guide_albedo``) and
    the world generator's version (``worlds_version``); on resume, refuse a config or a convention that
    would change existing views (a folder with no rendered image yet takes the new config)."""
    from ..trace.trace_pass import GUIDE_ALBEDO

    path = out / "config.json"
    wanted = {**asdict(config), "guide_albedo": GUIDE_ALBEDO, "worlds_version": WORLDS_VERSION}
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: is a file; name a folder")
    if path.exists() and any((out / "views").glob("*/*.exr")):
        try:
            held = json.loads(path.read_text())
        except json.JSONDecodeError as err:
            raise DatasetError(f"{path}: not valid JSON ({err})") from None
        # for keys older datasets lack (before guide_albedo existed, escaping paths had albedo 0: version 1;
        # before worlds_version, no training world held lamps in view: version 1; 3 paints training worlds)
        defaults = {**{f.name: f.default for f in fields(DatasetConfig)}, "guide_albedo": 1, "worlds_version": 1}
        # the generator's version changes only training worlds (the held-out family stays as it was)
        unaffected = () if config.worlds and config.family == "training" else ("worlds_version",)
        for key in CONFIG_KEYS_THAT_MUST_MATCH:
            if key in unaffected:
                continue
            if held.get(key, defaults[key]) != json.loads(json.dumps(wanted[key])):
                raise DatasetError(f"{path}: this dataset was rendered with {key}={held.get(key, defaults[key])!r}, "
                                   f"not {wanted[key]!r}; use another --out or the same settings")
    try:
        out.mkdir(parents=True, exist_ok=True)
        write_json(path, wanted)
    except OSError as err:   # inside a file, read-only, no permission: found before any rendering
        raise OutputError(f"--out {out}: cannot write the dataset there ({err.strerror or err})") from None


def is_finished(out: Path, view: ViewPlan, config: DatasetConfig) -> bool:
    folder = out / "views" / view.view_id
    return (folder / "view.json").exists() and all((folder / f).exists() for f in view.files(config))


class TruthEngine:
    """Renders planned views into a dataset folder (see the module docstring)."""

    def __init__(self, config: DatasetConfig, out: str | Path, renderer=None, gold_color=None):
        """``renderer`` has ``wgpu_rt.renderer.render``'s signature (the default); ``gold_color(scene, size,
        spp, max_depth, seed, frame)`` renders a gold's colour with ``config.gold_renderer`` "mitsuba" (default:
        Mitsuba in its fastest variant here, loaded now); tests pass fakes."""
        if renderer is None:
            from ..renderer import render as renderer
        from ..scene import load_scene

        self.render = renderer
        self.gold_color = gold_color
        if config.gold_renderer == "mitsuba" and gold_color is None:
            self.gold_color = _mitsuba_gold_color()
        self.config = config
        self.out = Path(out)
        # Load everything a view may draw now: a bad scene or mesh fails before any file is written.
        self._bases = {scene: load_scene(scene) for scene in config.scenes}
        if config.gold_renderer == "mitsuba":
            from ..scene.mitsuba import lights_through_panes

            for name, scene in self._bases.items():
                if lights_through_panes(scene):
                    raise DatasetError(f"{name}: Mitsuba's shadow rays stop at thin panes, so its gold would miss "
                                       f"the scene's point, spot or directional light through them; render this "
                                       f"scene's golds with --gold-renderer ours")
        self._mesh_files = load_mesh_folder(config.mesh_dir) if config.mesh_dir else []
        if config.mesh_dir and not self._mesh_files:
            raise DatasetError(f"{config.mesh_dir}: --meshes holds no mesh files ({', '.join(MESH_SUFFIXES)})")
        for path in self._mesh_files:
            load_mesh_file(path)

    def scene_for(self, view: ViewPlan):
        """The randomized scene or the generated world of ``view`` (deterministic in its seed)."""
        if view.world_seed is not None:
            return generate_world(view.world_seed, self.config.mesh_dir, frames=view.frames)
        shapes = HELD_OUT_SHAPES if view.split == "test" else TRAINING_SHAPES
        return vary_scene(self._bases[view.scene], _generator(self.config, view.scene_index, view.index, 2),
                          frames=view.frames, shapes=shapes, mesh_files=self._mesh_files)

    def render_view(self, view: ViewPlan) -> ViewRecord:
        from ..io import write_exr

        cfg = self.config
        folder = self.out / "views" / view.view_id
        folder.mkdir(parents=True, exist_ok=True)
        scene = self.scene_for(view)
        started = time.perf_counter()
        size = (cfg.size, cfg.size)
        for name, spp, salt in view.renders(cfg):
            path = folder / name
            if not path.exists():
                # the noisy renders get the noise-free aux pass whatever their spp; gold needs none
                gold = name == frame_file(salt[0], "gold")
                by_mitsuba = gold and cfg.gold_renderer == "mitsuba"
                seed = _render_seed(cfg, view, *salt)
                result = self.render(scene, spp=GOLD_AOV_SPP if by_mitsuba else spp, size=size,
                                     max_depth=cfg.max_depth, seed=seed, frames=salt[0], aovs=GBUFFERS,
                                     aux_samples=0 if gold else cfg.aux_samples)
                color = (self.gold_color(scene, size, spp, cfg.max_depth, seed, salt[0]) if by_mitsuba
                         else result.color)
                write_exr(path, _finite(color), {k: _finite(result.aovs[k]) for k in GBUFFERS})
        previous = folder / "view.json"
        seconds = time.perf_counter() - started
        if previous.exists():   # a view extended with more copies: its time is the sum of both runs
            seconds += json.loads(previous.read_text()).get("seconds", 0.0)
        record = ViewRecord(view.view_id, view.scene, view.split, view.frames, cfg.size, list(cfg.spp),
                            cfg.gold, [m.name for m in scene.meshes], round(seconds, 3),
                            noisy_copies=cfg.noisy_copies)
        write_json(folder / "view.json", asdict(record))
        return record

    def run(self, shard: tuple[int, int] = (0, 1), progress: bool = True) -> list[ViewRecord]:
        """Render every unfinished view of ``shard``; returns the records of the views rendered now. ``progress``:
        a bar, where stderr is a terminal (piped into a log it would be noise)."""
        import sys

        from tqdm import tqdm

        check_config(self.out, self.config)
        todo = [v for v in plan_views(self.config, shard) if not is_finished(self.out, v, self.config)]
        done = []
        try:
            with tqdm(todo, desc=f"views (shard {shard[0]}/{shard[1]})", unit="view",
                      disable=not (progress and sys.stderr.isatty())) as bar:
                for view in bar:
                    bar.set_postfix_str(f"{view.view_id} {view.scene} {view.split} ×{view.frames}")
                    done.append(self.render_view(view))
                    raise_if_terminated()   # a SIGTERM whose exit a library swallowed mid-view
        finally:   # interrupted too (Ctrl-C, SIGTERM: wgpu_rt.cli), the manifest lists every view finished
            write_manifest(self.out)
        return done


def _mitsuba_gold_color():
    """``render_in_passes`` bound to Mitsuba in its fastest variant here; a DatasetError when it does not
    load (before any file is written)."""
    from functools import partial

    from ..scene.mitsuba import load_mitsuba, render_in_passes

    try:
        mi = load_mitsuba()
    except (ImportError, RuntimeError, OSError) as err:
        raise DatasetError(f"--gold-renderer mitsuba: Mitsuba 3 does not load here ({err}); pip install "
                           "'wgpu-rt[bench]', or leave the gold to our tracer") from None
    return partial(render_in_passes, mi)


def _finite(array) -> np.ndarray:
    """NaN/Inf never reach a dataset file (a firefly of Inf would poison every metric)."""
    return np.nan_to_num(np.asarray(array, np.float32), nan=0.0, posinf=0.0, neginf=0.0)


def write_manifest(out: str | Path) -> dict:
    """Rebuild ``manifest.json`` from the finished views' records (safe with several shards)."""
    out = Path(out)
    views = []
    for record in sorted((out / "views").glob("*/view.json")):
        try:
            views.append(json.loads(record.read_text()))
        except json.JSONDecodeError as err:
            raise DatasetError(f"{record}: not valid JSON ({err}); delete it to re-render the view") from None
    config = json.loads((out / "config.json").read_text()) if (out / "config.json").exists() else {}
    manifest = {"config": config, "views": views}
    write_json(out / "manifest.json", manifest)
    return manifest
