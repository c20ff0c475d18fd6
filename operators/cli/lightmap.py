"""``python -m vpl_addon lightmap SCENE.blend -o DIR``: every chosen mesh's lightmap from one set of virtual lights
(``vpl_addon.lightmap``), one ``DIR/<object name>.exr`` each (the pass as linear RGB, alpha the texel coverage),
written atomically once all are baked, one line per object with its time.

The input is checked before anything is baked, one clear line per problem (``UserError``): an object that is not
in the scene, is not a mesh or has no such UV map, a size outside 1 to 16384, an unknown pass. Objects left out
of the bake still occlude and reflect light, and their files are not touched.
"""
from __future__ import annotations

import os
import sys
import time

import numpy as np

from ...vpl_addon.core.camera import Camera, view_window
from ...vpl_addon.core.exr import write_passes
from ...vpl_addon.lightmap import BAKE_PASSES, LightmapSettings, bake
from ...vpl_addon.lightmap.bake import MAX_SIZE
from ...vpl_addon.methods import METHODS, MethodSettings
from .scene_flags import UserError, ensure_registered, open_blend


def add_parser(sub) -> None:
    lm = sub.add_parser("lightmap", help="bake each mesh's light into its UV map, every object from one VPL set")
    lm.add_argument("scene", help="the .blend file")
    lm.add_argument("-o", "--output", required=True, help="folder for <object name>.exr (made if missing)")
    lm.add_argument("--objects", help="comma-separated object names (default: every mesh that renders)")
    lm.add_argument("--uv-map", help="the UV map to bake into (default: each mesh's active render UV map)")
    lm.add_argument("--size", type=int, default=128, help="texels per side of each map (default 128)")
    lm.add_argument("--pass", dest="bake_pass", default=BAKE_PASSES[0],
                    help=f"what to bake, as Cycles' bake types: {', '.join(BAKE_PASSES)} (default {BAKE_PASSES[0]})")
    lm.add_argument("--samples", type=int, default=4, help="sample points per texel (default 4)")
    lm.add_argument("--vpls", type=int, help="virtual lights for all the objects (default 4096)")
    lm.add_argument("--method", default="ir", choices=[n for n, m in METHODS.items() if m.sums_lights],
                    help="how the virtual lights are placed (default ir)")
    lm.add_argument("--margin", type=int, default=16, help="texels each island grows by (default 16, at least 2)")
    lm.add_argument("--no-denoise", action="store_true", help="leave the maps as baked (no OIDN lightmap filter)")
    lm.add_argument("--seed", type=int, default=0, help="random seed")
    lm.set_defaults(run=cmd_lightmap)


def cmd_lightmap(args) -> int:
    import bpy
    settings = _settings(args)
    ensure_registered()
    scene = open_blend(args.scene)
    names = _objects(scene, args.objects, args.uv_map)
    from ..scene.extract import ACTIVE_UV, ExtractionError, extract
    depsgraph = bpy.context.evaluated_depsgraph_get()
    t0 = time.perf_counter()
    try:
        built, warnings = extract(depsgraph, camera=_camera(scene, depsgraph),
                                  bake_uv=ACTIVE_UV if args.uv_map is None else args.uv_map)
    except ExtractionError as err:
        raise UserError(str(err)) from None
    hidden = [name for name in names if name not in built.object_names]
    if hidden:
        raise UserError(f"object {hidden[0]!r} has no faces that render (hidden from render, or empty)")
    result = bake(built, names, settings)
    for message in warnings + result.warnings:
        print(f"warning: {message}", file=sys.stderr)
    os.makedirs(args.output, exist_ok=True)
    vpls = result.info.get("vpls", 0)
    print(f"{vpls} VPLs placed for {len(names)} objects in {result.seconds['place']:.2f} s")
    for name in names:
        path = os.path.join(args.output, f"{_file_name(name)}.exr")
        write_passes(path, {settings.bake_pass: result.images[name]})
        print(f"wrote {path}: {settings.size}x{settings.size} {settings.bake_pass}, {result.seconds[name]:.2f} s")
    print(f"lightmaps of {len(names)} objects in {time.perf_counter() - t0:.2f} s")
    return 0


def _settings(args) -> LightmapSettings:
    """The bake's settings from the flags, each bad one refused in a line that names it."""
    if not 0 < args.size <= MAX_SIZE:
        raise UserError(f"--size {args.size}: must be between 1 and {MAX_SIZE} texels")
    if args.bake_pass not in BAKE_PASSES:
        raise UserError(f"--pass {args.bake_pass!r}: choose one of {', '.join(BAKE_PASSES)}")
    for flag, value, least in (("samples", args.samples, 1), ("vpls", args.vpls, 1), ("margin", args.margin, 0)):
        if value is not None and value < least:
            raise UserError(f"--{flag} {value}: must be at least {least}")
    placement = MethodSettings(vpls=args.vpls) if args.vpls else LightmapSettings().placement
    return LightmapSettings(size=args.size, samples=args.samples, bake_pass=args.bake_pass, method=args.method,
                            placement=placement, margin=args.margin, denoise=not args.no_denoise, seed=args.seed)


def _objects(scene, listed: str | None, uv_map: str | None) -> list[str]:
    """The names of the objects to bake: those ``listed`` (comma-separated) or every mesh that renders; each a
    mesh with UV map ``uv_map`` (or any UV map, without one)."""
    if listed is None:
        names = [obj.name for obj in scene.objects if obj.type == "MESH" and not obj.hide_render]
        if not names:
            raise UserError(f"scene {scene.name!r} has no mesh to bake")
    else:
        names = [name.strip() for name in listed.split(",") if name.strip()]
    for name in names:
        obj = scene.objects.get(name)
        if obj is None:
            raise UserError(f"--objects: no object {name!r} in scene {scene.name!r}")
        if obj.type != "MESH":
            raise UserError(f"object {name!r} is a {obj.type.lower()}, not a mesh: only meshes are baked")
        layers = obj.data.uv_layers
        if uv_map is not None and uv_map not in layers:
            raise UserError(f"object {name!r} has no UV map {uv_map!r} (it has: "
                            f"{', '.join(layer.name for layer in layers) or 'none'})")
        if not len(layers):
            raise UserError(f"object {name!r} has no UV map: unwrap it (e.g. Smart UV Project) before baking")
    return names


def _camera(scene, depsgraph) -> Camera:
    """The scene's camera (which methods that place by the view read), or a placeholder where it has none."""
    from ..scene.extract import camera_of
    if scene.camera is not None and scene.camera.type == "CAMERA":
        return camera_of(scene, depsgraph)
    return Camera(np.eye(4), 1, 1, view_window(1, 1, orthographic=True, ortho_scale=1.0), orthographic=True)


def _file_name(name: str) -> str:
    """An object's name as a file name: the path separators replaced."""
    return name.replace(os.sep, "_").replace("/", "_")
