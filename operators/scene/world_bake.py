"""Worlds the engine cannot read node by node (Sky Texture, gradients, mixes of backgrounds, linked strengths) as
Cycles itself sees them: Cycles renders the world alone through an equirectangular panoramic camera at the origin,
once, into the map the engine's environment light samples (``lights/environment.py``), cached by a digest of the
world's node tree.

The render runs in a separate Blender process (``bpy.app.binary_path -b``, or the Python that has the ``bpy``
module), since a render engine cannot start another render from inside its own. The world is handed over as a
library file (``bpy.data.libraries.write``, paths made absolute) at the frame being rendered, so animated worlds bake
per frame. The camera looks along +X with +Z up: Cycles' equirectangular image then has +X in its middle and +Z at
the top, the engine's convention.
"""
from __future__ import annotations

import hashlib
import os
import subprocess
import sys
import tempfile
import time
from typing import Callable

import bpy
import numpy as np

from ...vpl_addon.core.compiled import cache_root
from ...vpl_addon.render import Cancelled

WIDTH, HEIGHT = 1024, 512  # a texel is 0.35 degrees: Nishita's sun disc (0.545 degrees) spans about two
SAMPLES = 16  # a smooth world (the sky without its sun disc): Diffuse Direct mean within 0.1 % of Cycles
SUN_SAMPLES = 256  # a Sky Texture's sun disc covers a few texels, lit by few of 16 samples: 2-3 % of its light off
# at 16 or 64 samples, 0.5 % at 256 (mean Diffuse Direct against Cycles, tests/cycles/test_world_bake.py)
TIMEOUT = 300.0  # seconds
POLL = 0.1  # seconds between two looks at the user's ESC while Cycles bakes

_SCRIPT = """
import sys, bpy, numpy as np
library, name, out, frame, width, height, samples = sys.argv[sys.argv.index("--") + 1:]
bpy.ops.wm.read_factory_settings(use_empty=True)
with bpy.data.libraries.load(library) as (source, target):
    target.worlds = [name]
scene = bpy.context.scene
scene.world = target.worlds[0]
camera = bpy.data.objects.new("Panorama", bpy.data.cameras.new("Panorama"))
camera.data.type, camera.data.panorama_type = "PANO", "EQUIRECTANGULAR"
camera.rotation_euler = (1.5707963267948966, 0.0, -1.5707963267948966)
scene.collection.objects.link(camera)
scene.camera = camera
scene.frame_set(int(frame))
scene.render.engine = "CYCLES"
scene.cycles.device, scene.cycles.samples, scene.cycles.use_denoising = "CPU", int(samples), False
scene.cycles.use_adaptive_sampling = False
scene.render.resolution_x, scene.render.resolution_y, scene.render.resolution_percentage = int(width), int(height), 100
scene.render.film_transparent = False
scene.render.image_settings.file_format, scene.render.image_settings.color_depth = "OPEN_EXR", "32"
scene.render.filepath = out + ".exr"
bpy.ops.render.render(write_still=True)
image = bpy.data.images.load(out + ".exr")
pixels = np.empty(len(image.pixels), np.float32)
image.pixels.foreach_get(pixels)
np.save(out, pixels.reshape(int(height), int(width), -1)[..., :3])
"""


class BakeError(RuntimeError):
    """Cycles could not bake the world; the message says why."""


def cache_dir() -> str:
    """Where baked worlds are kept: ``$VPL_GI_CACHE/worlds``, by default under ~/.cache/vpl_gi."""
    return os.path.join(cache_root(), "worlds")


