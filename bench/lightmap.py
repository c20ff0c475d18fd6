"""Lightmaps against Cycles' bake (issue 68): time and error of our Diffuse Indirect lightmaps at several VPL budgets,
of Cycles' bake (type DIFFUSE, pass filter INDIRECT, colour off) at several sample counts, and of that bake denoised
by OIDN's lightmap filter, all against a Cycles bake at many samples, on the Cornell box UV-mapped per object by
Smart UV Project (``example_blends/make_lightmapped.py``), in one run.

    .venv/bin/python bench/lightmap.py [--size 128] [--reference-samples 4096] [--cycles 4,16,64]
        [--vpls 4096,16384,65536] [--twin] [--json bench/results/lightmap/comparison.json]
    .venv/bin/python bench/lightmap.py --scaling 10,100 [--texels 163840]

``--scaling`` bakes a room of N tiles, each its own object, at the same total of texels for each N (no Blender):
the VPLs are placed once for all, so the time per texel should not grow with the number of objects.

The error is pooled over the interior texels of all objects: those whose samples all lie inside the UV map (our
coverage 1) and a texel from the island's edge, Cycles' bake margin and ours left out. The time is the whole bake of
all objects: Cycles' calls of ``bpy.ops.object.bake`` one object after the other (plus the filter for the denoised
rival), ours the scene's extraction and ``lightmap.bake``. The reference is cached by scene, size and samples under
``$VPL_GI_CACHE/lightmap``.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import pathlib
import time

import numpy as np
from scipy.ndimage import binary_erosion

from vbnl_stages import register_extension
from vpl_addon.core.compiled import cache_root  # noqa: E402 (vbnl_stages puts the project on the path)
from vpl_addon.core.denoise import denoise_lightmap
from vpl_addon.evaluation.metrics import clean_rrmse, errors

ROOT = pathlib.Path(__file__).resolve().parent.parent
SCENE = ROOT / "example_blends" / "cornell_area.blend"
LIT = 0.05  # the share of the reference's mean above which a texel counts as lit (``pooled``)


def _ints(text: str) -> list[int]:
    return [int(v) for v in text.split(",")]


def open_uv_box():
    """The Cornell box opened in bpy with a Smart UV Project map "Lightmap" per mesh; the meshes' names."""
    register_extension()
    import bpy
    from example_blends.make_lightmapped import unwrap
    bpy.ops.wm.open_mainfile(filepath=str(SCENE))
    return unwrap(bpy)


def cycles_maps(names, size: int, samples: int, seed: int | None = None) -> tuple[dict, float]:
    """Cycles' Diffuse Indirect bake of each object (with Cycles' ``seed``; None: the references' own), and the
    seconds of all of them."""
    import bpy
    from vpl_gi.operators.output.cycles_bake import cycles_lightmap
    t0 = time.perf_counter()
    maps = {name: cycles_lightmap(bpy, bpy.data.objects[name], size, samples, uv_map="Lightmap", seed=seed)
            for name in names}
    return maps, time.perf_counter() - t0


def reference(names, size: int, samples: int, seed: int | None = None) -> dict:
    """The reference bake (``seed`` None) or its twin (another seed: the same bake with independent noise), from
    the cache when this scene was baked at this size, samples and seed before."""
    digest = hashlib.sha256(SCENE.read_bytes() + f"{size} {samples}".encode()
                            + (b"" if seed is None else f" seed {seed}".encode())).hexdigest()[:16]
    path = pathlib.Path(cache_root()) / "lightmap" / f"cornell_area-{digest}.npz"
    if path.is_file():
        return dict(np.load(path))
    maps, seconds = cycles_maps(names, size, samples, seed)
    print(f"reference: Cycles bake at {samples} samples (seed {seed}), {seconds:.1f} s")
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **maps)
    return maps


