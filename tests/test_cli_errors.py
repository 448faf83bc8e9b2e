"""User-caused failures of ``denoise`` and ``infer`` end in one line on stderr naming the file or flag,
exit status 2, before any work, with nothing written: no output and no temporary file."""

import errno
import os

import numpy as np
import pytest

from wgpu_rt.cli import main
from wgpu_rt.io import write_exr


@pytest.fixture
def inputs(tmp_path):
    """A valid denoiser EXR and an empty-batch .npy, in a folder of their own."""
    folder = tmp_path / "in"
    folder.mkdir()
    layers = {"albedo": np.full((4, 4, 3), 0.5), "normal": np.dstack([np.zeros((4, 4, 2)), np.ones((4, 4))]),
              "depth": np.ones((4, 4))}
    write_exr(folder / "in.exr", np.ones((4, 4, 3)), layers)
    np.save(folder / "empty.npy", np.zeros((0, 10, 8, 8), np.float32))
    (folder / "file").write_text("not a folder")
    (folder / "taken.exr").mkdir()
    (folder / "taken.npy").mkdir()
    cut = (folder / "in.exr").read_bytes()
    (folder / "cut.exr").write_bytes(cut[:-10])
    return folder


# (argv with IN for the inputs folder, what the one line must name, what it must say)
CASES = {
    "denoise --out .txt": (["denoise", "IN/in.exr", "--out", "IN/x.txt"], "--out IN/x.txt",
                           "must end in .exr or .png"),
    "denoise --out a folder": (["denoise", "IN/in.exr", "--out", "IN/taken.exr"], "--out IN/taken.exr",
                               "is a folder"),
    "denoise --out inside a file": (["denoise", "IN/in.exr", "--out", "IN/file/o.exr"], "--out IN/file/o.exr",
                                    "IN/file is a file, not a folder"),
    "denoise truncated input": (["denoise", "IN/cut.exr", "--out", "IN/o.exr"], "IN/cut.exr",
                                "not a readable OpenEXR file"),
    "infer --output a folder": (["infer", "m.onnx", "--input", "IN/empty.npy", "--output", "IN/taken.npy"],
                                "--output IN/taken.npy", "is a folder"),
    "infer --output inside a file": (["infer", "m.onnx", "--input", "IN/empty.npy", "--output", "IN/file/o.npy"],
                                     "--output IN/file/o.npy", "IN/file is a file, not a folder"),
    "infer --output .txt": (["infer", "m.onnx", "--input", "IN/empty.npy", "--output", "IN/o.txt"],
                            "--output IN/o.txt", "must end in .npy"),
    "render --quality without --denoise": (["render", "cornell", "--out", "IN/o.exr", "--quality", "high"],
                                           "--quality high", "is the denoiser's: add --denoise"),
    "render --low-band without --denoise": (["render", "cornell", "--out", "IN/o.exr", "--low-band", "on"],
                                            "--low-band on", "is the denoiser's: add --denoise"),
    "infer empty batch": (["infer", "m.onnx", "--input", "IN/empty.npy", "--output", "IN/o.npy"],
                          "IN/empty.npy", "shape (0, 10, 8, 8) is empty"),
}


def _tree(folder):
    return sorted((str(p.relative_to(folder)), p.is_dir()) for p in folder.rglob("*"))


def _refused_in_one_line(argv, names, says, folder, capfd):
    before = _tree(folder)
    assert main([arg.replace("IN", str(folder)) for arg in argv]) == 2
    out, err = capfd.readouterr()
    assert out == ""
    assert err.count("\n") == 1 and err.startswith(f"wgpu-rt {argv[0]}: error: "), err
    assert names.replace("IN", str(folder)) in err and says.replace("IN", str(folder)) in err, err
    assert _tree(folder) == before   # no output, no temporary file


@pytest.mark.parametrize("case", CASES)
def test_refused_in_one_line_before_any_work(case, inputs, capfd):
    _refused_in_one_line(*CASES[case], inputs, capfd)


def test_read_only_output_folder_is_refused(inputs, capfd):
    if os.geteuid() == 0:
        pytest.skip("root writes through permission bits")
    locked = inputs / "locked"
    locked.mkdir(mode=0o555)
    try:
        _refused_in_one_line(["denoise", "IN/in.exr", "--out", "IN/locked/o.exr"], "--out IN/locked/o.exr",
                             "cannot write in IN/locked (Permission denied)", inputs, capfd)
    finally:
        locked.chmod(0o755)


def test_an_os_error_naming_a_path_is_one_line(monkeypatch, capfd):
    from wgpu_rt.commands import info

    def full_disk(args):
        raise OSError(errno.ENOSPC, "No space left on device", "/data/out.exr")

    monkeypatch.setattr(info, "run", full_disk)
    assert main(["info"]) == 2
    assert capfd.readouterr().err == "wgpu-rt info: error: /data/out.exr: No space left on device\n"


def test_an_os_error_naming_no_path_keeps_its_traceback(monkeypatch):
    from wgpu_rt.commands import info

    def bug(args):
        raise OSError("a bug, not the user's doing")

    monkeypatch.setattr(info, "run", bug)
    with pytest.raises(OSError, match="a bug"):
        main(["info"])



@pytest.mark.parametrize("printed", [10, 100_000], ids=["at the last flush", "mid-run"])
def test_a_reader_that_leaves_early_ends_the_command_quietly(printed):
    """`wgpu-rt info | head -1`: once the pipe's reader has gone, the command stops with status 141 (as
    a tool killed by SIGPIPE) and no traceback, whether a write fails mid-run or at the last flush."""
    import subprocess
    import sys

    script = ("import sys\nimport wgpu_rt.commands.info as info\nfrom wgpu_rt.cli import main\n"
              f"info.run = lambda args: print('x' * {printed}) or 0\nsys.exit(main(['info']))\n")
    read_end, write_end = os.pipe()
    os.close(read_end)   # nobody reads: the first write that reaches the pipe fails
    done = subprocess.run([sys.executable, "-c", script], stdout=write_end, stderr=subprocess.PIPE, text=True)
    os.close(write_end)
    assert done.returncode == 141 and done.stderr == "", done.stderr


def test_a_command_that_returns_after_a_swallowed_sigterm_exits_143(monkeypatch):
    """A library that catches BaseException can swallow the exit SIGTERM raises; the command then runs on
    to its end, and the CLI still reports the termination (status 143), not success."""
    import signal

    from wgpu_rt import termination
    from wgpu_rt.commands import info

    def run_swallowing_sigterm(args):
        try:
            termination.on_sigterm(signal.SIGTERM, None)
        except BaseException:
            pass
        return 0

    monkeypatch.setattr(info, "run", run_swallowing_sigterm)
    before = signal.getsignal(signal.SIGTERM)
    assert main(["info"]) == 143
    assert termination.received() is None and signal.getsignal(signal.SIGTERM) is before
