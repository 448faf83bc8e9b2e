import os
import subprocess
import sys

import numpy as np
import pytest
import wgpu

from wgpu_rt.errors import NoAdapterError
from wgpu_rt.gpu import BOUNDS_CHECKS_ENV, select_adapter, shader_module


def test_roundtrip_and_compute(gpu):
    code = """
    @group(0) @binding(0) var<storage, read_write> data: array<f32>;
    @compute @workgroup_size(64) fn main(@builtin(global_invocation_id) id: vec3u) {
        if (id.x < arrayLength(&data)) { data[id.x] = data[id.x] * 2.0 + 1.0; }
    }"""
    values = np.arange(100, dtype=np.float32)
    buf = gpu.upload(values)
    pipeline = gpu.compute_pipeline(code)
    enc = gpu.device.create_command_encoder()
    cp = enc.begin_compute_pass()
    cp.set_pipeline(pipeline)
    cp.set_bind_group(0, gpu.bind_group(pipeline, [buf]))
    cp.dispatch_workgroups(2)
    cp.end()
    gpu.device.queue.submit([enc.finish()])
    np.testing.assert_array_equal(gpu.read(buf, shape=(100,)), values * 2 + 1)


def test_shader_modules_drop_bounds_checks_unless_asked(gpu, monkeypatch):
    """Modules come from wgpu-native's trusted call (no naga clamps); WGPU_RT_BOUNDS_CHECKS=1 goes back
    to wgpu-py's checked create_shader_module. Both compile the same WGSL and validate it alike."""
    device_type = type(gpu.device)
    checked_calls = []
    checked = device_type.create_shader_module

    def counting(self, **kwargs):
        checked_calls.append(kwargs["label"])
        return checked(self, **kwargs)

    monkeypatch.setattr(device_type, "create_shader_module", counting)
    code = "@compute @workgroup_size(1) fn main() { }"
    monkeypatch.delenv(BOUNDS_CHECKS_ENV, raising=False)
    assert "GPUShaderModule" in repr(shader_module(gpu.device, code, "trusted"))
    assert checked_calls == []
    with pytest.raises(wgpu.GPUValidationError, match="'bad'"):
        shader_module(gpu.device, "@compute @workgroup_size(1) fn main() { let x: f32 = 1u; }", "bad")
    monkeypatch.setenv(BOUNDS_CHECKS_ENV, "1")
    shader_module(gpu.device, code, "checked")
    assert checked_calls == ["checked"]


def test_prefers_vulkan_over_opengl(gpu):
    assert "OpenGL" not in gpu.label


def test_unknown_adapter_name_lists_available(gpu):
    with pytest.raises(NoAdapterError, match="no adapter matches 'no-such-gpu'"):
        select_adapter("no-such-gpu")


def test_buffer_limit_error_names_what(gpu):
    from wgpu_rt.errors import DeviceLimitError
    with pytest.raises(DeviceLimitError, match="BVH nodes needs .* MiB in one storage buffer.*`wgpu-rt info` lists"):
        gpu.check_buffer_size(1 << 40, "BVH nodes")


def test_info_command(gpu):
    """It names the adapter, its features and the NN engine's defaults there (autotuning as the
    environment says)."""
    from wgpu_rt.nn.model import default_conv_tiling, default_math, default_precision, default_weight_fetch

    env = {k: v for k, v in os.environ.items() if k != "WGPU_RT_AUTOTUNE"}
    out = subprocess.run([sys.executable, "-m", "wgpu_rt", "info"], capture_output=True, text=True, env=env)
    assert out.returncode == 0, out.stderr
    assert "chosen:" in out.stdout and "shader-f16" in out.stdout
    precision = default_precision(gpu)
    assert (f"nn engine: precision {precision} ({default_math(gpu, precision)} math), "
            f"conv tiling {default_conv_tiling(gpu)}, weight fetch {default_weight_fetch(gpu)}, "
            in out.stdout and "autotuning off" in out.stdout)
    tuned = subprocess.run([sys.executable, "-m", "wgpu_rt", "info"], capture_output=True, text=True,
                           env={**env, "WGPU_RT_AUTOTUNE": "1"})
    assert "autotuning on" in tuned.stdout


def test_info_lists_the_choices_measured_on_this_adapter(gpu, tmp_path):
    import json

    from wgpu_rt.measured_choices import CACHE_DIR_ENV, CACHE_VERSION, MeasuredChoices

    adapter = MeasuredChoices(gpu, tmp_path / "unused.json").adapter
    entries = {f"{adapter} | BVH layout | accel/x.wgsl | ~2^16 triangles":
               {"variant": "wide", "seconds": {"threaded": 0.09, "wide": 0.05}},
               "another GPU | | Vulkan | BVH layout | accel/x.wgsl | ~2^12 triangles": {"variant": "threaded"}}
    (tmp_path / "autotune.json").write_text(json.dumps({"version": CACHE_VERSION, "entries": entries}))
    out = subprocess.run([sys.executable, "-m", "wgpu_rt", "info"], capture_output=True, text=True,
                         env={**os.environ, CACHE_DIR_ENV: str(tmp_path)})
    assert out.returncode == 0, out.stderr
    assert f"1 choice(s) kept for this adapter in {tmp_path / 'autotune.json'}" in out.stdout
    assert "BVH layout | accel/x.wgsl | ~2^16 triangles: wide (threaded 90 ms, wide 50 ms)" in out.stdout
    assert "another GPU" not in out.stdout and "2^12" not in out.stdout


def test_bad_adapter_flag_exits_nonzero(gpu):
    out = subprocess.run([sys.executable, "-m", "wgpu_rt", "--adapter", "nope", "info"],
                         capture_output=True, text=True)
    assert out.returncode == 2 and "no adapter matches 'nope'" in out.stderr


def test_no_xdg_runtime_dir_noise_and_no_folder_left(gpu, tmp_path):
    # libwayland, probed while enumerating adapters, prints an "error:" line per probe without it.
    env = {k: v for k, v in os.environ.items() if k != "XDG_RUNTIME_DIR"}
    env["TMPDIR"] = str(tmp_path)
    out = subprocess.run([sys.executable, "-m", "wgpu_rt", "info"], capture_output=True, text=True, env=env,
                         check=False)
    assert out.returncode == 0 and out.stderr == ""
    assert list(tmp_path.iterdir()) == []     # the private runtime folder went with the process


@pytest.mark.parametrize("value", [None, "", "relative/dir", "/no/such/folder"])
def test_runtime_dir_is_made_private_only_when_invalid(value, monkeypatch, tmp_path):
    from wgpu_rt.gpu import ensure_runtime_dir

    if value is None:
        monkeypatch.delenv("XDG_RUNTIME_DIR", raising=False)
    else:
        monkeypatch.setenv("XDG_RUNTIME_DIR", value)
    ensure_runtime_dir()
    made = os.environ["XDG_RUNTIME_DIR"]
    assert os.path.isabs(made) and os.stat(made).st_mode & 0o777 == 0o700
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    ensure_runtime_dir()
    assert os.environ["XDG_RUNTIME_DIR"] == str(tmp_path)
