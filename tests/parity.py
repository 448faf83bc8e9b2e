"""The one parity helper every kernel test uses (after tinygrad's helper_test_op).

``check_parity(shapes, reference_fn, our_fn, atol, rtol)`` makes seeded random inputs of ``shapes``,
runs both functions and asserts equal shapes, finite output and
``|ours - ref| <= atol * max(1, max|ref|) + rtol * |ref|`` element-wise, reporting the worst element.
"""

from __future__ import annotations

import numpy as np


def check_parity(shapes, reference_fn, our_fn, atol=1e-4, rtol=0.0, low=-1.0, high=1.0, seed=0,
                 inputs=None, name=""):
    rng = np.random.default_rng(seed)
    if inputs is None:
        inputs = [rng.uniform(low, high, size=s).astype(np.float32) for s in shapes]
    reference = np.asarray(reference_fn(*inputs), dtype=np.float64)
    ours = np.asarray(our_fn(*inputs), dtype=np.float64)
    label = f"{name}: " if name else ""
    assert ours.shape == reference.shape, f"{label}shape {ours.shape} != reference {reference.shape}"
    assert np.all(np.isfinite(ours)), f"{label}{np.count_nonzero(~np.isfinite(ours))} non-finite values"
    scale = max(1.0, float(np.max(np.abs(reference))) if reference.size else 1.0)
    bound = atol * scale + rtol * np.abs(reference)
    err = np.abs(ours - reference)
    if err.size and np.any(err > bound):
        worst = np.unravel_index(np.argmax(err - bound), err.shape)
        raise AssertionError(
            f"{label}max |ours - ref| = {err.max():.3e} (bound {atol:.1e}·{scale:.3g} + {rtol:.1e}·|ref|); "
            f"worst at {worst}: ours {ours[worst]:.6g} ref {reference[worst]:.6g}; "
            f"{np.count_nonzero(err > bound)} of {err.size} elements over")
    return ours, reference


def run_frame_pass(gpu, frame_pass, width: int, height: int, planes: dict):
    """Upload ``planes`` ({PlaneSpec: (H, W[, C]) array}) into fresh FrameBuffers, record and submit
    ``frame_pass.execute(encoder, buffers)``, and return the buffers (read them with ``buffers.read``)."""
    from wgpu_rt.frame.planes import write_plane
    from wgpu_rt.passes import FrameBuffers

    buffers = FrameBuffers(gpu, width, height)
    for spec, image in planes.items():
        write_plane(buffers, spec, image)
    encoder = gpu.device.create_command_encoder()
    frame_pass.execute(encoder, buffers)
    gpu.device.queue.submit([encoder.finish()])
    return buffers
