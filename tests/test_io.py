import errno
import json
import os

import numpy as np
import pytest

from wgpu_rt.errors import ImageError, OutputError
from wgpu_rt.io import (
    atomic_output,
    check_output_path,
    read_exr,
    require_layers,
    write_exr,
    write_json,
    write_png,
)


def test_exr_roundtrip_keeps_layers_and_order(tmp_path):
    rng = np.random.default_rng(1)
    color = rng.uniform(0, 50, (6, 7, 3)).astype(np.float32)
    layers = {"albedo": rng.random((6, 7, 3)), "normal": rng.normal(size=(6, 7, 3)),
              "depth": rng.random((6, 7)), "motion": rng.normal(size=(6, 7, 2)), "spp": np.full((6, 7), 4.0),
              "features": rng.random((6, 7, 12))}
    path = tmp_path / "x.exr"
    write_exr(path, color, layers)
    back = read_exr(path)
    assert set(back) == {"color", *layers}
    np.testing.assert_array_equal(back["color"], color)
    for name, array in layers.items():
        np.testing.assert_allclose(back[name], np.asarray(array, np.float32).reshape(back[name].shape))
    assert back["depth"].shape == (6, 7, 1) and back["features"].shape == (6, 7, 12)


def test_exr_refuses_nan_and_leaves_no_file(tmp_path):
    color = np.zeros((2, 2, 3), np.float32)
    color[0, 0, 1] = np.nan
    with pytest.raises(ValueError, match="NaN/Inf"):
        write_exr(tmp_path / "bad.exr", color)
    assert list(tmp_path.iterdir()) == []


def test_exr_refuses_mismatched_layer(tmp_path):
    with pytest.raises(ValueError, match="albedo"):
        write_exr(tmp_path / "bad.exr", np.zeros((2, 2, 3)), {"albedo": np.zeros((3, 2, 3))})


def test_read_errors_name_the_file(tmp_path):
    with pytest.raises(ImageError, match="missing.exr: no such file"):
        read_exr(tmp_path / "missing.exr")
    corrupt = tmp_path / "corrupt.exr"
    corrupt.write_bytes(b"v/1\x01 definitely not an exr")
    with pytest.raises(ImageError, match="corrupt.exr: not a readable OpenEXR"):
        read_exr(corrupt)


def test_require_layers_names_missing_layer(tmp_path):
    path = tmp_path / "c.exr"
    write_exr(path, np.ones((2, 2, 3)))
    with pytest.raises(ImageError, match=r"c.exr: missing layer 'albedo' \(channels albedo.R"):
        require_layers(read_exr(path), path, "color", "albedo")


def test_png_writes_8bit(tmp_path):
    from PIL import Image

    display = np.linspace(0, 1, 12, dtype=np.float32).reshape(2, 2, 3)
    write_png(tmp_path / "p.png", display)
    pixels = np.asarray(Image.open(tmp_path / "p.png"))
    assert pixels.dtype == np.uint8 and pixels.shape == (2, 2, 3)
    assert pixels[0, 0, 0] == 0 and pixels[1, 1, 2] == 255


def test_json_writes_atomically(tmp_path):
    write_json(tmp_path / "a" / "m.json", {"views": [1, 2]})
    assert json.loads((tmp_path / "a" / "m.json").read_text()) == {"views": [1, 2]}
    assert [p.name for p in (tmp_path / "a").iterdir()] == ["m.json"]


@pytest.mark.parametrize("failure", [RuntimeError("boom"), KeyboardInterrupt()])
def test_atomic_output_failure_keeps_the_old_file_and_leaves_no_temporary(tmp_path, failure):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(type(failure)), atomic_output(target) as tmp:
        tmp.write_bytes(b"half")
        raise failure
    assert target.read_bytes() == b"old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


def test_atomic_output_names_the_target_in_an_unnamed_os_error(tmp_path):
    target = tmp_path / "out.bin"
    with pytest.raises(OSError) as caught, atomic_output(target):
        raise OSError(errno.ENOSPC, "No space left on device")   # what a write to a full disk raises
    assert caught.value.errno == errno.ENOSPC and caught.value.filename == str(target)
    assert list(tmp_path.iterdir()) == []


def _folder(tmp_path):
    (tmp_path / "taken.exr").mkdir()
    return tmp_path / "taken.exr"


def _inside_a_file(tmp_path):
    (tmp_path / "file").write_text("x")
    return tmp_path / "file" / "sub" / "out.exr"


@pytest.mark.parametrize("make, reason", [
    (lambda tmp_path: tmp_path / "out.png", "the output must end in .exr"),
    (lambda tmp_path: tmp_path / "out", "the output must end in .exr"),
    (_folder, "is a folder"),
    (_inside_a_file, "file is a file, not a folder"),
])
def test_check_output_path_refuses_with_flag_and_path(tmp_path, make, reason):
    path = make(tmp_path)
    before = sorted(tmp_path.rglob("*"))
    with pytest.raises(OutputError, match=f"^--out {path}: .*{reason}"):
        check_output_path(path, "--out", (".exr",))
    assert sorted(tmp_path.rglob("*")) == before


def test_check_output_path_accepts_new_folders_and_any_case(tmp_path):
    assert check_output_path(tmp_path / "a" / "b" / "X.EXR", "--out", (".exr",)) == tmp_path / "a" / "b" / "X.EXR"
    assert list(tmp_path.iterdir()) == []   # the folders are made by the write, not the check


def test_check_output_path_refuses_a_read_only_folder(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes through permission bits")
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o555)
    with pytest.raises(OutputError, match=f"--out {folder}/new/out.exr: cannot write in {folder} "
                                          r"\(Permission denied\)"):
        check_output_path(folder / "new" / "out.exr", "--out")


def test_exr_write_failure_is_an_output_error_naming_the_file(tmp_path):
    if os.geteuid() == 0:
        pytest.skip("root writes through permission bits")
    folder = tmp_path / "ro"
    folder.mkdir(mode=0o555)
    try:
        with pytest.raises(OutputError, match=f"^{folder}/x.exr: cannot write .*{folder}/x.exr"):
            write_exr(folder / "x.exr", np.zeros((2, 2, 3)))
    finally:
        folder.chmod(0o755)
    assert list(folder.iterdir()) == []


def test_truncated_exr_is_one_error_and_no_library_output(tmp_path, capfd):
    path = tmp_path / "cut.exr"
    write_exr(path, np.random.default_rng(0).random((20, 28, 3)))
    path.write_bytes(path.read_bytes()[:-10])
    with pytest.raises(ImageError, match=r"cut.exr: not a readable OpenEXR file \(.*corrupt"):
        read_exr(path)
    assert capfd.readouterr() == ("", "")
