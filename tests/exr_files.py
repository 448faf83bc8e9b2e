"""EXR files as other programs write them, for the reader's and `wgpu-rt denoise`'s tests: multi-part files
(Blender 5 writes its multilayer EXR as one part per pass) and Blender's layer names."""

import numpy as np

NO_HIT = 1e10   # Blender's Z pass where nothing was hit


def write_parts(path, parts: dict, attributes: dict | None = None) -> None:
    """A multi-part EXR: {part name: {channel: (H, W) plane}}, each part's data window its planes' size, the
    display window the first part's; ``attributes`` in every part's header."""
    import OpenEXR

    def window(plane):
        return np.zeros(2, np.int32), np.array(plane.shape[::-1], np.int32) - 1

    first = next(iter(next(iter(parts.values())).values()))
    header = {**(attributes or {}), "compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage,
              "displayWindow": window(first)}
    made = [OpenEXR.Part({**header, "name": part, "dataWindow": window(next(iter(channels.values())))},
                         {name: np.ascontiguousarray(plane, np.float32) for name, plane in channels.items()},
                         name=part) for part, channels in parts.items()]
    with OpenEXR.File(made) as exr:
        exr.write(str(path))


def write_blender_exr(path, color, layers: dict, view_layers=("ViewLayer",), samples: int | None = 4,
                      denoising_data: bool = True) -> None:
    """A multilayer EXR as Blender 5 writes one from Cycles: per view layer a part per pass (Combined with an
    alpha, Depth with NO_HIT where the depth is 0, Normal, and the Denoising Data passes when
    ``denoising_data``), and ``cycles.VL.samples`` in the header."""
    h, w = color.shape[:2]
    depth = np.asarray(layers["depth"], np.float32).reshape(h, w)
    passes = {"Combined": ("RGBA", np.dstack([color, np.ones((h, w))])),
              "Depth": ("Z", np.where(depth > 0, depth, NO_HIT)[..., None]), "Normal": ("XYZ", layers["normal"])}
    if denoising_data:
        passes |= {"Denoising Normal": ("XYZ", layers["normal"]), "Denoising Albedo": ("RGB", layers["albedo"]),
                   "Denoising Depth": ("Z", depth[..., None])}
    parts = {f"{vl}.{name}": {f"{vl}.{name}.{c}": planes[..., i] for i, c in enumerate(channels)}
             for vl in view_layers for name, (channels, planes) in passes.items()}
    attributes = {f"cycles.{vl}.samples": str(samples) for vl in view_layers if samples is not None}
    write_parts(path, parts, {"BlenderMultiChannel": "Blender V2.55.1 and newer", **attributes})