def ours(names, size: int, vpls: int) -> tuple[dict, float, dict]:
    """Our maps at ``vpls`` virtual lights (RGB and the coverage), and the seconds of extraction and bake."""
    import bpy
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.lightmap import LightmapSettings, bake
    from vpl_gi.vpl_addon.methods import MethodSettings
    t0 = time.perf_counter()
    scene, _ = extract(bpy.context.evaluated_depsgraph_get(), bake_uv="Lightmap")
    result = bake(scene, names, LightmapSettings(size=size, placement=MethodSettings(vpls=vpls)))
    seconds = time.perf_counter() - t0
    return {n: result.images[n][..., :3] for n in names}, seconds, {n: result.images[n][..., 3] for n in names}


def pooled(maps: dict, ref: dict, interior: dict, twin: dict | None = None) -> dict:
    """``errors`` of the interior texels of all objects at once, and the rMAE of those the reference finds lit
    (``rmae_lit``: above ``LIT`` of its mean). The texels left out are those whose centre lies inside a box standing
    on the floor: Cycles bakes a texel at its centre, so there it finds nothing (under 1 % of the mean, and no
    interior texel lies between 1 % and ``LIT``), where ours holds the light of the texel's part outside the box (the
    samples that see a back face moved out of it): a texel no one sees, whose relative error is that of nearly
    nothing. With the reference's ``twin`` (another seed), ``clean_rrmse_lit``: the relative RMSE of the lit
    texels against the truth, the references' own noise taken out (``metrics.clean_rrmse``)."""
    got = np.concatenate([maps[n][interior[n]] for n in ref])[:, None]
    want = np.concatenate([ref[n][interior[n]] for n in ref])[:, None]
    lit = want.mean(axis=-1) > LIT * want.mean()
    row = {**errors(got, want), "rmae_lit": errors(got[lit][:, None], want[lit][:, None])["rmae"],
           "lit_share": float(lit.mean())}
    if twin is not None:
        other = np.concatenate([twin[n][interior[n]] for n in ref])[:, None]
        row["clean_rrmse_lit"] = clean_rrmse(got[lit][:, None], want[lit][:, None], other[lit][:, None])
    return row


