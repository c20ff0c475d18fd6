"""Denoise Combined alone, or the light passes apart and add them up? (issue 23: "denoise the direct-light passes and
the indirect passes where that measures better than denoising Combined alone; the passes keep summing to Combined")

One undenoised render per scene, setting and seed (the gather's filter off, as in a denoised render), then OIDN
(``core.denoise``, the same guides) on:
* Combined alone (what the engine does with Indirect Light Apart off);
* indirect apart: the indirect light (colour x Diffuse / Glossy Indirect) and the rest of Combined each denoised,
  added (the engine's default, ``denoise(..., apart=)``);
* direct: Diffuse Color x Diffuse Direct + Glossy Color x Glossy Direct denoised, the rest added as rendered;
* direct + indirect: the same and the indirect light (colour x Diffuse / Glossy Indirect) denoised apart;
* light passes: Diffuse / Glossy Direct denoised themselves (a white albedo guide), then times their colours;
* light passes + indirect.
Each judged by Combined's rMAE against the scene's committed Cycles reference, averaged over the seeds.

    .venv/bin/python bench/denoise_passes.py [cornell_area,cornell_sun] [--seeds 2]
"""
from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from vbnl_stages import ROOT, load_scene

SETTINGS = ((4, 4, 16), (16, 1, 16), (4, 4, 64))  # camera samples, light samples, vbnl's sample pairs
VARIANTS = ("noisy", "Combined alone", "indirect apart", "direct", "direct + indirect", "light passes",
            "light passes + indirect")


def variants(passes, denoise, P) -> list[np.ndarray]:
    """Combined of each variant (``VARIANTS``) from one render's passes."""
    albedo, normal = passes[P.DENOISING_ALBEDO], passes[P.DENOISING_NORMAL]

    def clean(image, guide=albedo):
        return denoise(image, guide, normal)
    combined = passes[P.COMBINED][..., :3]
    colour = passes[P.DIFFUSE_COLOR], passes[P.GLOSSY_COLOR]
    direct = colour[0] * passes[P.DIFFUSE_DIRECT] + colour[1] * passes[P.GLOSSY_DIRECT]
    indirect = colour[0] * passes[P.DIFFUSE_INDIRECT] + colour[1] * passes[P.GLOSSY_INDIRECT]
    rest = combined - direct - indirect
    white = np.ones_like(albedo)
    lights = colour[0] * clean(passes[P.DIFFUSE_DIRECT], white) + colour[1] * clean(passes[P.GLOSSY_DIRECT], white)
    return [combined, clean(combined), denoise(combined, albedo, normal, apart=np.asarray(indirect, np.float32)),
            clean(direct) + indirect + rest, clean(direct) + clean(indirect) + rest,
            lights + indirect + rest, lights + clean(indirect) + rest]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("scenes", nargs="?", default="cornell_area,cornell_sun")
    ap.add_argument("--seeds", type=int, default=2)
    args = ap.parse_args(argv)
    print("| scene, camera x light samples, pairs | " + " | ".join(VARIANTS) + " |")
    print("|" + " --- |" * (len(VARIANTS) + 1))
    for name in args.scenes.split(","):
        blend = ROOT / "example_blends" / f"{name}.blend"
        scene = load_scene(blend)
        import bpy
        from vpl_gi.vpl_addon.core import passes as P
        from vpl_gi.vpl_addon.core.denoise import denoise
        from vpl_gi.vpl_addon.core.exr import read_passes
        from vpl_gi.vpl_addon.evaluation.metrics import coverage_mask, errors
        from vpl_gi.vpl_addon.render import render
        reference = read_passes(str(ROOT / "tests" / "references" / f"{name}.exr"))[0][P.COMBINED]
        mask = coverage_mask(reference[..., 3], reference.shape[:2])
        wanted = (P.COMBINED, P.DIFFUSE_DIRECT, P.DIFFUSE_COLOR, P.GLOSSY_DIRECT, P.GLOSSY_COLOR,
                  P.DIFFUSE_INDIRECT, P.GLOSSY_INDIRECT, P.DENOISING_ALBEDO, P.DENOISING_NORMAL)
        base = bpy.context.scene.vpl_gi.render_settings(wanted)
        for samples, light_samples, pairs in SETTINGS:
            vbnl = base.placement.vbnl
            vbnl = dataclasses.replace(vbnl, sampling=dataclasses.replace(vbnl.sampling, samples=pairs))
            rmae = []
            for seed in range(args.seeds):
                # undenoised, but as a denoised render runs: the gather's filter off (``render``'s ``filtering``)
                settings = dataclasses.replace(base, samples=samples, light_samples=light_samples, seed=seed,
                                               denoise=False, placement=dataclasses.replace(base.placement, vbnl=vbnl),
                                               gather=dataclasses.replace(base.gather, filter=False))
                passes = render(scene, settings).passes
                rmae.append([errors(image, reference, mask)["rmae"] for image in variants(passes, denoise, P)])
            mean = np.mean(rmae, axis=0)
            print(f"| {name}, {samples} x {light_samples}, {pairs} | " + " | ".join(f"{v:.4f}" for v in mean) + " |",
                  flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
