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
