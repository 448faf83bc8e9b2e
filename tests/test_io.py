import errno
import json
import os

import numpy as np
import pytest
from exr_files import write_parts

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


def test_exr_channels_keep_their_order_and_names_whatever_the_files_order(tmp_path):
    """A file stores channels in any order (OpenEXR sorts them by name): known sets come back R, G, B, A /
    X, Y, Z, numbered ones in numeric order, and each layer's channel names are kept for writing back."""
    import OpenEXR

    rng = np.random.default_rng(2)
    planes = {name: rng.random((3, 4)).astype(np.float32) for name in
              ("R", "G", "B", "A", "diffuse.R", "diffuse.G", "diffuse.B", "N.X", "N.Y", "N.Z",
               *(f"feature.{i}" for i in range(11)))}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, dict(sorted(planes.items()))) as exr:
        exr.write(str(tmp_path / "theirs.exr"))
    back = read_exr(tmp_path / "theirs.exr")
    assert back.channels == {"color": list("RGBA"), "diffuse": list("RGB"), "N": list("XYZ"),
                             "feature": [str(i) for i in range(11)]}
    for layer, names in back.channels.items():
        for i, name in enumerate(names):
            np.testing.assert_array_equal(back[layer][..., i], planes[name if layer == "color" else f"{layer}.{name}"])
    write_exr(tmp_path / "again.exr", back["color"], {k: v for k, v in back.items() if k != "color"},
              channel_names=back.channels)
    again = read_exr(tmp_path / "again.exr")
    assert again.channels == back.channels
    assert all(np.array_equal(again[layer], back[layer]) for layer in back)


def test_half_layers_are_named_by_their_channels_and_old_numbered_ones_still_read(tmp_path):
    """`--aov half_radiance,half_spp` writes half_radiance.R/G/B and half_spp.Y (as the README says); files
    written before, with half_radiance.0/1/2, read the same."""
    import OpenEXR

    half = np.random.default_rng(3).random((2, 3, 3)).astype(np.float32)
    write_exr(tmp_path / "new.exr", np.zeros((2, 3, 3)), {"half_radiance": half, "half_spp": np.ones((2, 3))})
    new = read_exr(tmp_path / "new.exr")
    assert new.channels["half_radiance"] == list("RGB") and new.channels["half_spp"] == ["Y"]
    channels = {c: np.zeros((2, 3), np.float32) for c in "RGB"}
    channels.update({f"half_radiance.{i}": np.ascontiguousarray(half[..., i]) for i in range(3)})
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, channels) as exr:
        exr.write(str(tmp_path / "old.exr"))
    np.testing.assert_array_equal(read_exr(tmp_path / "old.exr")["half_radiance"], new["half_radiance"])


def test_exr_refuses_nan_and_leaves_no_file(tmp_path):
    color = np.zeros((2, 2, 3), np.float32)
    color[0, 0, 1] = np.nan
    with pytest.raises(ValueError, match="NaN/Inf"):
        write_exr(tmp_path / "bad.exr", color)
    assert list(tmp_path.iterdir()) == []


def test_every_part_of_a_multi_part_file_is_read(tmp_path):
    """Blender 5 writes a multilayer EXR as one part per pass: every part's channels are read as one file's,
    with the first part's header attributes less its layout (its name, its chunk count)."""
    rng = np.random.default_rng(3)
    planes = {name: rng.random((3, 4)) for name in ("VL.Combined.R", "VL.Combined.G", "VL.Combined.B",
                                                    "VL.Combined.A", "VL.Depth.Z", "VL.Normal.X", "VL.Normal.Y",
                                                    "VL.Normal.Z")}
    write_parts(tmp_path / "parts.exr", {"VL.Combined": {k: v for k, v in planes.items() if ".Combined." in k},
                                          "VL.Depth": {"VL.Depth.Z": planes["VL.Depth.Z"]},
                                          "VL.Normal": {k: v for k, v in planes.items() if ".Normal." in k}},
                {"Software": "Blender 5.0.1"})
    back = read_exr(tmp_path / "parts.exr")
    assert back.channels == {"VL.Combined": list("RGBA"), "VL.Depth": ["Z"], "VL.Normal": list("XYZ")}
    for layer, names in back.channels.items():
        for i, name in enumerate(names):
            np.testing.assert_array_equal(back[layer][..., i], np.float32(planes[f"{layer}.{name}"]))
    assert back.attributes == {"Software": "Blender 5.0.1"}


@pytest.mark.parametrize("second, says", [
    ({"a.R": np.zeros((3, 4))}, "channel 'a.R' appears in more than one part"),
    ({"b.R": np.zeros((5, 4))}, "part 'second' is 4×5 pixels, unlike the file's first part"),
])
def test_multi_part_files_whose_parts_clash_are_refused(second, says, tmp_path):
    write_parts(tmp_path / "clash.exr", {"first": {"a.R": np.ones((3, 4))}, "second": second})
    with pytest.raises(ImageError, match=f"clash.exr: {says}"):
        read_exr(tmp_path / "clash.exr")


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
