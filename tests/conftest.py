"""Shared fixtures. GPU tests skip on a machine with no WebGPU adapter, except under CI (``CI`` set),
where a missing adapter fails the run: a green CI means the kernels really ran."""

import os
import tempfile

import pytest

from wgpu_rt.errors import NoAdapterError


def pytest_configure(config):
    """Choices measured per adapter (wgpu_rt.measured_choices) go to a cache of this test session's
    own, so no test reads one a user's runs left behind (XDG_CACHE_HOME stays: Mesa keeps its compiled
    shaders there)."""
    from wgpu_rt.measured_choices import CACHE_DIR_ENV

    os.environ[CACHE_DIR_ENV] = tempfile.mkdtemp(prefix="wgpu-rt-test-cache-")


def _in_ci() -> bool:
    return os.environ.get("CI", "").lower() not in ("", "0", "false")


@pytest.fixture(scope="session")
def gpu():
    """The process-wide GpuContext (lavapipe in CI)."""
    from wgpu_rt.gpu import get_context

    try:
        return get_context()
    except NoAdapterError as err:
        if _in_ci():
            pytest.fail(f"CI must run the GPU tests, but: {err}")
        pytest.skip(str(err))


@pytest.fixture(scope="session")
def seed_models(tmp_path_factory):
    """The three seed networks (small U-Net widths), random weights, exported once to ONNX."""
    from wgpu_rt.train.networks import export_seed_models

    return export_seed_models(tmp_path_factory.mktemp("seed_models"), widths=(8, 16))


@pytest.fixture(scope="session")
def moving():
    """The built-in animated scene."""
    from wgpu_rt.scene.builtin import builtin_scene

    return builtin_scene("moving")


@pytest.fixture(scope="session")
def mi():
    """Mitsuba 3 set to a variant that loads here (``wgpu_rt.scene.mitsuba.use_variant``: scalar_rgb, or
    on the lent GPUs' trimmed build cuda_ad_rgb); skipped without Mitsuba or without such a variant."""
    mitsuba = pytest.importorskip("mitsuba")
    from wgpu_rt.scene.mitsuba import use_variant

    if use_variant(mitsuba) is None:
        pytest.skip("no Mitsuba variant loads in this build")
    return mitsuba
