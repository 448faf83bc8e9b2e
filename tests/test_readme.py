"""The README's command lines are the command line's: each `wgpu-rt …` line of its bash blocks parses (its
comment and [optional] parts left out), so a renamed or removed flag cannot linger in the docs."""

import re
import shlex
from pathlib import Path

import pytest

from wgpu_rt.cli import build_parser

README = (Path(__file__).resolve().parents[1] / "README.md").read_text()
LINES = [line.strip() for block in re.findall(r"```bash\n(.*?)```", README, re.S) for line in block.splitlines()
         if line.strip().startswith("wgpu-rt ")]


def arguments(line: str) -> list[str]:
    """The line's arguments after `wgpu-rt`, its comment and [optional] parts left out."""
    return shlex.split(re.sub(r"\[[^\]]*\]", "", re.sub(r"\s#.*$", "", line)))[1:]


def test_the_readme_shows_the_commands():
    assert len(LINES) >= 20 and {arguments(line)[0] for line in LINES} >= {"render", "denoise", "train", "info"}


@pytest.mark.parametrize("line", LINES)
def test_a_readme_command_line_parses(line):
    build_parser().parse_args(arguments(line))   # a flag the command does not have exits with status 2
