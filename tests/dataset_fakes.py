"""A stand-in for ``wgpu_rt.renderer.render`` so the truth engine, the reader and training can be tested
in milliseconds without a GPU: a smooth pattern that depends on the scene's camera and objects, scrolling
2 px per frame (with matching motion vectors), plus noise whose variance falls as 1/spp."""

from types import SimpleNamespace

import numpy as np

SCROLL = 2.0


def fake_render(scene, spp=16, size=(32, 32), max_depth=8, seed=0, frames=0, aovs=(), aux_samples=0):
    width, height = size
    ys, xs = np.mgrid[0:height, 0:width].astype(np.float32)
    camera = scene.camera_at(frames)
    phase = float(camera.origin.sum()) + 0.3 * len(scene.meshes)
    u = (xs + SCROLL * frames) / width
    clean = np.stack([1.0 + np.sin(6 * u + phase), 1.0 + np.cos(4 * ys / height - phase),
                      0.5 + 0.5 * (u > 0.5)], axis=-1).astype(np.float32)
    rng = np.random.default_rng(seed)
    color = clean * rng.gamma(spp, 1.0 / spp, size=clean.shape).astype(np.float32)
    planes = {"albedo": np.clip(clean / 2, 0, 1), "normal": np.dstack([np.zeros_like(xs), np.ones_like(xs),
                                                                      np.zeros_like(xs)]),
              "depth": (1.0 + u)[..., None], "motion": np.dstack([np.full_like(xs, SCROLL if frames else 0.0),
                                                                   np.zeros_like(xs)]),
              "spp": np.full((height, width, 1), spp, np.float32)}
    return SimpleNamespace(color=color, aovs={k: planes[k].astype(np.float32) for k in aovs})
