"""The package's imports follow the frame's data flow: a stage imports only from stages before it (or
its own), never up, and no modules import each other in a cycle. Function-level imports count too."""

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "wgpu_rt"
# Lower first. Shared infrastructure (errors, SIGTERM's record, GPU context, shaders, files, metrics, the pass
# contract, the network registry) sits under every stage.
STAGES = [
    {"errors", "termination", "gpu", "shaders", "io", "measured_choices", "metrics", "passes", "models"},
    {"scene"},
    {"accel"},
    {"trace"},
    {"nn"},
    {"frame"},
    {"renderer"},
    {"dataset"},
    {"train"},
    {"commands", "cli", "__main__"},
]


def stage_of(module: str) -> int:
    part = module.split(".")[1] if "." in module else ""
    for rank, names in enumerate(STAGES):
        if part in names:
            return rank
    raise AssertionError(f"{module}: not placed in a stage of tests/test_layers.py")


def module_name(path: Path) -> str:
    parts = ("wgpu_rt",) + path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path) -> set[str]:
    """wgpu_rt modules that ``path`` imports (``from . import x`` names module x when it is one)."""
    name = module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - node.level + 1] if node.level else []
            target = ".".join(base + ([node.module] if node.module else [])) if node.level else node.module
            for alias in node.names:
                candidate = f"{target}.{alias.name}"
                found.add(candidate if candidate in MODULES else target)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {m for m in found if m.startswith("wgpu_rt.")}


MODULES = {module_name(p) for p in ROOT.rglob("*.py")}
GRAPH = {module_name(p): imports_of(p) for p in ROOT.rglob("*.py") if module_name(p) != "wgpu_rt"}


@pytest.mark.parametrize("module", sorted(GRAPH))
def test_no_import_reaches_a_later_stage(module):
    upward = sorted(m for m in GRAPH[module] if stage_of(m) > stage_of(module))
    assert not upward, f"{module} imports from a later stage: {upward}"


def test_no_import_cycles():
    visiting, done = [], set()

    def visit(module):
        if module in visiting:
            raise AssertionError("import cycle: " + " → ".join(visiting[visiting.index(module):] + [module]))
        if module in done or module not in GRAPH:
            return
        visiting.append(module)
        for target in sorted(GRAPH[module]):
            visit(target)
        visiting.pop()
        done.add(module)

    for module in sorted(GRAPH):
        visit(module)


def test_the_checks_can_fail():
    """A stage importing upward and a two-module cycle are both caught."""
    assert stage_of("wgpu_rt.scene.loader") < stage_of("wgpu_rt.frame.pipeline")
    with pytest.raises(AssertionError, match="later stage"):
        GRAPH["wgpu_rt.scene.fake"] = {"wgpu_rt.frame.pipeline"}
        try:
            test_no_import_reaches_a_later_stage("wgpu_rt.scene.fake")
        finally:
            del GRAPH["wgpu_rt.scene.fake"]
