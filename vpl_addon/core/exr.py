"""Multilayer EXR files as Blender writes them: one pass per channel group ``<ViewLayer>.<Pass>``.

``read_passes`` accepts single- and multi-part files and returns ``{pass name: (H,W,C) float32}`` for the first view
layer, rows from the top; ``write_passes`` writes the same layout (one part per pass) with extra header attributes,
through a temporary file renamed into place so no partial file ever carries the final name.
"""
from __future__ import annotations

import os
import tempfile

import numpy as np
import OpenEXR

LAYER = "ViewLayer"


def read_passes(path: str) -> tuple[dict[str, np.ndarray], dict]:
    """Passes of the first view layer in ``path`` and the header of its first part."""
    with OpenEXR.File(str(path)) as f:
        passes: dict[str, np.ndarray] = {}
        layer = None
        for part in f.parts:
            for name, channel in part.channels.items():
                prefix, _, pass_name = name.rpartition(".")
                if not prefix:  # a plain RGB(A) image: treat it as Combined
                    prefix, pass_name = LAYER, "Combined"
                layer = layer or prefix
                if prefix != layer:
                    continue
                pixels = np.asarray(channel.pixels, np.float32)
                passes[pass_name] = pixels if pixels.ndim == 3 else pixels[..., None]
        header = dict(f.parts[0].header) if f.parts else {}
    return passes, header


def write_passes(path: str, passes: dict[str, np.ndarray], attributes: dict | None = None,
                 half: bool = False) -> None:
    """Write passes (H,W,C) as a multi-part EXR, atomically; ``half`` stores 16-bit floats (PIZ) for small files."""
    parts = []
    dtype = np.float16 if half else np.float32
    compression = OpenEXR.PIZ_COMPRESSION if half else OpenEXR.ZIP_COMPRESSION
    for name, image in passes.items():
        header = {"compression": compression, "type": OpenEXR.scanlineimage, "name": name}
        if not parts:
            header.update(attributes or {})
        parts.append(OpenEXR.Part(header, {f"{LAYER}.{name}": np.ascontiguousarray(image, dtype)}))
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(prefix=".partial-", suffix=".exr", dir=folder)
    os.close(fd)
    try:
        with OpenEXR.File(parts) as f:
            f.write(tmp)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