def baked_world(world, frame: int, progress: Callable[[str], bool] | None = None) -> np.ndarray:
    """(HEIGHT, WIDTH, 3) float32 linear radiance of ``world`` (an evaluated or original datablock) as Cycles
    renders it at ``frame``, rows from the bottom; from the cache when this tree was baked before. While Cycles bakes,
    ``progress(text)`` is told so every ``POLL`` seconds and may return False to stop it (ESC): ``Cancelled``."""
    samples = SUN_SAMPLES if _has_sun_disc(world.node_tree, set()) else SAMPLES
    digest = world_digest(world)
    path = os.path.join(cache_dir(), f"{digest}.npy")
    if os.path.exists(path):
        try:
            return np.load(path)
        except (OSError, ValueError):
            pass  # a damaged cache file is baked again
    os.makedirs(cache_dir(), exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="vpl_world_") as folder:
        library, out = os.path.join(folder, "world.blend"), os.path.join(folder, "world")
        original = world.original
        bpy.data.libraries.write(library, {original}, path_remap="ABSOLUTE", fake_user=True)
        command = _blender() + ["--", library, original.name, out, str(frame), str(WIDTH), str(HEIGHT), str(samples)]
        returncode, stderr = _run(command, samples, progress)
        if returncode != 0 or not os.path.exists(out + ".npy"):
            last = (stderr.strip().splitlines() or ["no message"])[-1]
            raise BakeError(f"Cycles failed ({last})")
        image = np.load(out + ".npy")
    with tempfile.NamedTemporaryFile(dir=cache_dir(), prefix=".partial-", suffix=".npy", delete=False) as f:
        np.save(f, image)
    os.replace(f.name, path)  # never a half-written cache file under the final name, nor two processes' in one file
    return image


def _run(command: list[str], samples: int, progress) -> tuple[int, str]:
    """Run the bake, telling ``progress`` and stopping when it says so or after ``TIMEOUT``; (exit code, stderr)."""
    try:
        process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    except OSError as err:
        raise BakeError(f"Cycles did not start ({err})") from err
    start = time.monotonic()
    try:
        while True:
            try:
                _, stderr = process.communicate(timeout=POLL)
                return process.returncode, stderr
            except subprocess.TimeoutExpired:
                seconds = time.monotonic() - start
                if progress is not None and progress(f"baking the world with Cycles ({samples} samples, "
                                                     f"{seconds:.0f} s; once per world)") is False:
                    raise Cancelled()
                if seconds > TIMEOUT:
                    raise BakeError(f"Cycles did not finish in {TIMEOUT:.0f} s")
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()


def _blender() -> list[str]:
    """The command that runs ``_SCRIPT`` in a fresh Blender: the Blender binary, or (the ``bpy`` module, whose
    binary path is empty) this Python."""
    if bpy.app.binary_path and os.path.basename(bpy.app.binary_path).lower().startswith("blender"):
        return [bpy.app.binary_path, "-b", "--factory-startup", "--python-expr", _SCRIPT]
    return [sys.executable, "-c", _SCRIPT]


def world_digest(world) -> str:
    """A digest of everything in ``world``'s node tree that changes its light: node kinds and settings, input
    values, links, node groups and images (path, size), and the bake's own resolution and samples."""
    digest = hashlib.sha256(f"{bpy.app.version_string} {WIDTH} {HEIGHT} {SAMPLES} {SUN_SAMPLES}".encode())
    _tree_digest(world.node_tree, digest, set())
    return digest.hexdigest()


def _has_sun_disc(tree, seen: set) -> bool:
    """Whether a Sky Texture with its sun disc on is in ``tree`` or its node groups."""
    if tree is None or tree.name_full in seen:
        return False
    seen.add(tree.name_full)
    return any((n.type == "TEX_SKY" and getattr(n, "sun_disc", False))
               or (n.type == "GROUP" and _has_sun_disc(n.node_tree, seen)) for n in tree.nodes)


_BASE = set(bpy.types.ShaderNode.bl_rna.properties.keys())


def _tree_digest(tree, digest, seen: set) -> None:
    if tree is None or tree.name_full in seen:
        return
    seen.add(tree.name_full)
    for node in sorted(tree.nodes, key=lambda n: n.name):
        values = [node.bl_idname, node.name, node.mute]
        for key, prop in node.bl_rna.properties.items():
            if key in _BASE or prop.type in {"POINTER", "COLLECTION"}:
                continue
            value = getattr(node, key)
            values.append((key, tuple(value) if hasattr(value, "__len__") and not isinstance(value, str) else value))
        for socket in node.inputs:
            value = getattr(socket, "default_value", None)
            values.append((socket.identifier, tuple(value) if hasattr(value, "__len__") else value))
        image = getattr(node, "image", None)
        if image is not None:
            values.append((image.filepath, tuple(image.size), image.source))
        digest.update(repr(values).encode())
        if node.type == "GROUP":
            _tree_digest(node.node_tree, digest, seen)
    for link in tree.links:
        digest.update(repr((link.from_node.name, link.from_socket.identifier, link.to_node.name,
                            link.to_socket.identifier, link.is_muted)).encode())