def tiles_scene(count: int):
    """A floor under ``count`` tiles in a grid, each tile its own UV-mapped object (the whole map), lit by one
    point light."""
    from vpl_addon.core.camera import Camera, view_window
    from vpl_addon.core.scene import Materials, Scene
    from vpl_addon.lights import PointLight
    side = int(np.ceil(np.sqrt(count)))
    quads = [((-4.0, -4.0), 8.0, 0.0)] + [((-4.0 + 8.0 * (i % side) / side, -4.0 + 8.0 * (i // side) / side),
                                          0.8 * 8.0 / side, 1.0) for i in range(count)]
    tris, uvs = [], []
    for (x, y), width, z in quads:
        c = np.array([(x, y, z), (x + width, y, z), (x + width, y + width, z), (x, y + width, z)])
        tris += [c[[0, 1, 2]], c[[0, 2, 3]]]
        uvs += [np.array([(0, 0), (1, 0), (1, 1)]), np.array([(0, 0), (1, 1), (0, 1)])]
    names = ["floor"] + [f"tile {i}" for i in range(count)]
    cam = Camera(np.eye(4), 1, 1, view_window(1, 1, orthographic=True, ortho_scale=1.0), orthographic=True)
    return Scene.build(np.array(tris), Materials.make([{"name": "grey", "base_color": (0.6,) * 3}]),
                       [PointLight("lamp", [0.0, 0.0, 3.0], [500.0] * 3)], cam, uvs=np.array(uvs),
                       material=np.ones(len(tris)), object_id=np.repeat(np.arange(len(names)), 2),
                       object_names=names), names[1:]


def scaling(counts: list[int], texels: int) -> list[dict]:
    """The bake of ``count`` tiles at ``texels`` texels in all, for each count: seconds, and per million texels."""
    from vpl_addon.lightmap import LightmapSettings, bake
    rows = []
    for count in counts:
        scene, names = tiles_scene(count)
        size = int(round(np.sqrt(texels / count)))
        t0 = time.perf_counter()
        bake(scene, names, LightmapSettings(size=size))
        seconds = time.perf_counter() - t0
        rows.append({"objects": count, "size": size, "seconds": seconds,
                     "seconds_per_mtexel": seconds / (count * size * size) * 1e6})
        print(f"{count:4d} objects at {size}x{size}: {seconds:.2f} s, "
              f"{rows[-1]['seconds_per_mtexel']:.2f} s per million texels")
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--reference-samples", type=int, default=4096)
    ap.add_argument("--cycles", type=_ints, default=[4, 16, 64], help="Cycles' samples per texel")
    ap.add_argument("--vpls", type=_ints, default=[4096, 16384, 65536], help="our VPL budgets")
    ap.add_argument("--twin", action="store_true",
                    help="bake the reference again with another seed: the references' noise floor, and each row's "
                         "error against the truth with that noise taken out")
    ap.add_argument("--json", help="where to write the rows")
    ap.add_argument("--scaling", type=_ints, help="object counts for the scaling line (instead of the comparison)")
    ap.add_argument("--texels", type=int, default=10 * 128 * 128, help="texels in all, for --scaling")
    args = ap.parse_args()
    if args.scaling:
        scaling([1], 64)  # compiles the kernels before anything is timed
        rows = scaling(args.scaling, args.texels)
        if args.json:
            _write(args.json, {"texels": args.texels, "scaling": rows})
        return
    names = open_uv_box()
    ours(names, 16, 64)  # compiles the kernels before anything is timed
    ref = reference(names, args.size, args.reference_samples)
    twin = reference(names, args.size, args.reference_samples, seed=1) if args.twin else None
    _, _, coverage = ours(names, args.size, 64)
    interior = {n: binary_erosion(coverage[n] == 1.0, iterations=1) for n in names}
    rows = []
    if twin is not None:
        rows.append({"what": f"the reference's twin (seed 1), {args.reference_samples} spp", "seconds": 0.0,
                     **pooled(twin, ref, interior)})
    for samples in args.cycles:
        maps, seconds = cycles_maps(names, args.size, samples)
        rows.append({"what": f"Cycles bake {samples} spp", "seconds": seconds, **pooled(maps, ref, interior, twin)})
        t0 = time.perf_counter()
        denoised = {n: denoise_lightmap(maps[n]) for n in names}
        rows.append({"what": f"Cycles bake {samples} spp + OIDN", "seconds": seconds + time.perf_counter() - t0,
                     **pooled(denoised, ref, interior, twin)})
    for vpls in args.vpls:
        maps, seconds, _ = ours(names, args.size, vpls)
        rows.append({"what": f"VPL GI ir {vpls} VPLs", "seconds": seconds, **pooled(maps, ref, interior, twin)})
    _print(rows, twin is not None)
    if args.json:
        _write(args.json, {"size": args.size, "reference_samples": args.reference_samples, "rows": rows})


def _print(rows: list[dict], clean: bool) -> None:
    """The table: seconds, rMAE, lit rMAE, mean ratio (and the clean lit rRMSE with a twin); the twin's own rMAE
    over sqrt(2) is what the truth would score (``metrics.noise_floor``)."""
    print(f"{'':40} {'seconds':>8} {'rMAE':>8} {'lit rMAE':>8} {'mean':>8}" + (f" {'clean':>8}" if clean else ""))
    for row in rows:
        print(f"{row['what']:40} {row['seconds']:8.2f} {row['rmae']:8.4f} {row['rmae_lit']:8.4f} "
              f"{row['mean_ratio']:8.4f}" + (f" {row.get('clean_rrmse_lit', float('nan')):8.4f}" if clean else ""))
    if clean:
        print(f"the truth's lit rMAE against the reference (its noise floor): {rows[0]['rmae_lit'] / np.sqrt(2):.4f}")


def _write(path: str, table: dict) -> None:
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w") as f:
        json.dump(table, f, indent=1)


if __name__ == "__main__":
    main()
