"""Converted public scenes against the reference renders shipped with them: Cycles of the converted .blend at a
modest sample count, mean brightness ratio to the shipped reference (linear EXR to linear EXR, the reference box-
filtered down to our resolution), and a side-by-side PNG (ours | reference, the same exposure and sRGB curve).

    .venv/bin/python bench/scene_check.py [NAME ...] [--scenes scenes] [--source ../shared/scenes] [--samples 256]
        [--out bench/results/scene_check]

Scenes without a shipped reference are rendered too (their PNG shows ours alone), so framing can be checked by eye;
``--exr NAME=PATH`` takes an existing Cycles EXR of a scene (e.g. its converged reference) instead of rendering.
Run it under ``nice``: each scene is a Cycles render of a minute or more on 2 cores.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, ROOT)
from vpl_addon.__main__ import extension_package  # noqa: E402

PKG = extension_package().__name__
import importlib  # noqa: E402

import bpy  # noqa: E402
from PIL import Image  # noqa: E402

shared_scenes = importlib.import_module(f"{PKG}.importers.shared_scenes")
reference = importlib.import_module(f"{PKG}.operators.output.reference")
output = importlib.import_module(f"{PKG}.operators.output.render_file")
exr = importlib.import_module(f"{PKG}.vpl_addon.core.exr")
linear_to_srgb = importlib.import_module(f"{PKG}.vpl_addon.core.color").linear_to_srgb

LUMA = np.array([0.2126, 0.7152, 0.0722])


def box_down(img: np.ndarray, shape) -> np.ndarray:
    """Area-average ``img`` (H,W,C) down to ``shape`` (h, w) when H, W are multiples of h, w."""
    h, w = shape
    H, W = img.shape[:2]
    if (H, W) == (h, w):
        return img
    if H % h or W % w:
        raise ValueError(f"reference {W}x{H} is not a multiple of {w}x{h}")
    return img.reshape(h, H // h, w, W // w, -1).mean(axis=(1, 3))


def to_png(img: np.ndarray, exposure: float) -> np.ndarray:
    x = linear_to_srgb(np.clip(img[..., :3] * exposure, 0, 1))
    return (x * 255 + 0.5).astype(np.uint8)


def render_cycles(blend: str, samples: int) -> tuple[np.ndarray, float]:
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend))
    scene = bpy.context.scene
    reference.configure_cycles(scene, samples)
    scene.render.film_transparent = False  # the shipped references show the background
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "c.exr")
        t0 = time.perf_counter()
        output.render_to(scene, path)
        seconds = time.perf_counter() - t0
        images, _ = exr.read_passes(path)
    return images["Combined"][..., :3].astype(np.float64), seconds


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("names", nargs="*")
    p.add_argument("--scenes", default=os.path.join(ROOT, "scenes"))
    p.add_argument("--source", default=os.path.join(ROOT, "..", "shared", "scenes"))
    p.add_argument("--samples", type=int, default=256)
    p.add_argument("--out", default=os.path.join(ROOT, "bench", "results", "scene_check"))
    p.add_argument("--exr", action="append", default=[], metavar="NAME=PATH",
                   help="use this Cycles EXR for scene NAME instead of rendering it")
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    given = dict(spec.split("=", 1) for spec in args.exr)
    summary = os.path.join(args.out, "check.json")
    rows = json.load(open(summary)) if os.path.isfile(summary) else []
    for name in args.names or list(shared_scenes.SCENES):
        if name in given:
            images, header = exr.read_passes(given[name])
            ours, seconds = images["Combined"][..., :3].astype(np.float64), None
            samples = json.loads(header.get(reference.HEADER_KEY, "{}")).get("samples")
        else:
            blend = os.path.join(args.scenes, name + ".blend")
            ours, seconds = render_cycles(blend, args.samples)
            samples = args.samples
        row = {"scene": name, "samples": samples, "seconds": seconds and round(seconds, 1),
               "mean_ours": [round(float(v), 5) for v in ours.mean((0, 1))]}
        ref_name = shared_scenes.REFERENCE_IMAGES.get(name)
        panels = [ours]
        if ref_name:
            folder = shared_scenes.SCENES[name][0]
            ref_full, _ = exr.read_passes(os.path.join(args.source, folder, ref_name))
            ref = box_down(ref_full["Combined"][..., :3].astype(np.float64), ours.shape[:2])
            panels.append(ref)
            row["reference"] = f"{folder}/{ref_name}"
            row["mean_reference"] = [round(float(v), 5) for v in ref.mean((0, 1))]
            row["ratio_rgb"] = [round(float(a / b), 4) for a, b in zip(ours.mean((0, 1)), ref.mean((0, 1)))]
            row["ratio_luminance"] = round(float((ours @ LUMA).mean() / (ref @ LUMA).mean()), 4)
        key = panels[-1] @ LUMA
        exposure = 0.18 / max(float(np.exp(np.log(key + 1e-4).mean())), 1e-6)  # log-average luminance -> 0.18
        strip = np.concatenate([to_png(x, exposure) for x in panels], axis=1)
        Image.fromarray(strip).save(os.path.join(args.out, f"{name}.png"), optimize=True)
        row["exposure"] = round(exposure, 4)
        rows = [r for r in rows if r["scene"] != name] + [row]
        print(json.dumps(row), flush=True)
    with open(summary, "w") as f:
        json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
