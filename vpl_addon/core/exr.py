"""Multilayer EXR files as Blender writes them: one pass per channel group ``<ViewLayer>.<Pass>``.

``read_passes`` accepts single- and multi-part files and returns ``{pass name: (H,W,C) float32}`` for the first view
layer, rows from the top, channels in Blender's order (RGBA, XYZW, UVA; Cryptomatte's rgba); ``write_passes`` writes
the same layout (one part per pass) with extra header attributes, through a temporary file renamed into place so no
partial file ever carries the final name.
"""
from __future__ import annotations

import os
import tempfile

import numpy as np
import OpenEXR

LAYER = "ViewLayer"
CHANNEL_ORDER = "RGBXYZUVWA"  # of the channels of a pass: RGBA, XYZ(W) of vectors, UVA of the UV pass


def read_passes(path: str, layer: str | None = None) -> tuple[dict[str, np.ndarray], dict]:
    """Passes of the view layer ``layer`` in ``path`` (None: the first; Blender writes the compositor's output first,
    as layer ``Composite``) and the header of its first part."""
    with OpenEXR.File(str(path)) as f:
        channels: dict[str, dict[str, np.ndarray]] = {}  # pass -> channel -> (H,W) or (H,W,C) of grouped RGB(A)
        for part in f.parts:
            for name, channel in part.channels.items():
                prefix, _, pass_name = name.rpartition(".")
                if not prefix:  # a plain RGB(A) image: treat it as Combined
                    prefix, pass_name = LAYER, "Combined"
                letter = ""
                if "." in prefix:  # a channel OpenEXR did not group: <layer>.<pass>.<X|Y|Z|r|...>
                    (prefix, _, pass_name), letter = prefix.rpartition("."), pass_name
                layer = layer or prefix
                if prefix == layer:
                    channels.setdefault(pass_name, {})[letter] = np.asarray(channel.pixels, np.float32)
        header = dict(f.parts[0].header) if f.parts else {}
    passes = {}
    for name, parts in channels.items():
        ordered = [parts[letter] for letter in sorted(parts, key=lambda c: CHANNEL_ORDER.find(c.upper()))]
        passes[name] = np.concatenate([p if p.ndim == 3 else p[..., None] for p in ordered], axis=2)
    return passes, header


def read_header(path: str) -> dict:
    """The header of the first part of ``path`` (what ``read_passes`` returns beside the passes), pixels unread."""
    with OpenEXR.File(str(path), header_only=True) as f:
        return dict(f.parts[0].header) if f.parts else {}


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
