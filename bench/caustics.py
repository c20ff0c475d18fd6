"""The helmet's caustics on its ground (issue 70): the ground's mean Diffuse Indirect, vbnl with the caustics of
sharp lobes from its photons (the distant lights' aimed at the sharp surfaces, ``VBNLSettings.aimed_caustics``, or
not) and from paths alone (``SamplingSettings.caustic_photons``), over seeds, against a Cycles render of the same
scene; over the frame, the 8 x 8-block rMAE of Diffuse Indirect (Cycles' own at 64 samples beside it) and the rMAE
of Combined denoised. The ground gets all its indirect light from the helmet, most of it the sun's glints in the
metal; ``sharp`` is the scene with Roughness 0.1 on every Principled BSDF, no emission and at most 2 bounces,
where only the photons' caustics and the paths' direct light at the metal differ.

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


CONFIGURATIONS = (("photons, aimed", True, None), ("photons", True, 0.0), ("paths", False, None))
BLOCK = 8


def ground_mean(passes: dict, ground: np.ndarray) -> float:
    return float(passes["Diffuse Indirect"][..., :3][ground].mean())


def frame_errors(passes: dict, ref: dict) -> tuple[float, float]:
    """(8 x 8-block rMAE of Diffuse Indirect, per-pixel rMAE of Combined) of ``passes`` against ``ref``."""
    from vpl_gi.vpl_addon.evaluation.metrics import block_means, coverage_mask, errors
    full = coverage_mask(ref["Combined"][..., 3], ref["Combined"].shape[:2])
    whole = block_means(full[..., None].astype(float), BLOCK)[..., 0] >= 1.0
    blocks = errors(block_means(passes["Diffuse Indirect"][..., :3], BLOCK),
                    block_means(ref["Diffuse Indirect"][..., :3], BLOCK), whole)["rmae"]
    return blocks, errors(passes["Combined"], ref["Combined"], full)["rmae"]


def cycles(variant: str, samples: int, percentage: int, folder: str) -> dict:
    """Cycles' passes of ``variant`` at ``samples`` (rendered once into ``folder``)."""
    from vpl_gi.operators.output.reference import configure_cycles
    from vpl_gi.operators.output.render_file import render_to
    from vpl_gi.vpl_addon.core.exr import read_passes
    path = os.path.join(folder, f"cycles_{variant}_{samples}.exr")
    if not os.path.exists(path):
        scene = load(variant, percentage)
        configure_cycles(scene, samples)
        scene.view_layers[0].use_pass_object_index = True
        render_to(scene, path)
    return read_passes(path)[0]


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
    from vpl_gi.operators.scene.extract import extract
    from vpl_gi.vpl_addon.render import RenderSettings, render
    os.makedirs(args.out, exist_ok=True)
    print("| scene | light paths | Cycles spp | ground DI (Cycles) | caustics | ground: mean ratio (seeds) | "
          "Diffuse Indirect 8x8 rMAE | Combined denoised rMAE |\n| --- | --- | --- | --- | --- | --- | --- | --- |")
    samples = {k: int(v) for k, v in (item.split("=") for item in args.reference_samples.split(","))}
    paths = args.light_paths or "automatic"
    for variant in args.variants.split(","):
        ref = cycles(variant, samples[variant], args.percentage, args.out)
        ground = ref["Object Index"][..., 0] == GROUND
        theirs = ground_mean(ref, ground)
        head = f"| helmet_hdri {variant} | {paths} | {samples[variant]} | {theirs:.4f} |"
        quick = cycles(variant, 64, args.percentage, args.out)
        blocks, _ = frame_errors(quick, ref)
        print(f"{head} Cycles 64 spp | {ground_mean(quick, ground) / theirs:.3f} | {blocks:.3f} | |", flush=True)
        load(variant, args.percentage)
        built, _ = extract(bpy.context.evaluated_depsgraph_get())
        for label, photons, aimed in CONFIGURATIONS:
            ratios, figures = [], []
            for seed in range(args.seeds):
                settings = RenderSettings(seed=seed, denoise=True, passes=("Combined", "Diffuse Indirect"))
                settings.placement.vbnl.sampling.caustic_photons = photons
                settings.placement.vbnl.photons = args.light_paths
                if aimed is not None:
                    settings.placement.vbnl.aimed_caustics = aimed
                passes = render(built, settings).passes
                ratios.append(ground_mean(passes, ground) / theirs)
                figures.append(frame_errors(passes, ref))
            blocks, combined = np.mean(figures, axis=0)
            print(f"{head} {label} | {np.mean(ratios):.3f} ({min(ratios):.2f}-{max(ratios):.2f}) | {blocks:.3f} | "
                  f"{combined:.4f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
