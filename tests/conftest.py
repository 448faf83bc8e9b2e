"""Shared fixtures. GPU tests skip on a machine with no WebGPU adapter, except under CI (``CI`` set),
where a missing adapter fails the run: a green CI means the kernels really ran."""

import os

import pytest

from wgpu_rt.errors import NoAdapterError


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
