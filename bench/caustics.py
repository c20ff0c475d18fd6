"""The helmet's caustics on its ground (issue 70): the ground's mean Diffuse Indirect, vbnl with the caustics of
sharp lobes from its photons and from paths alone (``SamplingSettings.caustic_photons``), over seeds, against a
Cycles render of the same scene. The ground gets all its indirect light from the helmet, most of it the sun's
glints in the metal; ``sharp`` is the scene with Roughness 0.1 on every Principled BSDF, no emission and at most
2 bounces, where only the photons' caustics and the paths' direct light at the metal differ.

    .venv/bin/python bench/caustics.py [--variants asis,sharp] [--seeds 6] [--reference-samples asis=16384,sharp=4096]
        [--light-paths 0] [--percentage 50] [--out out/bench/caustics]

``--light-paths``: vbnl's Light Paths (0: automatic, 2^18 at this size).

Cycles' own mean of the ground converges slowly (the glints are its rare samples too): 0.0318 at 1024 samples,
0.0381 and 0.0368 at 4096 (two seeds), 0.0348 at 16384.
"""
from __future__ import annotations

import argparse
import os
import pathlib
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "bench"))
from vbnl_stages import register_extension  # noqa: E402

GROUND = 1  # the ground's pass index, read back from Cycles' Object Index pass


def load(variant: str, percentage: int):
    """The helmet scene of ``variant`` opened in bpy, its ground's pass index set."""
    import bpy
    bpy.ops.wm.open_mainfile(filepath=str(ROOT / "scenes" / "helmet_hdri.blend"))
    scene = bpy.context.scene
    scene.render.resolution_percentage = percentage
    bpy.data.objects["Ground"].pass_index = GROUND
    if variant == "sharp":
        scene.cycles.max_bounces = 2
        for material in bpy.data.materials:
            for node in material.node_tree.nodes if material.node_tree else ():
                if node.type == "BSDF_PRINCIPLED":
                    for name, value in (("Roughness", 0.1), ("Emission Strength", 0.0)):
                        for link in list(node.inputs[name].links):
                            material.node_tree.links.remove(link)
                        node.inputs[name].default_value = value
    return scene


def ground_mean(passes: dict, ground: np.ndarray) -> float:
    return float(passes["Diffuse Indirect"][..., :3][ground].mean())


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="asis,sharp")
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--reference-samples", default="asis=16384,sharp=4096",
                    help="Cycles' samples per variant, VARIANT=N,...")
    ap.add_argument("--light-paths", type=int, default=0)
    ap.add_argument("--percentage", type=int, default=50)
    ap.add_argument("--out", default=str(ROOT / "out" / "bench" / "caustics"))
    args = ap.parse_args(argv)
    register_extension()
    import bpy
    from vpl_gi.operators.output.reference import configure_cycles
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.core.exr import read_passes
    from vpl_gi.vpl_addon.render import RenderSettings, render
    os.makedirs(args.out, exist_ok=True)
    print("| scene | light paths | Cycles spp | ground DI (Cycles) | photons: mean ratio (seeds) | paths: mean ratio "
          "(seeds) |\n| --- | --- | --- | --- | --- | --- |")
    samples = {k: int(v) for k, v in (item.split("=") for item in args.reference_samples.split(","))}
    for variant in args.variants.split(","):
        path = os.path.join(args.out, f"cycles_{variant}_{samples[variant]}.exr")
        if not os.path.exists(path):
            scene = load(variant, args.percentage)
            configure_cycles(scene, samples[variant])
            scene.view_layers[0].use_pass_object_index = True
            render_to(scene, path)
        ref = read_passes(path)[0]
        ground = ref["Object Index"][..., 0] == GROUND
        theirs = ground_mean(ref, ground)
        load(variant, args.percentage)
        built, _ = extract(bpy.context.evaluated_depsgraph_get())
        ratios = {}
        for photons in (True, False):
            found = []
            for seed in range(args.seeds):
                settings = RenderSettings(seed=seed, passes=("Combined", "Diffuse Indirect"))
                settings.placement.vbnl.sampling.caustic_photons = photons
                settings.placement.vbnl.photons = args.light_paths
                found.append(ground_mean(render(built, settings).passes, ground) / theirs)
            ratios[photons] = found
        cells = [f"{np.mean(r):.3f} ({min(r):.2f}-{max(r):.2f})" for r in (ratios[True], ratios[False])]
        paths = args.light_paths or "automatic"
        print(f"| helmet_hdri {variant} | {paths} | {samples[variant]} | {theirs:.4f} | {cells[0]} | {cells[1]} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
