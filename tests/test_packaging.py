"""The wheel must carry every package and the shader/model resource folders."""

import tomllib
from importlib import resources
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_package_is_listed():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(config["packages"])
    found = {".".join(p.parent.relative_to(ROOT).parts) for p in (ROOT / "wgpu_rt").rglob("__init__.py")}
    assert found <= listed, f"add to [tool.setuptools] packages: {sorted(found - listed)}"
    for resource_package, folder in config["package-dir"].items():
        assert (ROOT / folder / "__init__.py").exists(), folder
        assert resource_package in listed


def test_resource_packages_resolve():
    for package in ("wgpu_rt.wgsl", "wgpu_rt.nn_kernels", "wgpu_rt.models"):
        assert resources.files(package).is_dir()


def test_package_data_covers_every_resource_file():
    """A shader in a new stage subfolder must be named in package-data, or the wheel ships without it."""
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    for resource_package, patterns in config["package-data"].items():
        folder = ROOT / config["package-dir"][resource_package]
        covered = {p for pattern in patterns for p in folder.glob(pattern)}
        shipped = {p for p in folder.rglob("*") if p.suffix in (".wgsl", ".onnx", ".md")}
        assert shipped <= covered, f"{resource_package}: package-data misses {sorted(map(str, shipped - covered))}"


def test_the_command_line_says_its_version(capsys):
    import pytest

    from wgpu_rt import __version__
    from wgpu_rt.cli import main

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    with pytest.raises(SystemExit) as exit_status:
        main(["--version"])
    assert exit_status.value.code == 0 and capsys.readouterr().out == f"wgpu-rt {__version__}\n"
    assert __version__ == config["version"]
