"""Cycles as the judge: converged references rendered with the settings of DESIGN.md, cached by a hash.

The hash covers the .blend file's bytes, the frame, the sample count, the seed and Blender's version, and is stored
in the reference EXR's header (attribute ``vplReference``), so a reference made from an older scene is detected as
stale. A *twin* is the same reference rendered with another seed (``TWIN_SEED``): two references with independent
noise let the bench take their own noise out of an error (``metrics.clean_rrmse``).
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import time

import bpy

from ...vpl_addon.core import passes as P
from ...vpl_addon.core.exr import read_header, read_passes, write_passes
from ..engine.render_engine import LIGHT_PASSES
from .render_file import render_to

HEADER_KEY = "vplReference"
KEPT_PASSES = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_INDIRECT, P.DIFFUSE_COLOR, P.EMIT)
# Kept too, but not part of the hash: a reference without them stays valid for the passes above (the committed
# references of the diffuse example scenes have none).
FURTHER_PASSES = P.GLOSSY + (P.ENVIRONMENT,)
RENAMED = {"Emission": P.EMIT}  # Blender 5's name of Cycles' Emit pass in its files
SEED = 0
TWIN_SEED = 17  # a second reference's seed: noise independent of the first's


def reference_hash(blend_path: str, samples: int, frame: int | None, percentage: int | None = None,
                   seed: int = SEED) -> str:
    digest = hashlib.sha256()
    with open(blend_path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)
    settings = {"samples": samples, "frame": frame, "seed": seed, "blender": bpy.app.version_string,
                "passes": KEPT_PASSES}
    if percentage is not None:
        settings["percentage"] = percentage
    digest.update(json.dumps(settings, sort_keys=True).encode())
    return digest.hexdigest()


def stored_info(path: str) -> dict:
    """The ``vplReference`` record of a reference EXR ({} if it has none)."""
    raw = read_header(path).get(HEADER_KEY)
    return json.loads(raw) if raw else {}


def configure_cycles(scene, samples: int) -> None:
    """Cycles on the CPU, unbiased and repeatable: no denoising, clamping, glossy filter, light threshold or
    adaptive sampling; fixed seed; transparent film (alpha = coverage); every diffuse and glossy pass on."""
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_denoising = False
    c.use_adaptive_sampling = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.light_sampling_threshold = 0.0
    c.seed = SEED
    c.use_animated_seed = False
    scene.render.film_transparent = True
    for layer in scene.view_layers:
        for _, toggle, _, _ in LIGHT_PASSES:
            setattr(layer, toggle, True)


def cache_entry(cache_dir: str, digest: str) -> tuple[str, bool]:
    """The file of ``cache_dir`` that keeps the reference of hash ``digest``, and whether it holds it now (the file
    exists and records that hash)."""
    path = os.path.join(cache_dir, f"{digest}.exr")
    return path, os.path.exists(path) and stored_info(path).get("hash") == digest


def make_reference(blend_path: str, out_path: str, samples: int, frame: int | None = None,
                   cache_dir: str | None = None, percentage: int | None = None, seed: int = SEED) -> dict:
    """Render (or fetch from the cache) the Cycles reference of ``blend_path`` with Cycles' ``seed``; returns its
    record. A twin (a seed other than ``SEED``) keeps Combined alone: it serves only to measure the noise."""
    digest = reference_hash(blend_path, samples, frame, percentage, seed)
    cached, held = cache_entry(cache_dir, digest) if cache_dir else (None, False)
    if held:
        shutil.copyfile(cached, out_path)
        return {**stored_info(out_path), "cached": True}
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(blend_path))
    scene = bpy.context.scene
    if frame is not None:
        scene.frame_set(frame)
    if percentage is not None:
        scene.render.resolution_percentage = percentage
    configure_cycles(scene, samples)
    scene.cycles.seed = seed
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=os.path.dirname(os.path.abspath(out_path))) as tmp:
        raw = os.path.join(tmp, "cycles.exr")
        render_to(scene, raw)
        seconds = time.perf_counter() - t0
        images = {RENAMED.get(name, name): image for name, image in read_passes(raw)[0].items()}
    info = {"hash": digest, "samples": samples, "frame": frame, "percentage": percentage,
            "seconds": round(seconds, 2), "seed": seed,
            "blend": os.path.basename(blend_path), "blender": bpy.app.version_string}
    kept = {name: images[name] for name in (KEPT_PASSES + FURTHER_PASSES if seed == SEED else (P.COMBINED,))
            if name in images}
    write_passes(out_path, kept, {HEADER_KEY: json.dumps(info, sort_keys=True)}, half=True)
    if cached:
        os.makedirs(cache_dir, exist_ok=True)
        shutil.copyfile(out_path, cached)
    return {**info, "cached": False}
