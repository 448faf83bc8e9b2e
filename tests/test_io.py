import numpy as np
import pytest

from wgpu_rt.errors import ImageError
from wgpu_rt.io import read_exr, require_layers, write_exr, write_png


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
