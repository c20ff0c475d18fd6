"""``python -m vpl_addon lightmap SCENE.blend -o DIR``: every chosen mesh's lightmap from one set of virtual lights
(``vpl_addon.lightmap``), one ``DIR/<object name>.exr`` each (the pass as linear RGB, alpha the texel coverage),
written atomically once all are baked, one line per object with its time.

The input is checked before anything is baked, one clear line per problem (``UserError``): an object that is not
in the scene, is not a mesh or has no such UV map (``output.lightmap_bake``, shared with the panel's operator), a
size outside 1 to 16384, an unknown pass. Objects left out of the bake still occlude and reflect light, and their
files are not touched.
"""
from __future__ import annotations

import sys
import time

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
    lm.add_argument("--texel-density", type=float,
                    help="texels a metre of surface spans: each object's size from its area, the nearest power of "
                         "two (in place of --size)")
    lm.add_argument("--pass", dest="bake_pass", default=BAKE_PASSES[0],
                    help=f"what to bake, as Cycles' bake types: {', '.join(BAKE_PASSES)} (default {BAKE_PASSES[0]})")
    lm.add_argument("--samples", type=int, default=4, help="sample points per texel (default 4)")
    lm.add_argument("--vpls", type=int,
                    help="virtual lights for all the objects (default 16384; each texel gathers 256 of them)")
    lm.add_argument("--method", default="ir", choices=[n for n, m in METHODS.items() if m.sums_lights],
                    help="how the virtual lights are placed (default ir)")
    lm.add_argument("--margin", type=int, default=16, help="texels each island grows by (default 16, at least 2)")
    lm.add_argument("--no-denoise", action="store_true", help="leave the maps as baked (no OIDN lightmap filter)")
    lm.add_argument("--seed", type=int, default=0, help="random seed")
    lm.set_defaults(run=cmd_lightmap)


def cmd_lightmap(args) -> int:
    settings = _settings(args)
    ensure_registered()
    scene = open_blend(args.scene)
    from ..output.lightmap_bake import LightmapError, baked_objects, extracted
    from ..output.lightmap_targets import file_path, write_files
    t0 = time.perf_counter()
    try:
        listed = None if args.objects is None else [n.strip() for n in args.objects.split(",") if n.strip()]
        names = baked_objects(scene, listed, args.uv_map)
        built, warnings = extracted(scene, names, args.uv_map)
    except LightmapError as err:
        raise UserError(str(err)) from None
    result = bake(built, names, settings)
    for message in warnings + result.warnings:
        print(f"warning: {message}", file=sys.stderr)
    print(f"{result.info.get('vpls', 0)} VPLs placed for {len(names)} objects in {result.seconds['place']:.2f} s")
    write_files(args.output, result.images)
    for name in names:
        size = len(result.images[name])
        print(f"wrote {file_path(args.output, name)}: {size}x{size} {settings.bake_pass}, "
              f"{result.seconds[name]:.2f} s")
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
    if args.texel_density is not None and not 0.0 < args.texel_density < float("inf"):
        raise UserError(f"--texel-density {args.texel_density}: must be a positive number of texels a metre")
    placement = MethodSettings(vpls=args.vpls) if args.vpls else LightmapSettings().placement
    return LightmapSettings(size=args.size, texel_density=args.texel_density, samples=args.samples,
                            bake_pass=args.bake_pass, method=args.method, placement=placement, margin=args.margin,
                            denoise=not args.no_denoise, seed=args.seed)
